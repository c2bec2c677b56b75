// Test pass for lib/shadow_map (tests/runtime/test_shadow_map.py): one point per pixel, (p.xyz, layer) from
// texel (x, y) of u_points (data orientation) -> shadow_visibility(p, layer, u_bias) in every channel.
#include <lib/shadow_map>

uniform sampler2D u_points;
uniform float u_bias;
layout(location = 0) out vec4 frag_out;

void main() {
    vec4 t = texelFetch(u_points, ivec2(gl_FragCoord.xy), 0);
    frag_out = vec4(shadow_visibility(t.xyz, int(t.w), u_bias));
}
