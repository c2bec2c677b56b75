// glTF reference pass: the mesh's glTF materials (lib/gltf_material) at each G-buffer pixel, shaded by
// the spec's BRDF (lib/gltf_brdf) with the scene's point lights and SH environment, plus emission.
// u_gltf_view (VIEWS in techniques/gltf_pbr/__init__.py; GLTF_VIEW_* from <choices>): the shaded
// result, or one channel of the material as the shader sees it (linear base colour, the mapped
// normal as 0.5 + 0.5 n, metallic, roughness, occlusion, emission).
#include <lib/camera>
#include <lib/gbuffer>
#include <lib/gltf_material>
#include <choices>

uniform vec2 u_size;
uniform vec3 u_sh[SH_COEFFS];
uniform sampler2D u_gbuffer_uv_grad;
uniform int u_gltf_view;
uniform int u_light_count;
layout(location = 0) out vec4 frag_color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 p, n;
    bool covered = gbuffer_surface(px, p, n);
    vec3 ro, rd;
    camera_ray(gl_FragCoord.xy, u_size, ro, rd);
    if (!covered) {
        frag_color = vec4(sh_background(rd, u_sh), 1.0);
        return;
    }
    vec4 uv = texelFetch(u_gbuffer_uv, px, 0);
    GltfSurface s = gltf_surface(int(uv.z + 0.5), uv.xy, texelFetch(u_gbuffer_uv_grad, px, 0), n,
                                 texelFetch(u_gbuffer_tangent, px, 0), -rd);
    vec3 c;
    if (u_gltf_view == GLTF_VIEW_BASE_COLOR) c = s.s.base_color;
    else if (u_gltf_view == GLTF_VIEW_NORMAL) c = 0.5 + 0.5 * s.n;
    else if (u_gltf_view == GLTF_VIEW_METALLIC) c = vec3(s.s.metallic);
    else if (u_gltf_view == GLTF_VIEW_ROUGHNESS) c = vec3(s.s.roughness);
    else if (u_gltf_view == GLTF_VIEW_OCCLUSION) c = vec3(s.occlusion);
    else if (u_gltf_view == GLTF_VIEW_EMISSIVE) c = s.emissive;
    else c = gltf_shade(s, p, -rd, u_sh, u_light_count);
    frag_color = vec4(c, 1.0);
}
