// Test pass for lib/pbr_set: one sample per pixel, read from 6 texels side by side in u_inputs
// (data orientation): lanes 0-3, lanes 4-7, (p, -), (geometric normal, -), tangent (xyz,
// handedness), (view ray, -). Attachment 0: (pbr_shade(...), 1). Needs chunks=sh_chunks(d).
// Used by tests/test_pbr_set.py.
#define TEST_TEXELS 6
#include <lib/pbr_set>
#include <lib/test_pass>

uniform vec3 u_sh[SH_COEFFS];
uniform int u_light_count;
layout(location = 0) out vec4 frag_out;

void main() {
    vec4 t[TEST_TEXELS];
    test_inputs(t);
    frag_out = vec4(pbr_shade(pbr_set_unpack(t[0], t[1]), t[2].xyz, t[3].xyz, t[4], t[5].xyz, u_sh,
                                  u_light_count), 1.0);
}
