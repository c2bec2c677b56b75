// Test pass for lib/gltf_brdf: one sample per pixel, 10 texels side by side in u_inputs (data
// orientation): t0 = (n.xyz, at.x), t1 = (at.yz, ab.xy), t2 = (ab.z, nc.xyz), t3 = (v.xyz, l.x),
// t4 = (l.yz, base.xy), t5 = (base.z, metallic, roughness, f0), t6 = (clearcoat, clearcoat
// roughness, sheen.xy), t7 = (sheen.z, sheen roughness, anisotropy, -), t8 = (irradiance.xyz, -),
// t9 = (radiance.xyz, -). Attachment 0: gltf_brdf; attachment 1: gltf_environment.
// Used by tests/models/test_gltf_brdf.py.
#define TEST_TEXELS 10
#include <lib/gltf_brdf>
#include <lib/test_pass>

layout(location = 0) out vec4 out_brdf;
layout(location = 1) out vec4 out_environment;

void main() {
    vec4 t[TEST_TEXELS];
    test_inputs(t);
    GltfShading s = GltfShading(vec3(t[4].zw, t[5].x), t[5].y, t[5].z, t[5].w, t[6].x, t[6].y,
                                vec3(t[6].zw, t[7].x), t[7].y, t[7].z);
    vec3 n = t[0].xyz, at = vec3(t[0].w, t[1].xy), ab = vec3(t[1].zw, t[2].x), nc = t[2].yzw;
    vec3 v = t[3].xyz, l = vec3(t[3].w, t[4].xy);
    out_brdf = vec4(gltf_brdf(s, n, at, ab, nc, v, l), 1.0);
    out_environment = vec4(gltf_environment(s, n, v, t[8].xyz, t[9].xyz), 1.0);
}
