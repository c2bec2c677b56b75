// A radiance-field network (position, direction -> rgb, density), ray marched through its box
// (lib/imported_field). Linear RGB over the constant background, alpha 1.
#include <lib/camera>
#include <network>
#include <imported_field_config>
#include <lib/imported_field>

uniform vec2 u_size;
layout(location = 0) out vec4 frag_color;

void main() {
    vec3 ro, rd;
    camera_ray(gl_FragCoord.xy, u_size, ro, rd);
    frag_color = field_march(ro, rd);
}
