// Test pass for the sparse_voxels emitter's fixed functions (components/sparse_voxels/emit.py), reached
// through a generated network chunk with prefix "net": one sample per pixel, one texel in u_inputs
// (data orientation, small exact integers as floats): (scale, i, j, k) of a cell query.
// Outputs: 0: (net_voxel_slot(scale, cell), NET_SCALE_MIN, NET_SCALE_MAX, NET_VOXELS);
//          1: net_voxel_sphere(uint(i)) (the i lane doubles as a slot query).
// Used by tests/components/test_sparse_voxels.py.
#include <network>
#include <lib/test_pass>

layout(location = 0) out vec4 frag_out[2];

void main() {
    vec4 a = test_input(0);
    uint slot = net_voxel_slot(int(a.x), ivec3(a.yzw));
    frag_out[0] = vec4(float(slot), float(NET_SCALE_MIN), float(NET_SCALE_MAX), float(NET_VOXELS));
    frag_out[1] = net_voxel_sphere(uint(max(a.y, 0.0)));
}
