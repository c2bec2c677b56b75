// The material network <network_mat> (mesh_features -> MLP) at a surface point: face k,
// barycentrics t = (t0, t1) of the face's vertices 0, 1. Its output lanes are the caller's to read
// (lib/uvf_material: the 9 channels of the technique's own material; lib/uvf_gltf: a glTF file's).
#include <network_mat>

void uvf_eval(uint k, vec2 t, out vec4 y[MAT_OUT_BLOCKS]) {
    uvec4 xu[MAT_IN_UINT_BLOCKS];
    xu[0] = uvec4(k, 0u, 0u, 0u);
    vec4 x[MAT_IN_BLOCKS];
    x[0] = vec4(t, 0.0, 0.0);
    mat_eval(xu, x, y);
}
