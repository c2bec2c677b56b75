// toy_noise: one uniform random sample per pixel per draw (the runtime averages them). Attachment 1's
// alpha is the pixel centre's u under the plane2d camera (u_view = origin, extent): the camera is an
// input of the draw, as for any real program.
#include <lib/random>

uniform int u_sample_index;
uniform float u_gain;
uniform vec4 u_view;
uniform vec2 u_size;
layout(location = 0) out vec4 frag_color;
layout(location = 1) out vec4 frag_noise;

void main() {
    uvec2 px = uvec2(gl_FragCoord.xy);
    float u = u_view.x + gl_FragCoord.x / u_size.x * u_view.z;
    frag_color = vec4(u_gain * random_uniform3(px, u_sample_index, 0), 1.0);
    frag_noise = vec4(random_uniform3(px, u_sample_index, 1), u);
}
