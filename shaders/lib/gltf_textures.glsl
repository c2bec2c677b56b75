// A glTF mesh's materials as runtime/materials.py packs them (u_material_params: a row per material;
// u_material_images: every image in linear light, colour ones decoded from sRGB before upload, a layer
// each): a material's factors (material_param) and a texture slot sampled at the uv set it reads
// (MaterialUV) with KHR_texture_transform and the sampler's wrap, the uv footprint choosing the mip
// level (material_texture). What
// lib/gltf_material shades and lib/gltf_cutout tests alpha with.

uniform sampler2D u_material_params;
uniform sampler2DArray u_material_images;

// runtime/materials.py SCALARS, SLOTS: texel offsets of a material row
#define MATERIAL_SCALARS 6
#define MATERIAL_BASE_COLOR 0
#define MATERIAL_METALLIC_ROUGHNESS 1
#define MATERIAL_NORMAL 2
#define MATERIAL_OCCLUSION 3
#define MATERIAL_EMISSIVE 4
#define MATERIAL_CLEARCOAT 5
#define MATERIAL_CLEARCOAT_ROUGHNESS 6
#define MATERIAL_CLEARCOAT_NORMAL 7
#define MATERIAL_SHEEN_COLOR 8
#define MATERIAL_SHEEN_ROUGHNESS 9
#define MATERIAL_ANISOTROPY 10
#define MATERIAL_ALPHA_MASK 1.0   // runtime/materials.py ALPHA_CODES
#define MATERIAL_ALPHA_BLEND 2.0

vec4 material_param(int m, int texel) {
    return texelFetch(u_material_params, ivec2(texel, m), 0);
}

float material_wrap(float x, float mode) {
    if (mode == 1.0) return clamp(x, 0.0, 1.0);                  // clamp to edge
    if (mode == 2.0) { float t = mod(x, 2.0); return t > 1.0 ? 2.0 - t : t; }   // mirrored repeat
    return x;                                                    // repeat: the array wraps
}

// A pixel's uv sets at glTF's orientation (v down) with their footprints per pixel: TEXCOORD_0 and
// TEXCOORD_1 (the same as the first where the mesh has no second set).
struct MaterialUV {
    vec2 g0, dx0, dy0;
    vec2 g1, dx1, dy1;
};

// From the G-buffer's uv (v up) and its footprint (dFdx(uv), dFdy(uv)) as stored.
MaterialUV material_uv(vec2 uv, vec4 grad) {
    MaterialUV t;
    t.g0 = vec2(uv.x, 1.0 - uv.y);
    t.dx0 = vec2(grad.x, -grad.y);
    t.dy0 = vec2(grad.z, -grad.w);
    t.g1 = t.g0; t.dx1 = t.dx0; t.dy1 = t.dy0;
    return t;
}

// The second set from the G-buffer's "uv1" (uv1, dFdx(uv1)) and "uv1_dy" (dFdy(uv1), 0, 0) targets.
void material_uv1(inout MaterialUV t, vec4 uv1, vec4 uv1_dy) {
    t.g1 = vec2(uv1.x, 1.0 - uv1.y);
    t.dx1 = vec2(uv1.z, -uv1.w);
    t.dy1 = vec2(uv1_dy.x, -uv1_dy.y);
}

// Slot `slot` of material m at the pixel's uv set that the slot reads; `fallback` without a texture.
vec4 material_texture(int m, int slot, MaterialUV uv, vec4 fallback) {
    int at = MATERIAL_SCALARS + 3 * slot;
    vec4 a = material_param(m, at);
    if (a.x < 0.0) return fallback;
    vec4 r0 = material_param(m, at + 1);
    vec4 r1 = material_param(m, at + 2);
    bool second = r1.z > 0.5;
    vec2 g = second ? uv.g1 : uv.g0, dx = second ? uv.dx1 : uv.dx0, dy = second ? uv.dy1 : uv.dy0;
    vec2 t = vec2(r0.x * g.x + r0.y * g.y + r0.z, r0.w * g.x + r1.x * g.y + r1.y);
    vec2 tdx = vec2(r0.x * dx.x + r0.y * dx.y, r0.w * dx.x + r1.x * dx.y);
    vec2 tdy = vec2(r0.x * dy.x + r0.y * dy.y, r0.w * dy.x + r1.x * dy.y);
    t = vec2(material_wrap(t.x, a.y), material_wrap(t.y, a.z));
    return textureGrad(u_material_images, vec3(t, a.x), tdx, tdy);
}

float material_scale(int m, int slot) {
    return material_param(m, MATERIAL_SCALARS + 3 * slot).w;
}

// The material's alpha at the pixel: base colour factor x texture alpha (MASK's cut-out, BLEND's weight).
float material_alpha(int m, MaterialUV uv) {
    return material_param(m, 0).a * material_texture(m, MATERIAL_BASE_COLOR, uv, vec4(1.0)).a;
}
