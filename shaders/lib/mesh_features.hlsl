// UV-free hashed per-triangle feature hierarchy in HLSL and Slang (mesh_features.glsl for OpenGL and
// Vulkan; models/mesh_features.py has the torch twin and the rules, geometry/mesh_topology.py the
// owner tables). All integer work is uint wrap-around arithmetic, bit-exact with torch; the float
// work is the same float32 operations in the same order.
#include <lib/texture_rows>

// The level's sub-triangle of a point with barycentrics t = (t0, t1): sub-vertices w[v] =
// (W0, W1) (W2 = 2^level - W0 - W1) and their weights, in the order the rule lists them.
void mf_subtriangle(float2 t, int level, out int2 w[3], out float3 weight) {
    float r = (float)(1 << level);
    float2 a = r * t;                                 // exact: r is a power of two
    float i = clamp(floor(a.x), 0.0, r - 1.0);
    float j = clamp(floor(a.y), 0.0, (r - 1.0) - i);
    float f0 = a.x - i;
    float f1 = a.y - j;
    int2 ij = int2((int)i, (int)j);
    if (i + j == r - 1.0 || f0 + f1 <= 1.0) {         // upright (always on the last diagonal)
        w[0] = ij; w[1] = ij + int2(1, 0); w[2] = ij + int2(0, 1);
        weight = float3((1.0 - f0) - f1, f0, f1);
    } else {                                          // rotated
        w[0] = ij + int2(1, 1); w[1] = ij + int2(0, 1); w[2] = ij + int2(1, 0);
        weight = float3((f0 + f1) - 1.0, 1.0 - f0, 1.0 - f1);
    }
}

// The canonical name (k', W'0, W'1) of sub-vertex W = (W0, W1, W2) of face k: a mesh vertex
// is named by its corner owner, a point on an edge by the edge's owner, an interior point by k.
uint3 mf_canonical(uint k, int3 W, int level, uint3 corners, uint3 edges) {
    int r = 1 << level;
    for (int s = 0; s < 3; ++s) {
        if (W[s] == r) {
            uint c = corners[s];
            uint3 w = (uint3)0u;
            w[(int)(c & 3u)] = (uint)r;
            return uint3(c >> 2u, w.x, w.y);
        }
    }
    for (int s2 = 0; s2 < 3; ++s2) {
        if (W[s2] == 0) {
            uint e = edges[s2];
            uint3 w = (uint3)0u;
            w[(int)((e >> 2u) & 3u)] = (uint)W[(s2 + 1) % 3];
            w[(int)(e & 3u)] = (uint)W[(s2 + 2) % 3];
            return uint3(e >> 4u, w.x, w.y);
        }
    }
    return uint3(k, (uint2)W.xy);
}

// The full 32-bit hash of a canonical sub-vertex (the thesis's eq. 5.8, pi3 reduced mod 2^32).
uint mf_hash(uint3 kw, int level) {
    return (2654435761u * kw.x) ^ kw.y ^ (805459861u * kw.z) ^ (1094488767u * (uint)level);
}

// Row of the feature table: level l owns rows l*T .. l*T + T - 1 (T a power of two).
uint mf_hash_index(uint3 kw, int level, uint table_size) {
    return (uint)level * table_size + (mf_hash(kw, level) & (table_size - 1u));
}

// The three table rows and weights of face k's point t at one level.
void mf_level_taps(uint k, float2 t, int level, uint table_size, uint3 corners, uint3 edges,
                   out uint index[3], out float3 weight) {
    int2 w[3];
    mf_subtriangle(t, level, w, weight);
    int r = 1 << level;
    for (int v = 0; v < 3; ++v) {
        int3 W = int3(w[v], r - w[v].x - w[v].y);
        index[v] = mf_hash_index(mf_canonical(k, W, level, corners, edges), level, table_size);
    }
}

// Face k's owner tables from a texture holding 2 texels per face: texel 2k = corners.xyz,
// texel 2k + 1 = edges.xyz.
void mf_face_tables(Texture2D<uint4> topo, uint k, int log2w, out uint3 corners, out uint3 edges) {
    corners = topo.Load(int3(rows_texel(2u * k, log2w), 0)).xyz;
    edges = topo.Load(int3(rows_texel(2u * k + 1u, log2w), 0)).xyz;
}

// The same from 1 texel per face, every id < 2^16 and two to a channel:
// (c0 | c1 << 16, c2 | e0 << 16, e1 | e2 << 16).
void mf_face_tables16(Texture2D<uint4> topo, uint k, int log2w, out uint3 corners, out uint3 edges) {
    uint3 p = topo.Load(int3(rows_texel(k, log2w), 0)).xyz;
    corners = uint3(p.x & 0xFFFFu, p.x >> 16u, p.y & 0xFFFFu);
    edges = uint3(p.y >> 16u, p.z & 0xFFFFu, p.z >> 16u);
}

// The same from 1 RGBA texel per face, every owner face < 2^16: the six owners two to a channel,
// their slot bits in w (corners 2 bits each from bit 0, edges 4 bits each from bit 6).
void mf_face_owners16(Texture2D<uint4> topo, uint k, int log2w, out uint3 corners, out uint3 edges) {
    uint4 p = topo.Load(int3(rows_texel(k, log2w), 0));
    corners = uint3(p.x & 0xFFFFu, p.x >> 16u, p.y & 0xFFFFu) << 2u
              | uint3(p.w & 3u, (p.w >> 2u) & 3u, (p.w >> 4u) & 3u);
    edges = uint3(p.y >> 16u, p.z & 0xFFFFu, p.z >> 16u) << 4u
            | uint3((p.w >> 6u) & 15u, (p.w >> 10u) & 15u, (p.w >> 14u) & 15u);
}

// One table row blended: ((w0 * f0) + w1 * f1) + w2 * f2, as torch sums it.
float4 mf_blend(Texture2D<float4> table, int log2w, uint index[3], float3 weight) {
    return (weight.x * table.Load(int3(rows_texel(index[0], log2w), 0))
            + weight.y * table.Load(int3(rows_texel(index[1], log2w), 0)))
           + weight.z * table.Load(int3(rows_texel(index[2], log2w), 0));
}
