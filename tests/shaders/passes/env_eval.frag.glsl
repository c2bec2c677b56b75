// Test pass for lib/environment: per pixel two texels of u_inputs (data orientation):
// texel 2x = (u.x, u.y, a, b), texel 2x+1 = (direction xyz, 0). Outputs: 0: env_sample(u) xyz +
// its pdf in w; 1: env_radiance(dir) rgb + env_pdf(dir) in w; 2: (mis_power(a, b), mis_power(b, a)).
// Used by tests/runtime/test_environment.py.
#include <lib/environment>

uniform sampler2D u_inputs;
layout(location = 0) out vec4 out_sample;
layout(location = 1) out vec4 out_lookup;
layout(location = 2) out vec4 out_mis;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 a = texelFetch(u_inputs, ivec2(2 * p.x, p.y), 0);
    vec3 dir = texelFetch(u_inputs, ivec2(2 * p.x + 1, p.y), 0).xyz;
    float pdf;
    vec3 d = env_sample(a.xy, pdf);
    out_sample = vec4(d, pdf);
    out_lookup = vec4(env_radiance(dir), env_pdf(dir));
    out_mis = vec4(mis_power(a.z, a.w), mis_power(a.w, a.z), 0.0, 0.0);
}
