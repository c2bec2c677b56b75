// Differentiable Indirection lookups for OpenGL and Vulkan GLSL (lookup_array.wgsl, lookup_array.hlsl
// for the others; the torch twin in torch_twin.py).
// Corner-aligned: along an axis of n cells, x in [0,1] (clamped) maps to u = x * (n - 1);
// cells i0 = min(floor(u), n - 2) and i0 + 1 are mixed with weight u - i0.
// *_exact: texelFetch + fp32 mix. *_fast: hardware linear filtering at (u + 0.5) / n.

// Vulkan GLSL reads the cells without a sampler on the exact path (GL_EXT_samplerless_texture_functions)
// and through the texture's own sampler, at level 0, on the fast path.
#ifdef VULKAN
#define LUT_TEX2D texture2D
#define LUT_TEX3D texture3D
#define LUT_FILTERED2D texture2D t, sampler s
#define LUT_FILTERED3D texture3D t, sampler s
#define LUT_SAMPLE2D(uv) textureLod(sampler2D(t, s), uv, 0.0)
#define LUT_SAMPLE3D(uv) textureLod(sampler3D(t, s), uv, 0.0)
#else
#define LUT_TEX2D sampler2D
#define LUT_TEX3D sampler3D
#define LUT_FILTERED2D sampler2D t
#define LUT_FILTERED3D sampler3D t
#define LUT_SAMPLE2D(uv) texture(t, uv)
#define LUT_SAMPLE3D(uv) texture(t, uv)
#endif

void inshade_lut_axis(float x, int n, out int i0, out int i1, out float f) {
    float u = clamp(x, 0.0, 1.0) * float(n - 1);
    float fl = min(floor(u), float(max(n - 2, 0)));
    i0 = int(fl);
    i1 = min(i0 + 1, n - 1);
    f = u - fl;
}

vec4 inshade_lut1_exact(LUT_TEX2D t, int n, float x) {
    int i0, i1; float f;
    inshade_lut_axis(x, n, i0, i1, f);
    return mix(texelFetch(t, ivec2(i0, 0), 0), texelFetch(t, ivec2(i1, 0), 0), f);
}

vec4 inshade_lut2_exact(LUT_TEX2D t, ivec2 n, vec2 x) {
    int x0, x1, y0, y1; vec2 f;
    inshade_lut_axis(x.x, n.x, x0, x1, f.x);
    inshade_lut_axis(x.y, n.y, y0, y1, f.y);
    vec4 a = mix(texelFetch(t, ivec2(x0, y0), 0), texelFetch(t, ivec2(x1, y0), 0), f.x);
    vec4 b = mix(texelFetch(t, ivec2(x0, y1), 0), texelFetch(t, ivec2(x1, y1), 0), f.x);
    return mix(a, b, f.y);
}

// One trilinear cell of a 3D texture whose z slices start at z_base.
vec4 inshade_lut3_cell(LUT_TEX3D t, ivec3 n, vec3 x, int z_base) {
    int x0, x1, y0, y1, z0, z1; vec3 f;
    inshade_lut_axis(x.x, n.x, x0, x1, f.x);
    inshade_lut_axis(x.y, n.y, y0, y1, f.y);
    inshade_lut_axis(x.z, n.z, z0, z1, f.z);
    z0 += z_base; z1 += z_base;
    vec4 a = mix(texelFetch(t, ivec3(x0, y0, z0), 0), texelFetch(t, ivec3(x1, y0, z0), 0), f.x);
    vec4 b = mix(texelFetch(t, ivec3(x0, y1, z0), 0), texelFetch(t, ivec3(x1, y1, z0), 0), f.x);
    vec4 c = mix(texelFetch(t, ivec3(x0, y0, z1), 0), texelFetch(t, ivec3(x1, y0, z1), 0), f.x);
    vec4 d = mix(texelFetch(t, ivec3(x0, y1, z1), 0), texelFetch(t, ivec3(x1, y1, z1), 0), f.x);
    return mix(mix(a, b, f.y), mix(c, d, f.y), f.z);
}

vec4 inshade_lut3_exact(LUT_TEX3D t, ivec3 n, vec3 x) { return inshade_lut3_cell(t, n, x, 0); }

// 4D arrays live in a 3D texture of n.x * n.y * (n.z * n.w): slice block w starts at w * n.z.
vec4 inshade_lut4_exact(LUT_TEX3D t, ivec4 n, vec4 x) {
    int w0, w1; float fw;
    inshade_lut_axis(x.w, n.w, w0, w1, fw);
    return mix(inshade_lut3_cell(t, n.xyz, x.xyz, w0 * n.z), inshade_lut3_cell(t, n.xyz, x.xyz, w1 * n.z), fw);
}

vec4 inshade_lut1_fast(LUT_FILTERED2D, int n, float x) {
    float nf = float(n);
    return LUT_SAMPLE2D(vec2((clamp(x, 0.0, 1.0) * (nf - 1.0) + 0.5) / nf, 0.5));
}

vec4 inshade_lut2_fast(LUT_FILTERED2D, ivec2 n, vec2 x) {
    vec2 nf = vec2(n);
    return LUT_SAMPLE2D((clamp(x, 0.0, 1.0) * (nf - 1.0) + 0.5) / nf);
}

vec4 inshade_lut3_fast(LUT_FILTERED3D, ivec3 n, vec3 x) {
    vec3 nf = vec3(n);
    return LUT_SAMPLE3D((clamp(x, 0.0, 1.0) * (nf - 1.0) + 0.5) / nf);
}

// Two trilinear fetches, one per slice block; z stays inside [0.5, n.z - 0.5] texels of
// its block so neighbouring blocks never bleed in.
vec4 inshade_lut4_fast(LUT_FILTERED3D, ivec4 n, vec4 x) {
    int w0, w1; float fw;
    inshade_lut_axis(x.w, n.w, w0, w1, fw);
    vec3 nf = vec3(n.xyz);
    vec3 u = clamp(x.xyz, 0.0, 1.0) * (nf - 1.0) + 0.5;
    float depth = float(n.z * n.w);
    vec4 a = LUT_SAMPLE3D(vec3(u.xy / nf.xy, (u.z + float(w0 * n.z)) / depth));
    vec4 b = LUT_SAMPLE3D(vec3(u.xy / nf.xy, (u.z + float(w1 * n.z)) / depth));
    return mix(a, b, fw);
}

// Layouts for arrays whose natural texture exceeds the context's limits (emit.py).
// 4D folded along another axis of the 3D texture: `fold` is the unit axis (x, y or z) that
// holds the n.w slice blocks, block w starting at w * n.xyz * fold.
vec4 inshade_lut3_cell_at(LUT_TEX3D t, ivec3 n, vec3 x, ivec3 base) {
    int x0, x1, y0, y1, z0, z1; vec3 f;
    inshade_lut_axis(x.x, n.x, x0, x1, f.x);
    inshade_lut_axis(x.y, n.y, y0, y1, f.y);
    inshade_lut_axis(x.z, n.z, z0, z1, f.z);
    x0 += base.x; x1 += base.x; y0 += base.y; y1 += base.y; z0 += base.z; z1 += base.z;
    vec4 a = mix(texelFetch(t, ivec3(x0, y0, z0), 0), texelFetch(t, ivec3(x1, y0, z0), 0), f.x);
    vec4 b = mix(texelFetch(t, ivec3(x0, y1, z0), 0), texelFetch(t, ivec3(x1, y1, z0), 0), f.x);
    vec4 c = mix(texelFetch(t, ivec3(x0, y0, z1), 0), texelFetch(t, ivec3(x1, y0, z1), 0), f.x);
    vec4 d = mix(texelFetch(t, ivec3(x0, y1, z1), 0), texelFetch(t, ivec3(x1, y1, z1), 0), f.x);
    return mix(mix(a, b, f.y), mix(c, d, f.y), f.z);
}

vec4 inshade_lut4_exact_fold(LUT_TEX3D t, ivec4 n, ivec3 fold, vec4 x) {
    int w0, w1; float fw;
    inshade_lut_axis(x.w, n.w, w0, w1, fw);
    return mix(inshade_lut3_cell_at(t, n.xyz, x.xyz, w0 * n.xyz * fold),
               inshade_lut3_cell_at(t, n.xyz, x.xyz, w1 * n.xyz * fold), fw);
}

vec4 inshade_lut4_fast_fold(LUT_FILTERED3D, ivec4 n, ivec3 fold, vec4 x) {
    int w0, w1; float fw;
    inshade_lut_axis(x.w, n.w, w0, w1, fw);
    vec3 nf = vec3(n.xyz);
    vec3 u = clamp(x.xyz, 0.0, 1.0) * (nf - 1.0) + 0.5;
    vec3 size = nf * (vec3(1.0) + float(n.w - 1) * vec3(fold));
    vec4 a = LUT_SAMPLE3D((u + float(w0) * nf * vec3(fold)) / size);
    vec4 b = LUT_SAMPLE3D((u + float(w1) * nf * vec3(fold)) / size);
    return mix(a, b, fw);
}

// Any array, exact path, cells in C order (x fastest) wrapped into rows of a 2D texture `w`
// texels wide: linear cell i lives at texel (i % w, i / w).
vec4 inshade_lut_wrapped_fetch(LUT_TEX2D t, int i, int w) {
    return texelFetch(t, ivec2(i % w, i / w), 0);
}

vec4 inshade_lut1_exact_wrapped(LUT_TEX2D t, int n, int w, float x) {
    int i0, i1; float f;
    inshade_lut_axis(x, n, i0, i1, f);
    return mix(inshade_lut_wrapped_fetch(t, i0, w), inshade_lut_wrapped_fetch(t, i1, w), f);
}

vec4 inshade_lut2_exact_wrapped(LUT_TEX2D t, ivec2 n, int w, vec2 x) {
    int x0, x1, y0, y1; vec2 f;
    inshade_lut_axis(x.x, n.x, x0, x1, f.x);
    inshade_lut_axis(x.y, n.y, y0, y1, f.y);
    y0 *= n.x; y1 *= n.x;
    vec4 a = mix(inshade_lut_wrapped_fetch(t, y0 + x0, w), inshade_lut_wrapped_fetch(t, y0 + x1, w), f.x);
    vec4 b = mix(inshade_lut_wrapped_fetch(t, y1 + x0, w), inshade_lut_wrapped_fetch(t, y1 + x1, w), f.x);
    return mix(a, b, f.y);
}

// One trilinear cell of a wrapped 3D array whose cells start at linear index `base`.
vec4 inshade_lut3_cell_wrapped(LUT_TEX2D t, ivec3 n, vec3 x, int base, int w) {
    int x0, x1, y0, y1, z0, z1; vec3 f;
    inshade_lut_axis(x.x, n.x, x0, x1, f.x);
    inshade_lut_axis(x.y, n.y, y0, y1, f.y);
    inshade_lut_axis(x.z, n.z, z0, z1, f.z);
    y0 *= n.x; y1 *= n.x;
    z0 = base + z0 * n.x * n.y; z1 = base + z1 * n.x * n.y;
    vec4 a = mix(inshade_lut_wrapped_fetch(t, z0 + y0 + x0, w), inshade_lut_wrapped_fetch(t, z0 + y0 + x1, w), f.x);
    vec4 b = mix(inshade_lut_wrapped_fetch(t, z0 + y1 + x0, w), inshade_lut_wrapped_fetch(t, z0 + y1 + x1, w), f.x);
    vec4 c = mix(inshade_lut_wrapped_fetch(t, z1 + y0 + x0, w), inshade_lut_wrapped_fetch(t, z1 + y0 + x1, w), f.x);
    vec4 d = mix(inshade_lut_wrapped_fetch(t, z1 + y1 + x0, w), inshade_lut_wrapped_fetch(t, z1 + y1 + x1, w), f.x);
    return mix(mix(a, b, f.y), mix(c, d, f.y), f.z);
}

vec4 inshade_lut3_exact_wrapped(LUT_TEX2D t, ivec3 n, int w, vec3 x) {
    return inshade_lut3_cell_wrapped(t, n, x, 0, w);
}

vec4 inshade_lut4_exact_wrapped(LUT_TEX2D t, ivec4 n, int w, vec4 x) {
    int w0, w1; float fw;
    inshade_lut_axis(x.w, n.w, w0, w1, fw);
    int block = n.x * n.y * n.z;
    return mix(inshade_lut3_cell_wrapped(t, n.xyz, x.xyz, w0 * block, w),
               inshade_lut3_cell_wrapped(t, n.xyz, x.xyz, w1 * block, w), fw);
}
