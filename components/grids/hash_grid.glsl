// Multiresolution grid encodings (instant-NGP's hash grid, tiny-cuda-nn's DenseGrid): one level's
// lookup, for OpenGL and Vulkan GLSL (hash_grid.wgsl, hash_grid.hlsl for the others).
// inshade/grid_layout.py states the rules, torch_twin.py is the torch twin; integer
// work is uint32 wrap-around arithmetic, bit-identical to tiny-cuda-nn's.
#include <lib/texture_rows>

// p = scale * x + 0.5 with two roundings, as the torch twin computes it (tiny-cuda-nn fuses it: one
// ulp of p apart at most). `precise` stops a GLSL 4 compiler from fusing it; before 4.00 and in ES a
// driver may still fuse (llvmpipe does not).
#if __VERSION__ >= 400
#define HG_PRECISE precise
#else
#define HG_PRECISE
#endif

// Vulkan GLSL reads the table without a sampler (GL_EXT_samplerless_texture_functions).
#ifdef VULKAN
#define HG_TABLE texture2D
#else
#define HG_TABLE sampler2D
#endif

// Row of vertex c within its level: dense index where the level's grid fits its rows, else the
// spatial hash xor_d (c_d * prime_d); then modulo the level's rows.
uint hg_index(uvec3 c, int dims, uint res, uint rows, bool dense, uvec3 primes) {
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
// in corner order (bit d of the corner number is axis d), as the torch twin does.
vec4 hg_level(HG_TABLE table, int log2w, vec3 x, int dims, float scale, uint res, uint rows, uint offset,
              bool dense, uvec3 primes) {
    HG_PRECISE vec4 p = vec4(scale) * vec4(x, 0.0) + vec4(0.5);
    vec4 g = floor(p);
    uvec3 c = uvec3(ivec3(g.xyz));
    vec3 f = p.xyz - g.xyz;
    vec4 acc = vec4(0.0);
    for (int corner = 0; corner < (1 << dims); ++corner) {
        float w = 1.0;
        uvec3 cc = c;
        for (int d = 0; d < dims; ++d) {
            bool up = ((corner >> d) & 1) == 1;
            w *= up ? f[d] : 1.0 - f[d];
            cc[d] += up ? 1u : 0u;
        }
        uint row = offset + hg_index(cc, dims, res, rows, dense, primes);
        acc += w * texelFetch(table, rows_texel(row, log2w), 0);
    }
    return acc;
}
