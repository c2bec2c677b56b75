// Test-only scene program (registered by tests/runtime/test_environment.py, geometry "sdf"): the
// environment texture seen along each camera ray (the runtime binds lib/environment's textures),
// the ray direction in attachment 1 so the test can look the same directions up in numpy.
#include <lib/camera>
#include <lib/environment>

uniform vec2 u_size;
layout(location = 0) out vec4 frag_color;
layout(location = 1) out vec4 frag_dir;

void main() {
    vec3 ro, rd;
    camera_ray(gl_FragCoord.xy, u_size, ro, rd);
    frag_color = vec4(env_radiance(rd), 1.0);
    frag_dir = vec4(rd, env_pdf(rd));
}
