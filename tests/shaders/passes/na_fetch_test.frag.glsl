// Test pass for lib/na_reference's na_fetch_parameters: one sample per pixel, (uv, lod, -) read
// from u_inputs (data orientation); the caller binds u_na_param0..2. Attachments 0-2: p0, p1, p2.
// Used by tests/techniques/neural_appearance/test_neural_appearance_material.py.
#include <lib/na_reference>
#include <lib/test_pass>

layout(location = 0) out vec4 out_p0;
layout(location = 1) out vec4 out_p1;
layout(location = 2) out vec4 out_p2;

void main() {
    vec4 t = test_input(0);
    na_fetch_parameters(t.xy, t.z, out_p0, out_p1, out_p2);
}
