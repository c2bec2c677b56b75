// UV-free hashed per-triangle feature hierarchy, for OpenGL and Vulkan GLSL (mesh_features.wgsl,
// mesh_features.hlsl for the others; models/mesh_features.py has the torch twin and the rules,
// geometry/mesh_topology.py the owner tables). All integer work is uint32 wrap-around arithmetic,
// bit-exact with torch; the float work is the same float32 operations in the same order.
#include <lib/texture_rows>

// Vulkan GLSL reads the tables without a sampler (GL_EXT_samplerless_texture_functions).
#ifdef VULKAN
#define MF_TOPOLOGY utexture2D
#define MF_TABLE texture2D
#else
#define MF_TOPOLOGY usampler2D
#define MF_TABLE sampler2D
#endif

// The level's sub-triangle of a point with barycentrics t = (t0, t1): sub-vertices w[v] =
// (W0, W1) (W2 = 2^level - W0 - W1) and their weights, in the order the rule lists them.
void mf_subtriangle(vec2 t, int level, out ivec2 w[3], out vec3 weight) {
    float r = float(1 << level);
    vec2 a = r * t;                                   // exact: r is a power of two
    float i = clamp(floor(a.x), 0.0, r - 1.0);
    float j = clamp(floor(a.y), 0.0, (r - 1.0) - i);
    float f0 = a.x - i;
    float f1 = a.y - j;
    ivec2 ij = ivec2(int(i), int(j));
    if (i + j == r - 1.0 || f0 + f1 <= 1.0) {         // upright (always on the last diagonal)
        w[0] = ij; w[1] = ij + ivec2(1, 0); w[2] = ij + ivec2(0, 1);
        weight = vec3((1.0 - f0) - f1, f0, f1);
    } else {                                          // rotated
        w[0] = ij + ivec2(1, 1); w[1] = ij + ivec2(0, 1); w[2] = ij + ivec2(1, 0);
        weight = vec3((f0 + f1) - 1.0, 1.0 - f0, 1.0 - f1);
    }
}

// The canonical name (k', W'0, W'1) of sub-vertex W = (W0, W1, W2) of face k: a mesh vertex
// is named by its corner owner, a point on an edge by the edge's owner, an interior point by k.
uvec3 mf_canonical(uint k, ivec3 W, int level, uvec3 corners, uvec3 edges) {
    int r = 1 << level;
    for (int s = 0; s < 3; ++s) {
        if (W[s] == r) {
            uint c = corners[s];
            uvec3 w = uvec3(0u);
            w[int(c & 3u)] = uint(r);
            return uvec3(c >> 2u, w.x, w.y);
        }
    }
    for (int s = 0; s < 3; ++s) {
        if (W[s] == 0) {
            uint e = edges[s];
            uvec3 w = uvec3(0u);
            w[int((e >> 2u) & 3u)] = uint(W[(s + 1) % 3]);
            w[int(e & 3u)] = uint(W[(s + 2) % 3]);
            return uvec3(e >> 4u, w.x, w.y);
        }
    }
    return uvec3(k, uvec2(W.xy));
}

// The full 32-bit hash of a canonical sub-vertex (the thesis's eq. 5.8, pi3 reduced mod 2^32).
uint mf_hash(uvec3 kw, int level) {
    return (2654435761u * kw.x) ^ kw.y ^ (805459861u * kw.z) ^ (1094488767u * uint(level));
}

// Row of the feature table: level l owns rows l*T .. l*T + T - 1 (T a power of two).
uint mf_hash_index(uvec3 kw, int level, uint table_size) {
    return uint(level) * table_size + (mf_hash(kw, level) & (table_size - 1u));
}

// The three table rows and weights of face k's point t at one level.
void mf_level_taps(uint k, vec2 t, int level, uint table_size, uvec3 corners, uvec3 edges,
                   out uint index[3], out vec3 weight) {
    ivec2 w[3];
    mf_subtriangle(t, level, w, weight);
    int r = 1 << level;
    for (int v = 0; v < 3; ++v) {
        ivec3 W = ivec3(w[v], r - w[v].x - w[v].y);
        index[v] = mf_hash_index(mf_canonical(k, W, level, corners, edges), level, table_size);
    }
}

// Face k's owner tables from an RGB32UI texture holding 2 texels per face (24 bytes, no padding):
// texel 2k = corners.xyz, texel 2k + 1 = edges.xyz. (highp: ES 3.00 has no default precision for usampler2D.)
void mf_face_tables(highp MF_TOPOLOGY topo, uint k, int log2w, out uvec3 corners, out uvec3 edges) {
    corners = texelFetch(topo, rows_texel(2u * k, log2w), 0).xyz;
    edges = texelFetch(topo, rows_texel(2u * k + 1u, log2w), 0).xyz;
}

// The same from 1 texel per face (12 bytes), every id < 2^16 and two to a channel:
// (c0 | c1 << 16, c2 | e0 << 16, e1 | e2 << 16).
void mf_face_tables16(highp MF_TOPOLOGY topo, uint k, int log2w, out uvec3 corners, out uvec3 edges) {
    uvec3 p = texelFetch(topo, rows_texel(k, log2w), 0).xyz;
    corners = uvec3(p.x & 0xFFFFu, p.x >> 16u, p.y & 0xFFFFu);
    edges = uvec3(p.y >> 16u, p.z & 0xFFFFu, p.z >> 16u);
}

// The same from 1 RGBA32UI texel per face (16 bytes), every owner face < 2^16: the six owners two
// to a channel, their slot bits in w (corners 2 bits each from bit 0, edges 4 bits each from bit 6).
void mf_face_owners16(highp MF_TOPOLOGY topo, uint k, int log2w, out uvec3 corners, out uvec3 edges) {
    uvec4 p = texelFetch(topo, rows_texel(k, log2w), 0);
    corners = uvec3(p.x & 0xFFFFu, p.x >> 16u, p.y & 0xFFFFu) << 2u
              | uvec3(p.w & 3u, (p.w >> 2u) & 3u, (p.w >> 4u) & 3u);
    edges = uvec3(p.y >> 16u, p.z & 0xFFFFu, p.z >> 16u) << 4u
            | uvec3((p.w >> 6u) & 15u, (p.w >> 10u) & 15u, (p.w >> 14u) & 15u);
}

// One table row blended: ((w0 * f0) + w1 * f1) + w2 * f2, as torch sums it.
vec4 mf_blend(MF_TABLE table, int log2w, uint index[3], vec3 weight) {
    return (weight.x * texelFetch(table, rows_texel(index[0], log2w), 0)
            + weight.y * texelFetch(table, rows_texel(index[1], log2w), 0))
           + weight.z * texelFetch(table, rows_texel(index[2], log2w), 0);
}
