// Differentiable Indirection lookups in HLSL and Slang (lookup_array.glsl for OpenGL; the torch twin in
// torch_twin.py). Textures are read with Load on the exact path; the fast path takes the texture's
// sampler beside it.
// Corner-aligned: along an axis of n cells, x in [0,1] (clamped) maps to u = x * (n - 1);
// cells i0 = min(floor(u), n - 2) and i0 + 1 are mixed with weight u - i0.
// *_exact: Load + fp32 mix. *_fast: hardware linear filtering at (u + 0.5) / n, level 0.

void inshade_lut_axis(float x, int n, out int i0, out int i1, out float f) {
    float u = clamp(x, 0.0, 1.0) * float(n - 1);
    float fl = min(floor(u), float(max(n - 2, 0)));
    i0 = int(fl);
    i1 = min(i0 + 1, n - 1);
    f = u - fl;
}

float4 inshade_lut1_exact(Texture2D<float4> t, int n, float x) {
    int i0, i1; float f;
    inshade_lut_axis(x, n, i0, i1, f);
    return lerp(t.Load(int3(i0, 0, 0)), t.Load(int3(i1, 0, 0)), f);
}

float4 inshade_lut2_exact(Texture2D<float4> t, int2 n, float2 x) {
    int x0, x1, y0, y1; float2 f;
    inshade_lut_axis(x.x, n.x, x0, x1, f.x);
    inshade_lut_axis(x.y, n.y, y0, y1, f.y);
    float4 a = lerp(t.Load(int3(x0, y0, 0)), t.Load(int3(x1, y0, 0)), f.x);
    float4 b = lerp(t.Load(int3(x0, y1, 0)), t.Load(int3(x1, y1, 0)), f.x);
    return lerp(a, b, f.y);
}

// One trilinear cell of a 3D texture whose z slices start at z_base.
float4 inshade_lut3_cell(Texture3D<float4> t, int3 n, float3 x, int z_base) {
    int x0, x1, y0, y1, z0, z1; float3 f;
    inshade_lut_axis(x.x, n.x, x0, x1, f.x);
    inshade_lut_axis(x.y, n.y, y0, y1, f.y);
    inshade_lut_axis(x.z, n.z, z0, z1, f.z);
    z0 += z_base; z1 += z_base;
    float4 a = lerp(t.Load(int4(x0, y0, z0, 0)), t.Load(int4(x1, y0, z0, 0)), f.x);
    float4 b = lerp(t.Load(int4(x0, y1, z0, 0)), t.Load(int4(x1, y1, z0, 0)), f.x);
    float4 c = lerp(t.Load(int4(x0, y0, z1, 0)), t.Load(int4(x1, y0, z1, 0)), f.x);
    float4 d = lerp(t.Load(int4(x0, y1, z1, 0)), t.Load(int4(x1, y1, z1, 0)), f.x);
    return lerp(lerp(a, b, f.y), lerp(c, d, f.y), f.z);
}

float4 inshade_lut3_exact(Texture3D<float4> t, int3 n, float3 x) { return inshade_lut3_cell(t, n, x, 0); }

// 4D arrays live in a 3D texture of n.x * n.y * (n.z * n.w): slice block w starts at w * n.z.
float4 inshade_lut4_exact(Texture3D<float4> t, int4 n, float4 x) {
    int w0, w1; float fw;
    inshade_lut_axis(x.w, n.w, w0, w1, fw);
    return lerp(inshade_lut3_cell(t, n.xyz, x.xyz, w0 * n.z), inshade_lut3_cell(t, n.xyz, x.xyz, w1 * n.z), fw);
}

float4 inshade_lut1_fast(Texture2D<float4> t, SamplerState s, int n, float x) {
    float nf = float(n);
    return t.SampleLevel(s, float2((clamp(x, 0.0, 1.0) * (nf - 1.0) + 0.5) / nf, 0.5), 0.0);
}

float4 inshade_lut2_fast(Texture2D<float4> t, SamplerState s, int2 n, float2 x) {
    float2 nf = float2(n);
    return t.SampleLevel(s, (clamp(x, 0.0, 1.0) * (nf - 1.0) + 0.5) / nf, 0.0);
}

float4 inshade_lut3_fast(Texture3D<float4> t, SamplerState s, int3 n, float3 x) {
    float3 nf = float3(n);
    return t.SampleLevel(s, (clamp(x, 0.0, 1.0) * (nf - 1.0) + 0.5) / nf, 0.0);
}

// Two trilinear fetches, one per slice block; z stays inside [0.5, n.z - 0.5] texels of
// its block so neighbouring blocks never bleed in.
float4 inshade_lut4_fast(Texture3D<float4> t, SamplerState s, int4 n, float4 x) {
    int w0, w1; float fw;
    inshade_lut_axis(x.w, n.w, w0, w1, fw);
    float3 nf = float3(n.xyz);
    float3 u = clamp(x.xyz, 0.0, 1.0) * (nf - 1.0) + 0.5;
    float depth = float(n.z * n.w);
    float4 a = t.SampleLevel(s, float3(u.xy / nf.xy, (u.z + float(w0 * n.z)) / depth), 0.0);
    float4 b = t.SampleLevel(s, float3(u.xy / nf.xy, (u.z + float(w1 * n.z)) / depth), 0.0);
    return lerp(a, b, fw);
}

// Layouts for arrays whose natural texture exceeds the context's limits (emit.py).
// 4D folded along another axis of the 3D texture: `fold` is the unit axis (x, y or z) that
// holds the n.w slice blocks, block w starting at w * n.xyz * fold.
float4 inshade_lut3_cell_at(Texture3D<float4> t, int3 n, float3 x, int3 base) {
    int x0, x1, y0, y1, z0, z1; float3 f;
    inshade_lut_axis(x.x, n.x, x0, x1, f.x);
    inshade_lut_axis(x.y, n.y, y0, y1, f.y);
    inshade_lut_axis(x.z, n.z, z0, z1, f.z);
    x0 += base.x; x1 += base.x; y0 += base.y; y1 += base.y; z0 += base.z; z1 += base.z;
    float4 a = lerp(t.Load(int4(x0, y0, z0, 0)), t.Load(int4(x1, y0, z0, 0)), f.x);
    float4 b = lerp(t.Load(int4(x0, y1, z0, 0)), t.Load(int4(x1, y1, z0, 0)), f.x);
    float4 c = lerp(t.Load(int4(x0, y0, z1, 0)), t.Load(int4(x1, y0, z1, 0)), f.x);
    float4 d = lerp(t.Load(int4(x0, y1, z1, 0)), t.Load(int4(x1, y1, z1, 0)), f.x);
    return lerp(lerp(a, b, f.y), lerp(c, d, f.y), f.z);
}

float4 inshade_lut4_exact_fold(Texture3D<float4> t, int4 n, int3 fold, float4 x) {
    int w0, w1; float fw;
    inshade_lut_axis(x.w, n.w, w0, w1, fw);
    return lerp(inshade_lut3_cell_at(t, n.xyz, x.xyz, w0 * n.xyz * fold),
               inshade_lut3_cell_at(t, n.xyz, x.xyz, w1 * n.xyz * fold), fw);
}

float4 inshade_lut4_fast_fold(Texture3D<float4> t, SamplerState s, int4 n, int3 fold, float4 x) {
    int w0, w1; float fw;
    inshade_lut_axis(x.w, n.w, w0, w1, fw);
    float3 nf = float3(n.xyz);
    float3 u = clamp(x.xyz, 0.0, 1.0) * (nf - 1.0) + 0.5;
    float3 size = nf * (1.0 + float(n.w - 1) * (float3)fold);
    float4 a = t.SampleLevel(s, (u + float(w0) * nf * (float3)fold) / size, 0.0);
    float4 b = t.SampleLevel(s, (u + float(w1) * nf * (float3)fold) / size, 0.0);
    return lerp(a, b, fw);
}

// Any array, exact path, cells in C order (x fastest) wrapped into rows of a 2D texture `w`
// texels wide: linear cell i lives at texel (i % w, i / w).
float4 inshade_lut_wrapped_fetch(Texture2D<float4> t, int i, int w) {
    return t.Load(int3(i % w, i / w, 0));
}

float4 inshade_lut1_exact_wrapped(Texture2D<float4> t, int n, int w, float x) {
    int i0, i1; float f;
    inshade_lut_axis(x, n, i0, i1, f);
    return lerp(inshade_lut_wrapped_fetch(t, i0, w), inshade_lut_wrapped_fetch(t, i1, w), f);
}

float4 inshade_lut2_exact_wrapped(Texture2D<float4> t, int2 n, int w, float2 x) {
    int x0, x1, y0, y1; float2 f;
    inshade_lut_axis(x.x, n.x, x0, x1, f.x);
    inshade_lut_axis(x.y, n.y, y0, y1, f.y);
    y0 *= n.x; y1 *= n.x;
    float4 a = lerp(inshade_lut_wrapped_fetch(t, y0 + x0, w), inshade_lut_wrapped_fetch(t, y0 + x1, w), f.x);
    float4 b = lerp(inshade_lut_wrapped_fetch(t, y1 + x0, w), inshade_lut_wrapped_fetch(t, y1 + x1, w), f.x);
    return lerp(a, b, f.y);
}

// One trilinear cell of a wrapped 3D array whose cells start at linear index `base`.
float4 inshade_lut3_cell_wrapped(Texture2D<float4> t, int3 n, float3 x, int base, int w) {
    int x0, x1, y0, y1, z0, z1; float3 f;
    inshade_lut_axis(x.x, n.x, x0, x1, f.x);
    inshade_lut_axis(x.y, n.y, y0, y1, f.y);
    inshade_lut_axis(x.z, n.z, z0, z1, f.z);
    y0 *= n.x; y1 *= n.x;
    z0 = base + z0 * n.x * n.y; z1 = base + z1 * n.x * n.y;
    float4 a = lerp(inshade_lut_wrapped_fetch(t, z0 + y0 + x0, w), inshade_lut_wrapped_fetch(t, z0 + y0 + x1, w), f.x);
    float4 b = lerp(inshade_lut_wrapped_fetch(t, z0 + y1 + x0, w), inshade_lut_wrapped_fetch(t, z0 + y1 + x1, w), f.x);
    float4 c = lerp(inshade_lut_wrapped_fetch(t, z1 + y0 + x0, w), inshade_lut_wrapped_fetch(t, z1 + y0 + x1, w), f.x);
    float4 d = lerp(inshade_lut_wrapped_fetch(t, z1 + y1 + x0, w), inshade_lut_wrapped_fetch(t, z1 + y1 + x1, w), f.x);
    return lerp(lerp(a, b, f.y), lerp(c, d, f.y), f.z);
}

float4 inshade_lut3_exact_wrapped(Texture2D<float4> t, int3 n, int w, float3 x) {
    return inshade_lut3_cell_wrapped(t, n, x, 0, w);
}

float4 inshade_lut4_exact_wrapped(Texture2D<float4> t, int4 n, int w, float4 x) {
    int w0, w1; float fw;
    inshade_lut_axis(x.w, n.w, w0, w1, fw);
    int block = n.x * n.y * n.z;
    return lerp(inshade_lut3_cell_wrapped(t, n.xyz, x.xyz, w0 * block, w),
               inshade_lut3_cell_wrapped(t, n.xyz, x.xyz, w1 * block, w), fw);
}
