// Shadow maps of directional lights (runtime/shadow.py ShadowMaps, bound by the renderer when a
// program's ProgramSpec.shadows returns a request). One R32F 2D texture array: layer l holds, per
// texel, the depth in [0, 1] (clip z * 0.5 + 0.5; 1.0 = nothing) of the nearest caster surface seen
// from light l, through u_shadow_matrix[l] (world -> light clip, orthographic, w = 1). Layers at and
// beyond u_shadow_layers are unused. Define SHADOW_MAX_LAYERS before the include to size the
// matrix array (default 64). numpy twin: runtime/shadow.py shadow_visibility_np.

#ifndef SHADOW_MAX_LAYERS
#define SHADOW_MAX_LAYERS 64
#endif

uniform sampler2DArray u_shadow_map;
uniform mat4 u_shadow_matrix[SHADOW_MAX_LAYERS];
uniform int u_shadow_layers;

// 1 = lit .. 0 = shadowed, for world_pos and light `layer`. 2x2 percentage-closer filtering on
// texel centres: the four texels whose centres surround the point (clamped to the map) each test
// depth - bias <= stored depth, and the four results are mixed with the point's bilinear weights
// (so the result is continuous across texels; 0 or 1 away from shadow edges). bias is in depth
// units (ShadowMaps.depth_scale per world unit along the light). 1.0 outside the map (|clip x|,
// |clip y| or |clip z| > 1) and for layer < 0 or layer >= u_shadow_layers.
float shadow_visibility(vec3 world_pos, int layer, float bias) {
    if (layer < 0 || layer >= u_shadow_layers) {
        return 1.0;
    }
    vec3 ndc = (u_shadow_matrix[layer] * vec4(world_pos, 1.0)).xyz;
    if (any(greaterThan(abs(ndc), vec3(1.0)))) {
        return 1.0;
    }
    float depth = ndc.z * 0.5 + 0.5 - bias;
    ivec2 size = textureSize(u_shadow_map, 0).xy;
    vec2 st = (ndc.xy * 0.5 + 0.5) * vec2(size) - 0.5;   // texel-centre coordinates
    vec2 base = floor(st);
    vec2 f = st - base;
    ivec2 i0 = clamp(ivec2(base), ivec2(0), size - 1);
    ivec2 i1 = clamp(ivec2(base) + 1, ivec2(0), size - 1);
    // step(edge, x) = x >= edge: lit when the stored depth is at or beyond the point's
    float l00 = step(depth, texelFetch(u_shadow_map, ivec3(i0.x, i0.y, layer), 0).r);
    float l10 = step(depth, texelFetch(u_shadow_map, ivec3(i1.x, i0.y, layer), 0).r);
    float l01 = step(depth, texelFetch(u_shadow_map, ivec3(i0.x, i1.y, layer), 0).r);
    float l11 = step(depth, texelFetch(u_shadow_map, ivec3(i1.x, i1.y, layer), 0).r);
    return mix(mix(l00, l10, f.x), mix(l01, l11, f.x), f.y);
}
