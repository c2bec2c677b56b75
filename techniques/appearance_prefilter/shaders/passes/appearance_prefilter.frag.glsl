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
#include <lib/dap_view>
#include <choices>

uniform float u_dap_distance;     // dolly: the eye's distance to the box centre times this (> 0)
layout(location = 0) out vec4 frag_color;

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
    frag_color = dap_view_colour(ro, rd, t0, background);
}
