// toy_rings: the network's rgb (a sine layer of uv) mapped to [0, 1], times the palette and the
// per-frame tint. Pixel centres: uv = gl_FragCoord.xy / u_size.
#include <network>
#include <toy_palette>

uniform vec2 u_size;
uniform vec3 u_toy_tint;
layout(location = 0) out vec4 frag_color;

void main() {
    vec4 x[NET_IN_BLOCKS];
    x[0] = vec4(gl_FragCoord.xy / u_size, 0.0, 0.0);
    vec4 y[NET_OUT_BLOCKS];
    net_eval(x, y);
    frag_color = vec4((0.5 + 0.5 * y[0].xyz) * TOY_PALETTE * u_toy_tint, 1.0);
}
