// instant-NGP's radiance field in a fragment shader: a hash-grid field (network hgrf) ray marched
// through its box with the occupancy grid (network hgocc) stepping over empty cells
// (lib/radiance_field_march). u_hgrf_view (HGRF_VIEW_* from <choices>): the composited radiance
// (linear RGB over the background, alpha 1) | the network evaluations per pixel / 64 (grey);
// u_hgrf_empty_space: HGRF_EMPTY_SKIP | HGRF_EMPTY_EVALUATE (every sample, the grid unused).
// The held-out reference image, split and error views are the scene's reference and display modes.
#include <lib/camera>
#include <network_hgrf>
#include <network_hgocc>
#include <radiance_field_config>
#include <lib/radiance_field_march>
#include <choices>

uniform vec2 u_size;
uniform int u_hgrf_view;
uniform int u_hgrf_empty_space;
layout(location = 0) out vec4 frag_color;

void main() {
    vec3 ro, rd;
    camera_ray(gl_FragCoord.xy, u_size, ro, rd);
    int evals;
    vec3 c = hgrf_march(ro, rd, u_hgrf_empty_space == HGRF_EMPTY_SKIP, evals);
    frag_color = u_hgrf_view == HGRF_VIEW_SAMPLES ? vec4(vec3(min(float(evals) / 64.0, 1.0)), 1.0) : vec4(c, 1.0);
}
