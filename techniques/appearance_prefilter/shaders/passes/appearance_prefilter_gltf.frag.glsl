// Deep Appearance Prefiltering (Bako et al. 2022) of a glTF file, next to the file's reference shading.
// The file is the scene's mesh, drawn in its own coordinates: the G-buffer feeds the reference
// (lib/gltf_material's gltf_surface + gltf_shade: the spec's BRDF with the file's textures, under
// the scene's sun and SH environment); the prefiltered half marches each pixel's beam through the
// voxels as passes/appearance_prefilter.frag does (lib/dap_march), the camera ray taken into the
// unit box the voxels were built in: box = (world - DAP_WORLD_CENTRE) * DAP_WORLD_SCALE + 0.5 (the
// record's <dap_config>, from the bundle's render.world). A uniform scale keeps directions, and the
// footprint per unit distance; the march's distances are the box's.
// They differ by design: the voxels carry a per-face material (no normal, occlusion or emissive
// textures, no KHR lobes), their BRDF is the bake's (Burley diffuse + GGX, techniques/
// appearance_prefilter/brdf_np.py), and their sun is shadowed (u_dap_shadows); the reference has
// no cast shadows.
// u_dap_view (GLTF_VIEWS in the record; DAP_VIEW_* from <choices>): prefiltered | scale | coverage |
// albedo (as passes/appearance_prefilter.frag) | reference | split (left half reference, right
// half prefiltered). Linear radiance; alpha = mean coverage (prefiltered), 1 (reference, split).
#include <lib/gltf_gbuffer>
#include <lib/lights>
#include <network_dap>
#include <dap_config>
#include <lib/dap_march>
#include <choices>

#if !defined(DAP_WORLD_CENTRE) || !defined(DAP_WORLD_SCALE)
#error "passes/appearance_prefilter_gltf.frag needs DAP_WORLD_CENTRE and DAP_WORLD_SCALE (the bundle's render.world)"
#endif

uniform vec2 u_size;
uniform mat4 u_proj;
uniform vec3 u_sh[SH_COEFFS];
uniform int u_dap_force_scale;    // >= 0: march this scale only
uniform int u_dap_view;
uniform int u_dap_shadows;        // 0: no global shadows
layout(location = 0) out vec4 frag_color;

vec3 dap_ramp(float x) {
    return vec3(x, 1.0 - abs(2.0 * x - 1.0), 1.0 - x);
}

// The file's reference shading at this pixel (passes/gltf_pbr.frag's, every light of the scene).
vec3 reference_colour(vec3 background) {
    GltfPixel g;
    GltfSurface s;
    if (!gltf_pixel(gl_FragCoord.xy, u_size, g, s)) {
        return background;
    }
    return gltf_shade(s, g.p, g.v, u_sh, INSHADE_MAX_LIGHTS);
}

// The prefiltered voxels along the world ray (ro, rd): passes/appearance_prefilter.frag's main at
// distance 1, in box coordinates.
vec4 prefiltered_colour(vec3 ro_world, vec3 rd, vec3 background) {
    vec3 ro = 0.5 + (ro_world - DAP_WORLD_CENTRE) * DAP_WORLD_SCALE;
    float t0, t1;
    if (!unit_box(ro, rd, t0, t1)) {
        return vec4(u_dap_view == DAP_VIEW_PREFILTERED || u_dap_view == DAP_VIEW_SPLIT ? background : vec3(0.0), 0.0);
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
    return vec4(colour, a.coverage);
}

void main() {
    vec3 ro, rd;
    camera_ray(gl_FragCoord.xy, u_size, ro, rd);
    vec3 background = sh_background(rd, u_sh);
    bool reference = u_dap_view == DAP_VIEW_REFERENCE
                     || (u_dap_view == DAP_VIEW_SPLIT && gl_FragCoord.x < 0.5 * u_size.x);
    if (reference) {
        frag_color = vec4(reference_colour(background), 1.0);
        return;
    }
    frag_color = prefiltered_colour(ro, rd, background);
    if (u_dap_view == DAP_VIEW_SPLIT) {
        frag_color.a = 1.0;   // both halves opaque: the background is already in the colour
    }
}
