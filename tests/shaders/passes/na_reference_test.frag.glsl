// Test pass for lib/na_reference: one sample per pixel, read from 5 texels side by side in
// u_inputs (data orientation): p0, p1, p2, (light.xyz, -), (view.xyz, -). Attachment 0:
// (na_reflectance(p0, p1, p2, light, view), 1). The u_na_* uniforms come from
// material.uniforms(). Used by tests/techniques/neural_appearance/test_neural_appearance_material.py.
#include <lib/na_reference>

uniform sampler2D u_inputs;
layout(location = 0) out vec4 frag_out;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 t[5];
    for (int i = 0; i < 5; ++i) t[i] = texelFetch(u_inputs, ivec2(p.x * 5 + i, p.y), 0);
    frag_out = vec4(na_reflectance(t[0], t[1], t[2], t[3].xyz, t[4].xyz), 1.0);
}
