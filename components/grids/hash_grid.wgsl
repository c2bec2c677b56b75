// Multiresolution grid encodings in WGSL (hash_grid.glsl for OpenGL and Vulkan): one level's lookup.
// inshade/grid_layout.py states the rules, torch_twin.py is the torch twin; integer work is u32
// wrap-around arithmetic, bit-identical to tiny-cuda-nn's.
#include <lib/texture_rows>

// Row of vertex c within its level: dense index where the level's grid fits its rows, else the
// spatial hash xor_d (c_d * prime_d); then modulo the level's rows.
fn hg_index(c: vec3<u32>, dims: i32, res: u32, rows: u32, dense: bool, primes: vec3<u32>) -> u32 {
    var index: u32;
    if (dense) {
        index = c.x + c.y * res;
        if (dims == 3) { index += c.z * (res * res); }
    } else {
        index = (c.x * primes.x) ^ (c.y * primes.y);
        if (dims == 3) { index ^= c.z * primes.z; }
    }
    return index % rows;
}

// One level: the 2^dims corners of x's cell weighted by prod_d (bit d ? f_d : 1 - f_d) and summed
// in corner order (bit d of the corner number is axis d), as the torch twin does. p = scale * x + 0.5
// as the torch twin computes it, two roundings; WGSL has no `precise`, so a compiler may fuse it
// (one ulp of p apart at most, as tiny-cuda-nn's own fused p is).
fn hg_level(table: texture_2d<f32>, log2w: i32, x: vec3<f32>, dims: i32, scale: f32, res: u32, rows: u32,
            first_row: u32, dense: bool, primes: vec3<u32>) -> vec4<f32> {
    let p = vec4<f32>(scale) * vec4<f32>(x, 0.0) + vec4<f32>(0.5);
    let g = floor(p);
    let c = vec3<u32>(vec3<i32>(g.xyz));
    var f = p.xyz - g.xyz;
    var acc = vec4<f32>(0.0);
    for (var corner = 0; corner < (1 << u32(dims)); corner++) {
        var w = 1.0;
        var cc = c;
        for (var d = 0; d < dims; d++) {
            let up = ((corner >> u32(d)) & 1) == 1;
            w *= select(1.0 - f[d], f[d], up);
            cc[d] += select(0u, 1u, up);
        }
        let row = first_row + hg_index(cc, dims, res, rows, dense, primes);
        acc += w * textureLoad(table, rows_texel(row, log2w), 0);
    }
    return acc;
}
