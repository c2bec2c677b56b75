// Latent texture pyramid lookups for Vulkan GLSL (latent_pyramid.glsl for OpenGL; the torch twin and
// the texel convention in models/latent_pyramid.py): one level per query, bilinear within it, texel
// centres at (i + 0.5) / N, wrap = repeat. `level` is already floored and clamped by the caller.
// *_exact: 4 texelFetch at the level (no sampler: GL_EXT_samplerless_texture_functions) with
// integer repeat wrap + fp32 mix. *_fast: textureLod at the integer level through the texture's
// sampler (hardware bilinear, repeat).

vec4 inshade_latent_exact(texture2D t, int n0, vec2 uv, int level) {
    int n = n0 >> level;
    vec2 s = uv * float(n) - 0.5;
    vec2 fl = floor(s);
    vec2 f = s - fl;
    ivec2 i0 = ivec2(fl) & (n - 1);   // n is a power of two: & wraps negatives too
    ivec2 i1 = (i0 + 1) & (n - 1);
    vec4 a = mix(texelFetch(t, ivec2(i0.x, i0.y), level), texelFetch(t, ivec2(i1.x, i0.y), level), f.x);
    vec4 b = mix(texelFetch(t, ivec2(i0.x, i1.y), level), texelFetch(t, ivec2(i1.x, i1.y), level), f.x);
    return mix(a, b, f.y);
}

vec4 inshade_latent_fast(texture2D t, sampler s, vec2 uv, int level) {
    return textureLod(sampler2D(t, s), uv, float(level));
}

// floor(level) clamped to [0, levels - 1].
int inshade_latent_level(float level, int levels) {
    return int(clamp(floor(level), 0.0, float(levels - 1)));
}
