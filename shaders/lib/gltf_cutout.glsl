// The G-buffer pass's cut-out test for a glTF mesh with alphaMode MASK materials: a fragment of a MASK
// material whose alpha (base colour factor x texture, lib/gltf_textures' sampling with this
// fragment's uv footprint) is below its alphaCutoff is cut, so the depth test keeps what lies behind.
// (passes/mesh_gbuffer includes <gbuffer_cutout>: this chunk, or lib/gbuffer_opaque.)
#include <lib/gltf_textures>

bool gbuffer_cut(vec2 uv, float material) {
    int m = int(material + 0.5);
    if (material_param(m, 1).w != MATERIAL_ALPHA_MASK) return false;
    vec2 g = vec2(uv.x, 1.0 - uv.y);   // glTF uv (v down)
    vec2 dx = dFdx(uv) * vec2(1.0, -1.0), dy = dFdy(uv) * vec2(1.0, -1.0);
    float alpha = material_param(m, 0).a * material_texture(m, MATERIAL_BASE_COLOR, g, dx, dy, vec4(1.0)).a;
    return alpha < material_param(m, 2).w;
}
