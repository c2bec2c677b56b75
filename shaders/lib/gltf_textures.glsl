// A glTF mesh's materials as runtime/materials.py packs them (u_material_params: a row per material;
// u_material_images: every image in linear light, colour ones decoded from sRGB before upload, a layer
// each): a material's factors (material_param) and a texture slot sampled with KHR_texture_transform
// and the sampler's wrap, the uv footprint choosing the mip level (material_texture). What
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

// Slot `slot` of material m at glTF uv g, footprint (dx, dy) per pixel; `fallback` without a texture.
vec4 material_texture(int m, int slot, vec2 g, vec2 dx, vec2 dy, vec4 fallback) {
    int at = MATERIAL_SCALARS + 3 * slot;
    vec4 a = material_param(m, at);
    if (a.x < 0.0) return fallback;
    vec4 r0 = material_param(m, at + 1);
    vec4 r1 = material_param(m, at + 2);
    vec2 t = vec2(r0.x * g.x + r0.y * g.y + r0.z, r0.w * g.x + r1.x * g.y + r1.y);
    vec2 tdx = vec2(r0.x * dx.x + r0.y * dx.y, r0.w * dx.x + r1.x * dx.y);
    vec2 tdy = vec2(r0.x * dy.x + r0.y * dy.y, r0.w * dy.x + r1.x * dy.y);
    t = vec2(material_wrap(t.x, a.y), material_wrap(t.y, a.z));
    return textureGrad(u_material_images, vec3(t, a.x), tdx, tdy);
}

float material_scale(int m, int slot) {
    return material_param(m, MATERIAL_SCALARS + 3 * slot).w;
}

// The material's alpha at glTF uv g: base colour factor x texture alpha (MASK's cut-out, BLEND's weight).
float material_alpha(int m, vec2 g, vec2 dx, vec2 dy) {
    return material_param(m, 0).a * material_texture(m, MATERIAL_BASE_COLOR, g, dx, dy, vec4(1.0)).a;
}
