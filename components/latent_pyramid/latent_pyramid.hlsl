// Latent texture pyramid lookups in HLSL and Slang (latent_pyramid.glsl for OpenGL; the torch twin
// and the texel convention in models/latent_pyramid.py): one level per query, bilinear within it,
// texel centres at (i + 0.5) / N, wrap = repeat. `level` is already floored and clamped by the caller.
// *_exact: 4 Load at the level with integer repeat wrap + fp32 lerp. *_fast: SampleLevel at the
// integer level through the texture's sampler (hardware bilinear, repeat).

float4 inshade_latent_exact(Texture2D<float4> t, int n0, float2 uv, int level) {
    int n = n0 >> level;
    float2 s = uv * float(n) - 0.5;
    float2 fl = floor(s);
    float2 f = s - fl;
    int2 i0 = int2(fl) & (n - 1);   // n is a power of two: & wraps negatives too
    int2 i1 = (i0 + 1) & (n - 1);
    float4 a = lerp(t.Load(int3(i0.x, i0.y, level)), t.Load(int3(i1.x, i0.y, level)), f.x);
    float4 b = lerp(t.Load(int3(i0.x, i1.y, level)), t.Load(int3(i1.x, i1.y, level)), f.x);
    return lerp(a, b, f.y);
}

float4 inshade_latent_fast(Texture2D<float4> t, SamplerState s, float2 uv, int level) {
    return t.SampleLevel(s, uv, float(level));
}

// floor(level) clamped to [0, levels - 1].
int inshade_latent_level(float level, int levels) {
    return int(clamp(floor(level), 0.0, float(levels - 1)));
}
