// glTF materials at a G-buffer pixel: the factors and textures lib/gltf_textures reads, the
// G-buffer's uv footprint choosing the mip level; then shaded by lib/gltf_brdf with the scene's
// lights and SH environment. The reference every learnt material of a glTF file is compared with.
// The G-buffer's uv run v up (the project's convention); glTF's run v down: g = (u, 1 - v).
// Alpha: MASK surfaces are cut out by the G-buffer pass (passes/mesh_gbuffer with lib/gltf_cutout); BLEND
// surfaces are peeled into layers of their own, each shaded here and laid over what lies behind by its
// alpha (runtime/renderer.py _peel, passes/gltf_blend_layer).
#include <lib/colour>
#include <lib/gltf_textures>
#include <lib/gltf_brdf>
#include <lib/lights>
#include <lib/spherical_harmonics>

// the smoothest surface shaded: GGX at roughness 0 is a delta, NaN at its peak
#define MATERIAL_MIN_ROUGHNESS 0.02

struct GltfSurface {
    GltfShading s;
    vec3 n;            // shading normal (normal map applied)
    vec3 nc;           // clearcoat normal
    vec3 at;           // anisotropy direction (orthogonal to n)
    vec3 ab;           // cross(n, at)
    float occlusion;   // scales the environment's light
    vec3 emissive;
    float alpha;
};

// The surface frame at a G-buffer pixel: t, b from the interpolated tangent and its handedness,
// orthonormal to the interpolated normal ng (b along +v).
void gltf_tangent_frame(vec3 ng, vec4 tangent, out vec3 t, out vec3 b) {
    t = tangent.xyz - ng * gltf_dot(ng, tangent.xyz);
    t = t * inversesqrt(max(gltf_dot(t, t), 1e-30));
    b = cross(ng, t) * (tangent.w < 0.0 ? -1.0 : 1.0);
}

// A tangent-space normal (x along t, y along b, z along ng) in world space, unit.
vec3 gltf_mapped_normal(vec3 nt, vec3 t, vec3 b, vec3 ng) {
    vec3 n = t * nt.x + b * nt.y + ng * nt.z;
    return n * inversesqrt(max(gltf_dot(n, n), 1e-30));
}

vec3 material_normal(int m, int slot, MaterialUV uv, vec3 t, vec3 b, vec3 ng) {
    vec4 tex = material_texture(m, slot, uv, vec4(0.5, 0.5, 1.0, 1.0));
    vec3 nt = tex.xyz * 2.0 - 1.0;
    nt.xy *= material_scale(m, slot);
    return gltf_mapped_normal(nt, t, b, ng);
}

// The material of face material m at the pixel: uv its uv sets and footprints (lib/gltf_textures
// material_uv), ng the interpolated normal, tangent (xyz, handedness), v towards the camera.
// A pass that decodes some channels with a network starts from this reference surface and replaces
// them (e.g. s.s.base_color, s.s.roughness, s.n = gltf_mapped_normal(...)): the rest stays the file's.
GltfSurface gltf_surface(int m, MaterialUV uv, vec3 ng, vec4 tangent, vec3 v) {
    vec4 base_f = material_param(m, 0), emissive_f = material_param(m, 1), mr_f = material_param(m, 2);
    vec4 layer_f = material_param(m, 3), sheen_f = material_param(m, 4), sided = material_param(m, 5);
    vec3 t, b;
    gltf_tangent_frame(ng, tangent, t, b);
    if (sided.x > 0.5 && gltf_dot(ng, v) < 0.0) {   // the back of a double-sided surface
        ng = -ng; t = -t; b = -b;
    }
    GltfSurface s;
    vec4 base = material_texture(m, MATERIAL_BASE_COLOR, uv, vec4(1.0));
    vec4 mr = material_texture(m, MATERIAL_METALLIC_ROUGHNESS, uv, vec4(1.0));
    s.s.base_color = base_f.rgb * base.rgb;
    s.alpha = base_f.a * base.a;
    s.s.metallic = clamp(mr_f.x * mr.b, 0.0, 1.0);
    s.s.roughness = clamp(mr_f.y * mr.g, MATERIAL_MIN_ROUGHNESS, 1.0);
    s.s.f0 = mr_f.z;
    s.n = material_normal(m, MATERIAL_NORMAL, uv, t, b, ng);
    float ao = material_texture(m, MATERIAL_OCCLUSION, uv, vec4(1.0)).r;
    s.occlusion = 1.0 + material_scale(m, MATERIAL_OCCLUSION) * (ao - 1.0);
    s.emissive = emissive_f.rgb * material_texture(m, MATERIAL_EMISSIVE, uv, vec4(1.0)).rgb;
    s.s.clearcoat = layer_f.x * material_texture(m, MATERIAL_CLEARCOAT, uv, vec4(1.0)).r;
    s.s.clearcoat_roughness = clamp(layer_f.y * material_texture(m, MATERIAL_CLEARCOAT_ROUGHNESS, uv,
                                                                 vec4(1.0)).g, MATERIAL_MIN_ROUGHNESS, 1.0);
    s.nc = material_normal(m, MATERIAL_CLEARCOAT_NORMAL, uv, t, b, ng);
    s.s.sheen_color = sheen_f.rgb * material_texture(m, MATERIAL_SHEEN_COLOR, uv, vec4(1.0)).rgb;
    s.s.sheen_roughness = layer_f.z * material_texture(m, MATERIAL_SHEEN_ROUGHNESS, uv, vec4(1.0)).a;
    vec4 an = material_texture(m, MATERIAL_ANISOTROPY, uv, vec4(1.0, 0.5, 1.0, 1.0));
    s.s.anisotropy = layer_f.w * an.b;
    vec2 d = an.rg * 2.0 - 1.0;
    float c = cos(sheen_f.w), sn = sin(sheen_f.w);
    d = vec2(c * d.x - sn * d.y, sn * d.x + c * d.y);
    vec3 at = t * d.x + b * d.y;
    at = at - s.n * gltf_dot(s.n, at);
    s.at = at * inversesqrt(max(gltf_dot(at, at), 1e-30));
    s.ab = cross(s.n, s.at);
    return s;
}

// Everything the surface sends towards the camera: the scene's lights (light_count of them), the
// SH environment (scaled by occlusion) and the emission.
vec3 gltf_shade(GltfSurface s, vec3 p, vec3 v, in vec3 sh[SH_COEFFS], int light_count) {
    vec3 r = reflect(-v, s.n);
    vec3 colour = gltf_environment(s.s, s.n, v, sh_irradiance(s.n, sh), max(sh_radiance(r, sh), vec3(0.0)))
                * s.occlusion + s.emissive;
    for (int i = 0; i < INSHADE_MAX_LIGHTS; ++i) {
        if (i >= scene_lights(light_count)) break;
        vec3 l;
        float scale;
        scene_light(i, p, l, scale);
        colour += gltf_brdf(s.s, s.n, s.at, s.ab, s.nc, v, l) * (u_lights[i].w * scale);
    }
    return colour;
}
