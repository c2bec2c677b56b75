// Test program for ProgramSpec.shadows through the real SceneRenderer (tests/runtime/test_shadow_map.py):
// pixel (x, y) of the target looks at the ground point (x + 0.5) / u_size.x, 0, (y + 0.5) / u_size.y
// of a unit-square ground and writes shadow_visibility of it for light u_layer, bias u_bias.
#define SHADOW_MAX_LAYERS 4
#include <lib/shadow_map>

uniform vec2 u_size;
uniform int u_layer;
uniform float u_bias;
layout(location = 0) out vec4 frag_color;

void main() {
    vec2 g = gl_FragCoord.xy / u_size;
    frag_color = vec4(vec3(shadow_visibility(vec3(g.x, 0.0, g.y), u_layer, u_bias)), 1.0);
}
