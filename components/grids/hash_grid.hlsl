// Multiresolution grid encodings in HLSL and Slang (hash_grid.glsl for OpenGL and Vulkan): one level's
// lookup. inshade/grid_layout.py states the rules, torch_twin.py is the torch twin; integer work is
// uint wrap-around arithmetic, bit-identical to tiny-cuda-nn's.
#include <lib/texture_rows>

// Row of vertex c within its level: dense index where the level's grid fits its rows, else the
// spatial hash xor_d (c_d * prime_d); then modulo the level's rows.
uint hg_index(uint3 c, int dims, uint res, uint rows, bool dense, uint3 primes) {
    uint index;
    if (dense) {
        index = c.x + c.y * res;
        if (dims == 3) index += c.z * (res * res);
    } else {
        index = (c.x * primes.x) ^ (c.y * primes.y);
        if (dims == 3) index ^= c.z * primes.z;
    }
    return index % rows;
}

// One level: the 2^dims corners of x's cell weighted by prod_d (bit d ? f_d : 1 - f_d) and summed
// in corner order (bit d of the corner number is axis d), as the torch twin does. p = scale * x + 0.5
// with two roundings, as the torch twin computes it: `precise` stops the compiler from fusing it.
float4 hg_level(Texture2D<float4> table, int log2w, float3 x, int dims, float scale, uint res, uint rows,
                uint first_row, bool dense, uint3 primes) {
    precise float4 p = (float4)scale * float4(x, 0.0) + (float4)0.5;
    float4 g = floor(p);
    uint3 c = (uint3)(int3)g.xyz;
    float3 f = p.xyz - g.xyz;
    float4 acc = (float4)0.0;
    for (int corner = 0; corner < (1 << dims); ++corner) {
        float w = 1.0;
        uint3 cc = c;
        for (int d = 0; d < dims; ++d) {
            bool up = ((corner >> d) & 1) == 1;
            w *= up ? f[d] : 1.0 - f[d];
            cc[d] += up ? 1u : 0u;
        }
        uint row = first_row + hg_index(cc, dims, res, rows, dense, primes);
        acc += w * table.Load(int3(rows_texel(row, log2w), 0));
    }
    return acc;
}
