// A glTF material's PBR set (Differentiable Indirection, Datta et al. 2023 4.2.1) decoded into the
// reference surface. Eight lanes, in techniques/di_pbr_set/gltf_lanes.py LANES order, as two vec4:
//   a = (albedo.rgb [sRGB-encoded], normal.x), b = (normal.y, roughness, occlusion, metallic)
// with the tangent-space normal's x, y stored as 0.5 + 0.5 n (x along t, y along b = +v) and z
// rebuilt as sqrt(1 - x^2 - y^2). The lanes cover a rectangle of the mesh's uv (the generated
// <pbr_set_gltf_domain>: PBR_GLTF_MATERIAL, PBR_GLTF_UV_ORIGIN, PBR_GLTF_UV_EXTENT,
// PBR_GLTF_REPEAT_U/V); the rest of the surface (emission, clearcoat, sheen, ior) stays the file's.
#include <lib/gltf_material>
#include <pbr_set_gltf_domain>

// Mesh uv -> the network's uv: the domain's rectangle mapped onto [0, 1]^2, wrapped along an axis
// whose textures repeat with the rectangle's period, clamped along one it spans.
vec2 pbr_set_gltf_uv(vec2 uv) {
    vec2 x = (uv - PBR_GLTF_UV_ORIGIN) / PBR_GLTF_UV_EXTENT;
    return vec2(PBR_GLTF_REPEAT_U ? fract(x.x) : clamp(x.x, 0.0, 1.0),
                PBR_GLTF_REPEAT_V ? fract(x.y) : clamp(x.y, 0.0, 1.0));
}

// The reference surface s of material m with the lanes' channels in place of the file's: base
// colour, roughness, occlusion, metallic and the normal map (in the same frame gltf_surface maps
// it in: the back of a double-sided surface flipped); the anisotropy direction follows the new normal.
void pbr_set_gltf_decode(inout GltfSurface s, vec4 a, vec4 b, int m, vec3 ng, vec4 tangent, vec3 v) {
    s.s.base_color = srgb_eotf(clamp(a.xyz, 0.0, 1.0));
    s.s.roughness = clamp(b.y, MATERIAL_MIN_ROUGHNESS, 1.0);
    s.occlusion = clamp(b.z, 0.0, 1.0);
    s.s.metallic = clamp(b.w, 0.0, 1.0);
    vec2 nxy = vec2(a.w, b.x) * 2.0 - 1.0;
    vec3 nt = vec3(nxy, sqrt(max(1.0 - nxy.x * nxy.x - nxy.y * nxy.y, 0.0)));
    vec3 t, bt;
    gltf_tangent_frame(ng, tangent, t, bt);
    if (material_param(m, 5).x > 0.5 && gltf_dot(ng, v) < 0.0) {   // as gltf_surface: double-sided, seen from behind
        ng = -ng; t = -t; bt = -bt;
    }
    s.n = gltf_mapped_normal(nt, t, bt, ng);
    vec3 at = s.at - s.n * gltf_dot(s.n, s.at);
    s.at = at * inversesqrt(max(gltf_dot(at, at), 1e-30));
    s.ab = cross(s.n, s.at);
}
