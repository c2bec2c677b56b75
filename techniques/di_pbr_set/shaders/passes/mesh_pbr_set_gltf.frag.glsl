// Mesh PBR-set pass over a glTF file (Differentiable Indirection, Datta et al. 2023 4.2.1): one of the
// file's materials compressed by DI (the bundle, <network>: uv -> 8 lanes, lib/pbr_set_gltf), next to
// the file's own material (lib/gltf_material gltf_surface, the reference). Both are shaded by the same
// gltf_shade (the spec's BRDF, the scene's point lights, the SH environment, the file's emission), so
// the two differ by what DI learnt alone. Deferred: the G-buffer gives position, normal, uv (material
// index in z), its footprint and the tangent per pixel; the network runs once per visible pixel.
// u_pbr_view (GLTF_VIEWS in techniques/di_pbr_set/__init__.py; PBR_VIEW_* from <choices>): reference |
// di | split (left half reference, right half DI) | error (|DI - reference| x u_pbr_error_scale).
// Faces of other materials stay the reference.
// DI is evaluated without a footprint (the base level), the reference samples the file's mip maps.
#include <network>
#include <lib/gltf_gbuffer>
#include <lib/pbr_set_gltf>
#include <choices>

#if NET_IN_DIM != 2 || NET_OUT_DIM < 8
#error "passes/mesh_pbr_set_gltf.frag needs a uv -> 8-lane network (inshade train di_pbr_set --gltf FILE)"
#endif

uniform vec2 u_size;
uniform vec3 u_sh[SH_COEFFS];
uniform int u_pbr_view;
uniform float u_pbr_error_scale;
uniform int u_light_count;
layout(location = 0) out vec4 frag_color;

void main() {
    GltfPixel g;
    GltfSurface s;
    bool error = u_pbr_view == PBR_VIEW_ERROR;
    if (!gltf_pixel(gl_FragCoord.xy, u_size, g, s)) {   // the sky: the same on both sides
        frag_color = vec4(error ? vec3(0.0) : sh_background(-g.v, u_sh), 1.0);
        return;
    }
    bool compressed = g.material == PBR_GLTF_MATERIAL && (u_pbr_view == PBR_VIEW_DI || error
                                                 || (u_pbr_view == PBR_VIEW_SPLIT && gl_FragCoord.x >= 0.5 * u_size.x));
    vec3 reference = error ? gltf_shade(s, g.p, g.v, u_sh, u_light_count) : vec3(0.0);
    if (compressed) {
        pbr_set_gltf_decode(s, material_channels(g.uv.xy), g.material, g.n, g.tangent, g.v);
    }
    vec3 c = gltf_shade(s, g.p, g.v, u_sh, u_light_count);
    frag_color = vec4(error ? abs(c - reference) * u_pbr_error_scale : c, 1.0);
}
