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
#include <lib/dap_view>
#include <choices>

#if !defined(DAP_WORLD_CENTRE) || !defined(DAP_WORLD_SCALE)
#error "passes/appearance_prefilter_gltf.frag needs DAP_WORLD_CENTRE and DAP_WORLD_SCALE (the bundle's render.world)"
#endif

layout(location = 0) out vec4 frag_color;

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
    return dap_view_colour(ro, rd, t0, background);
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
