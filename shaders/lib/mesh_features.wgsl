// UV-free hashed per-triangle feature hierarchy in WGSL (mesh_features.glsl for OpenGL and Vulkan;
// models/mesh_features.py has the torch twin and the rules, geometry/mesh_topology.py the owner
// tables). All integer work is u32 wrap-around arithmetic, bit-exact with torch; the float work is
// the same float32 operations in the same order. What GLSL writes to out parameters arrives here
// through pointers.
#include <lib/texture_rows>

// The level's sub-triangle of a point: sub-vertices w[v] = (W0, W1) and their weights.
struct MfSubtriangle {
    w: array<vec2<i32>, 3>,
    weight: vec3<f32>,
}

// The level's sub-triangle of a point with barycentrics t = (t0, t1) (W2 = 2^level - W0 - W1), in
// the order the rule lists them.
fn mf_subtriangle(t: vec2<f32>, level: i32) -> MfSubtriangle {
    let r = f32(1 << u32(level));
    let a = r * t;                                    // exact: r is a power of two
    let i = clamp(floor(a.x), 0.0, r - 1.0);
    let j = clamp(floor(a.y), 0.0, (r - 1.0) - i);
    let f0 = a.x - i;
    let f1 = a.y - j;
    let ij = vec2<i32>(i32(i), i32(j));
    var s: MfSubtriangle;
    if (i + j == r - 1.0 || f0 + f1 <= 1.0) {         // upright (always on the last diagonal)
        s.w = array<vec2<i32>, 3>(ij, ij + vec2<i32>(1, 0), ij + vec2<i32>(0, 1));
        s.weight = vec3<f32>((1.0 - f0) - f1, f0, f1);
    } else {                                          // rotated
        s.w = array<vec2<i32>, 3>(ij + vec2<i32>(1, 1), ij + vec2<i32>(0, 1), ij + vec2<i32>(1, 0));
        s.weight = vec3<f32>((f0 + f1) - 1.0, 1.0 - f0, 1.0 - f1);
    }
    return s;
}

// The canonical name (k', W'0, W'1) of sub-vertex W = (W0, W1, W2) of face k: a mesh vertex
// is named by its corner owner, a point on an edge by the edge's owner, an interior point by k.
fn mf_canonical(k: u32, W: vec3<i32>, level: i32, corners: vec3<u32>, edges: vec3<u32>) -> vec3<u32> {
    let r = 1 << u32(level);
    for (var s = 0; s < 3; s++) {
        if (W[s] == r) {
            let c = corners[s];
            var w = vec3<u32>(0u);
            w[i32(c & 3u)] = u32(r);
            return vec3<u32>(c >> 2u, w.x, w.y);
        }
    }
    for (var s = 0; s < 3; s++) {
        if (W[s] == 0) {
            let e = edges[s];
            var w = vec3<u32>(0u);
            w[i32((e >> 2u) & 3u)] = u32(W[(s + 1) % 3]);
            w[i32(e & 3u)] = u32(W[(s + 2) % 3]);
            return vec3<u32>(e >> 4u, w.x, w.y);
        }
    }
    return vec3<u32>(k, vec2<u32>(W.xy));
}

// The full 32-bit hash of a canonical sub-vertex (the thesis's eq. 5.8, pi3 reduced mod 2^32).
fn mf_hash(kw: vec3<u32>, level: i32) -> u32 {
    return (2654435761u * kw.x) ^ kw.y ^ (805459861u * kw.z) ^ (1094488767u * u32(level));
}

// Row of the feature table: level l owns rows l*T .. l*T + T - 1 (T a power of two).
fn mf_hash_index(kw: vec3<u32>, level: i32, table_size: u32) -> u32 {
    return u32(level) * table_size + (mf_hash(kw, level) & (table_size - 1u));
}

// The three table rows and weights of face k's point t at one level.
fn mf_level_taps(k: u32, t: vec2<f32>, level: i32, table_size: u32, corners: vec3<u32>, edges: vec3<u32>,
                 index: ptr<function, array<u32, 3>>, weight: ptr<function, vec3<f32>>) {
    var s = mf_subtriangle(t, level);
    *weight = s.weight;
    let r = 1 << u32(level);
    for (var v = 0; v < 3; v++) {
        let w = s.w[v];
        let W = vec3<i32>(w, r - w.x - w.y);
        (*index)[v] = mf_hash_index(mf_canonical(k, W, level, corners, edges), level, table_size);
    }
}

// Face k's owner tables from a texture holding 2 texels per face: texel 2k = corners.xyz,
// texel 2k + 1 = edges.xyz.
fn mf_face_tables(topo: texture_2d<u32>, k: u32, log2w: i32, corners: ptr<function, vec3<u32>>,
                  edges: ptr<function, vec3<u32>>) {
    *corners = textureLoad(topo, rows_texel(2u * k, log2w), 0).xyz;
    *edges = textureLoad(topo, rows_texel(2u * k + 1u, log2w), 0).xyz;
}

// The same from 1 texel per face, every id < 2^16 and two to a channel:
// (c0 | c1 << 16, c2 | e0 << 16, e1 | e2 << 16).
fn mf_face_tables16(topo: texture_2d<u32>, k: u32, log2w: i32, corners: ptr<function, vec3<u32>>,
                    edges: ptr<function, vec3<u32>>) {
    let p = textureLoad(topo, rows_texel(k, log2w), 0).xyz;
    *corners = vec3<u32>(p.x & 0xFFFFu, p.x >> 16u, p.y & 0xFFFFu);
    *edges = vec3<u32>(p.y >> 16u, p.z & 0xFFFFu, p.z >> 16u);
}

// The same from 1 RGBA texel per face, every owner face < 2^16: the six owners two to a channel,
// their slot bits in w (corners 2 bits each from bit 0, edges 4 bits each from bit 6).
fn mf_face_owners16(topo: texture_2d<u32>, k: u32, log2w: i32, corners: ptr<function, vec3<u32>>,
                    edges: ptr<function, vec3<u32>>) {
    let p = textureLoad(topo, rows_texel(k, log2w), 0);
    *corners = (vec3<u32>(p.x & 0xFFFFu, p.x >> 16u, p.y & 0xFFFFu) << vec3<u32>(2u))
               | vec3<u32>(p.w & 3u, (p.w >> 2u) & 3u, (p.w >> 4u) & 3u);
    *edges = (vec3<u32>(p.y >> 16u, p.z & 0xFFFFu, p.z >> 16u) << vec3<u32>(4u))
             | vec3<u32>((p.w >> 6u) & 15u, (p.w >> 10u) & 15u, (p.w >> 14u) & 15u);
}

// One table row blended: ((w0 * f0) + w1 * f1) + w2 * f2, as torch sums it.
fn mf_blend(table: texture_2d<f32>, log2w: i32, index: array<u32, 3>, weight: vec3<f32>) -> vec4<f32> {
    return (weight.x * textureLoad(table, rows_texel(index[0], log2w), 0)
            + weight.y * textureLoad(table, rows_texel(index[1], log2w), 0))
           + weight.z * textureLoad(table, rows_texel(index[2], log2w), 0);
}
