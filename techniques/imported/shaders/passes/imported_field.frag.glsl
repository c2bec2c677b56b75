// A radiance-field network (position, direction -> rgb, density), ray marched through its box
// (lib/field_march). Linear RGB over the constant background, alpha 1.
#include <lib/camera>
#include <network>
#include <field_config>
#include <lib/field_march>

uniform vec2 u_size;
layout(location = 0) out vec4 frag_color;

void main() {
    vec3 ro, rd;
    camera_ray(gl_FragCoord.xy, u_size, ro, rd);
    frag_color = field_march(ro, rd);
}
