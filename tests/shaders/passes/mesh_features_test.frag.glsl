// Test pass for lib/mesh_features: one sample per pixel, 3 texels side by side in u_inputs
// (data orientation, small exact integers as floats): (k, W0, W1, level), (corners.xyz,
// edges.x), (edges.yz, t0, t1). Outputs (all exact in float32 for the test's small meshes):
//   0: mf_canonical of sub-vertex (W0, W1) of face k: (k', W'0, W'1, low 16 bits of mf_hash)
//   1: (high 16 bits of mf_hash, mf_hash_index with u_table_size, 0, 0)
//   2: mf_subtriangle(t, level) sub-vertices (w0.x, w0.y, w1.x, w1.y)
//   3: (w2.x, w2.y, weight.x, weight.y)
//   4: (weight.z, mf_level_taps indices 0..2)
// Used by tests/components/test_mesh_features.py.
#define TEST_TEXELS 3
#include <lib/mesh_features>
#include <lib/test_pass>

uniform uint u_table_size;
layout(location = 0) out vec4 frag_out[5];

void main() {
    vec4 a = test_input(0), b = test_input(1), c = test_input(2);
    uint k = uint(a.x);
    int level = int(a.w);
    uvec3 corners = uvec3(b.xyz);
    uvec3 edges = uvec3(uint(b.w), uint(c.x), uint(c.y));
    int r = 1 << level;
    ivec3 W = ivec3(int(a.y), int(a.z), r - int(a.y) - int(a.z));
    uvec3 kw = mf_canonical(k, W, level, corners, edges);
    uint h = mf_hash(kw, level);
    frag_out[0] = vec4(vec3(kw), float(h & 0xFFFFu));
    frag_out[1] = vec4(float(h >> 16u), float(mf_hash_index(kw, level, u_table_size)), 0.0, 0.0);
    ivec2 w[3];
    vec3 weight;
    mf_subtriangle(c.zw, level, w, weight);
    frag_out[2] = vec4(vec2(w[0]), vec2(w[1]));
    frag_out[3] = vec4(vec2(w[2]), weight.xy);
    uint index[3];
    vec3 weight2;
    mf_level_taps(k, c.zw, level, u_table_size, corners, edges, index, weight2);
    frag_out[4] = vec4(weight.z, float(index[0]), float(index[1]), float(index[2]));
}
