// Test pass for lib/lights: one sample per pixel, (p.xyz, light index) from texel (x, y) of
// u_inputs (data orientation) -> (to_light.xyz, irradiance_scale) of scene_light(index, p).
// Used by tests/runtime/test_lights.py.
#include <lib/lights>
#include <lib/test_pass>

layout(location = 0) out vec4 frag_out;

void main() {
    vec4 t = test_input(0);
    vec3 to_light;
    float irradiance_scale;
    scene_light(int(t.w), t.xyz, to_light, irradiance_scale);
    frag_out = vec4(to_light, irradiance_scale);
}
