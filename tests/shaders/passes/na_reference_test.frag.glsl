// Test pass for lib/na_reference: one sample per pixel, read from 5 texels side by side in
// u_inputs (data orientation): p0, p1, p2, (light.xyz, -), (view.xyz, -). Attachment 0:
// (na_reflectance(p0, p1, p2, light, view), 1). The u_na_* uniforms come from
// material.uniforms(). Used by tests/techniques/neural_appearance/test_neural_appearance_material.py.
#define TEST_TEXELS 5
#include <lib/na_reference>
#include <lib/test_pass>

layout(location = 0) out vec4 frag_out;

void main() {
    vec4 t[TEST_TEXELS];
    test_inputs(t);
    frag_out = vec4(na_reflectance(t[0], t[1], t[2], t[3].xyz, t[4].xyz), 1.0);
}
