// The UV-free material's channels at a surface point, decoded or looked up (techniques/uvfree_material).
// Both routes give the texel values the reference textures store (model.py CHANNELS): albedo
// sRGB-encoded, the tangent-space normal as n * 0.5 + 0.5, then roughness, metallic, AO; so the
// decoded and the reference material go through the same unpacking and shading.
#include <network_mat>
#include <lib/colour>
#include <lib/pbr_shading>

#if MAT_OUT_DIM != 9 || !defined(MAT_IN_UINT_DIM)
#error "passes/mesh_uvfree_material.frag needs a (triangle uint, barycentric) -> 9-channel material network"
#endif
#include <lib/uvf_decoder>

uniform sampler2D u_uvf_albedo;   // the reference textures (scene.json "textures"), bilinear, clamp
uniform sampler2D u_uvf_normal;
uniform sampler2D u_uvf_rma;

struct UvfChannels {
    vec3 albedo;   // sRGB-encoded, as stored
    vec3 normal;   // n * 0.5 + 0.5
    vec3 rma;      // roughness, metallic, AO
};

// The network at face k, barycentrics t = (t0, t1) of the face's vertices 0, 1.
UvfChannels uvf_decode(uint k, vec2 t) {
    vec4 y[MAT_OUT_BLOCKS];
    uvf_eval(k, t, y);
    return UvfChannels(y[0].xyz, vec3(y[0].w, y[1].xy), vec3(y[1].zw, y[2].x));
}

UvfChannels uvf_reference(vec2 uv) {
    return UvfChannels(texture(u_uvf_albedo, uv).rgb, texture(u_uvf_normal, uv).rgb, texture(u_uvf_rma, uv).rgb);
}

PbrSample uvf_unpack(UvfChannels c) {
    PbrSample s;
    s.albedo = srgb_eotf(clamp(c.albedo, 0.0, 1.0));
    vec3 n = c.normal * 2.0 - 1.0;
    float len2 = dot(n, n);
    s.normal_ts = len2 > 1e-12 ? n * inversesqrt(len2) : vec3(0.0, 0.0, 1.0);
    s.roughness = clamp(c.rma.x, 0.0, 1.0);
    s.metallic = clamp(c.rma.y, 0.0, 1.0);
    s.ao = clamp(c.rma.z, 0.0, 1.0);
    return s;
}
