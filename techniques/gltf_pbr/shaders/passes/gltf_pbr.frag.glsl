// glTF reference pass: the mesh's glTF materials (lib/gltf_material) at each G-buffer pixel, shaded by
// the spec's BRDF (lib/gltf_brdf) with the scene's point lights and SH environment, plus emission.
// u_gltf_view (VIEWS in techniques/gltf_pbr/__init__.py; GLTF_VIEW_* from <choices>): the shaded
// result, or one channel of the material as the shader sees it (linear base colour, the mapped
// normal as 0.5 + 0.5 n, metallic, roughness, occlusion, emission).
#include <lib/gltf_gbuffer>
#include <choices>

uniform vec2 u_size;
uniform vec3 u_sh[SH_COEFFS];
uniform int u_gltf_view;
uniform int u_light_count;
layout(location = 0) out vec4 frag_color;

void main() {
    GltfPixel g;
    GltfSurface s;
    if (!gltf_pixel(gl_FragCoord.xy, u_size, g, s)) {
        frag_color = vec4(sh_background(-g.v, u_sh), 1.0);
        return;
    }
    vec3 c;
    if (u_gltf_view == GLTF_VIEW_BASE_COLOR) c = s.s.base_color;
    else if (u_gltf_view == GLTF_VIEW_NORMAL) c = 0.5 + 0.5 * s.n;
    else if (u_gltf_view == GLTF_VIEW_METALLIC) c = vec3(s.s.metallic);
    else if (u_gltf_view == GLTF_VIEW_ROUGHNESS) c = vec3(s.s.roughness);
    else if (u_gltf_view == GLTF_VIEW_OCCLUSION) c = vec3(s.occlusion);
    else if (u_gltf_view == GLTF_VIEW_EMISSIVE) c = s.emissive;
    else c = gltf_shade(s, g.p, g.v, u_sh, u_light_count);
    frag_color = vec4(c, 1.0);
}
