// The G-buffer pass's cut-out test for a glTF mesh with alphaMode MASK or BLEND materials.
// u_gbuffer_layer 0 (the opaque surfaces): a fragment of a MASK material whose alpha (base colour
// factor x texture, lib/gltf_textures' sampling with this fragment's uv footprint) is below its
// alphaCutoff is cut, and every BLEND fragment is, so the depth test keeps what lies behind;
// -1: the same, but BLEND fragments are kept (drawn opaque, where nothing peels them).
// u_gbuffer_layer k > 0 (depth peeling, runtime/geometry.py): only BLEND fragments, in front of the
// opaque surface (u_peel_back: layer 0's positions) and behind layer k - 1's (u_peel_front), so the
// depth test keeps the k-th nearest BLEND surface of each pixel. Depth is the view-space distance of
// the stored world positions, computed alike in every layer, so a layer never peels itself again.
// (passes/mesh_gbuffer includes <gbuffer_cutout>: this chunk, or lib/gbuffer_opaque.)
#include <lib/gltf_textures>

uniform int u_gbuffer_layer;
uniform sampler2D u_peel_front;
uniform sampler2D u_peel_back;
uniform mat4 u_view;

float peel_depth(vec3 p) {
    return -(u_view * vec4(p, 1.0)).z;
}

bool gbuffer_cut(vec2 uv, vec2 uv1, float material, vec3 p) {
    int m = int(material + 0.5);
    float mode = material_param(m, 1).w;
    if (u_gbuffer_layer > 0) {
        if (mode != MATERIAL_ALPHA_BLEND) return true;
        ivec2 px = ivec2(gl_FragCoord.xy);
        float d = peel_depth(p);
        vec4 back = texelFetch(u_peel_back, px, 0);
        if (back.w > 0.0 && d >= peel_depth(back.xyz)) return true;
        if (u_gbuffer_layer > 1) {
            vec4 front = texelFetch(u_peel_front, px, 0);
            if (front.w <= 0.0 || d <= peel_depth(front.xyz)) return true;
        }
        return false;
    }
    if (mode == MATERIAL_ALPHA_BLEND) return u_gbuffer_layer == 0;   // -1: drawn opaque, not peeled
    if (mode != MATERIAL_ALPHA_MASK) return false;
    MaterialUV t = material_uv(uv, vec4(dFdx(uv), dFdy(uv)));
    material_uv1(t, vec4(uv1, dFdx(uv1)), vec4(dFdy(uv1), 0.0, 0.0));
    return material_alpha(m, t) < material_param(m, 2).w;
}
