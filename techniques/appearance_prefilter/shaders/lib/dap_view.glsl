// What both prefiltering passes (passes/appearance_prefilter, passes/appearance_prefilter_gltf) show
// of the voxels along a pixel's beam, and the settings they share: u_dap_view (DAP_VIEW_* from
// <choices>: prefiltered, or the scale ramp, coverage, albedo), u_dap_force_scale (>= 0: march this
// scale only; tests, bench) and u_dap_shadows (0: no global shadows).
#include <lib/camera>
#include <lib/dap_march>
#include <choices>

uniform vec2 u_size;
uniform mat4 u_proj;
uniform vec3 u_sh[SH_COEFFS];
uniform int u_dap_force_scale;
uniform int u_dap_view;
uniform int u_dap_shadows;

vec3 dap_ramp(float x) {
    return vec3(x, 1.0 - abs(2.0 * x - 1.0), 1.0 - x);
}

// The beam (ro, rd) in box coordinates, entering the unit box at t0, over the background; alpha =
// mean coverage.
vec4 dap_view_colour(vec3 ro, vec3 rd, float t0, vec3 background) {
    float px = 2.0 / (u_proj[1][1] * u_size.y);
    float L = dap_footprint_scale(t0, px, u_dap_force_scale);
    vec3 sun_dir, sun;
    dap_scene_sun(sun_dir, sun);
    DapPixel p = dap_pixel(ro, rd, px, t0, sun_dir, sun, u_sh);
    DapResult a = dap_march_at(p, L, u_dap_shadows != 0);
    vec3 colour = a.radiance + (1.0 - a.coverage) * background;
    if (u_dap_view == DAP_VIEW_COVERAGE) colour = vec3(a.coverage);
    if (u_dap_view == DAP_VIEW_ALBEDO) colour = a.albedo;
    if (u_dap_view == DAP_VIEW_SCALE) {
        colour = a.coverage * dap_ramp((L - float(DAP_SCALE_MIN)) / float(max(DAP_SCALE_MAX - DAP_SCALE_MIN, 1)));
    }
    return vec4(colour, a.coverage);
}
