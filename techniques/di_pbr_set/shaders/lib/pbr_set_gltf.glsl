// A glTF material's PBR set (Differentiable Indirection, Datta et al. 2023 4.2.1) decoded into the
// reference surface: the channels lib/pbr_set_gltf_channels decodes from the network (base colour,
// normal map, roughness, occlusion, metallic) in place of the file's; the rest of the surface
// (emission, clearcoat, sheen, ior) stays the file's.
#include <lib/gltf_material>
#include <lib/pbr_set_gltf_channels>

// The reference surface s of material m with the lanes' channels in place of the file's: base
// colour, roughness, occlusion, metallic and the normal map (in the same frame gltf_surface maps
// it in: the back of a double-sided surface flipped); the anisotropy direction follows the new normal.
void pbr_set_gltf_decode(inout GltfSurface s, MaterialChannels c, int m, vec3 ng, vec4 tangent, vec3 v) {
    s.s.base_color = c.base_color;
    s.s.roughness = max(c.roughness, MATERIAL_MIN_ROUGHNESS);
    s.occlusion = c.occlusion;
    s.s.metallic = c.metallic;
    vec3 t, bt;
    gltf_tangent_frame(ng, tangent, t, bt);
    if (material_param(m, 5).x > 0.5 && gltf_dot(ng, v) < 0.0) {   // as gltf_surface: double-sided, seen from behind
        ng = -ng; t = -t; bt = -bt;
    }
    s.n = gltf_mapped_normal(c.normal, t, bt, ng);
    vec3 at = s.at - s.n * gltf_dot(s.n, s.at);
    s.at = at * inversesqrt(max(gltf_dot(at, at), 1e-30));
    s.ab = cross(s.n, s.at);
}
