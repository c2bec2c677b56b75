// Deep Appearance Prefiltering (Bako et al. 2022) as a full-screen pass: every pixel marches its
// beam through the sparse voxel grid of network <network_dap> (component sparse_voxels + decoders)
// at the scale its footprint asks for, blending the two nearest scales (lib/dap_march, where the
// march is written out step by step; torch twin techniques/appearance_prefilter/march.py).
// The technique record (techniques/appearance_prefilter/__init__.py) generates <dap_config>
// (DAP_MASK, DAP_BINS, DAP_BINS_THETA, DAP_BINS_PHI from the bundle's render metadata) and asks for
// the sun's shadow map (ProgramSpec.shadows; u_dap_shadows 0 or no map: no global shadows).
// u_dap_view (VIEWS in the record; DAP_VIEW_* from <choices>): prefiltered | scale (the scale L
// each pixel marched at, as a ramp x = (L - S_MIN) / (S_MAX - S_MIN) from blue (coarsest) through
// green to red (finest), on what the pixel covers, over black) | coverage (mean Lambda as grey) |
// albedo (coverage-weighted albedo).
// Lighting: the scene's first directional light (E_sun = its intensity, white) and the SH
// environment u_sh. Linear radiance; alpha = mean coverage.
#include <lib/camera>
#include <lib/lights>
#include <network_dap>
#include <dap_config>
#include <lib/dap_march>
#include <choices>

uniform vec2 u_size;
uniform mat4 u_proj;
uniform vec3 u_sh[SH_COEFFS];
uniform float u_dap_distance;     // dolly: the eye's distance to the box centre times this (> 0)
uniform int u_dap_force_scale;    // >= 0: march this scale only (tests, bench)
uniform int u_dap_view;
uniform int u_dap_shadows;        // 0: no global shadows
layout(location = 0) out vec4 frag_color;

vec3 dap_ramp(float x) {
    return vec3(x, 1.0 - abs(2.0 * x - 1.0), 1.0 - x);
}

void main() {
    vec3 ro, rd;
    camera_ray(gl_FragCoord.xy, u_size, ro, rd);
    ro = 0.5 + (ro - 0.5) * u_dap_distance;
    vec3 background = sh_background(rd, u_sh);
    float t0, t1;
    if (!unit_box(ro, rd, t0, t1)) {
        frag_color = vec4(u_dap_view == DAP_VIEW_PREFILTERED ? background : vec3(0.0), 0.0);
        return;
    }
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
    frag_color = vec4(colour, a.coverage);
}
