// Differentiable Indirection lookups (models/lookup_array.py has the torch twin).
// Corner-aligned: along an axis of n cells, x in [0,1] (clamped) maps to u = x * (n - 1);
// cells i0 = min(floor(u), n - 2) and i0 + 1 are mixed with weight u - i0.
// *_exact: texelFetch + fp32 mix. *_fast: hardware linear filtering at (u + 0.5) / n.

void inshade_lut_axis(float x, int n, out int i0, out int i1, out float f) {
    float u = clamp(x, 0.0, 1.0) * float(n - 1);
    float fl = min(floor(u), float(max(n - 2, 0)));
    i0 = int(fl);
    i1 = min(i0 + 1, n - 1);
    f = u - fl;
}

vec4 inshade_lut1_exact(sampler2D t, int n, float x) {
    int i0, i1; float f;
    inshade_lut_axis(x, n, i0, i1, f);
    return mix(texelFetch(t, ivec2(i0, 0), 0), texelFetch(t, ivec2(i1, 0), 0), f);
}

vec4 inshade_lut2_exact(sampler2D t, ivec2 n, vec2 x) {
    int x0, x1, y0, y1; vec2 f;
    inshade_lut_axis(x.x, n.x, x0, x1, f.x);
    inshade_lut_axis(x.y, n.y, y0, y1, f.y);
    vec4 a = mix(texelFetch(t, ivec2(x0, y0), 0), texelFetch(t, ivec2(x1, y0), 0), f.x);
    vec4 b = mix(texelFetch(t, ivec2(x0, y1), 0), texelFetch(t, ivec2(x1, y1), 0), f.x);
    return mix(a, b, f.y);
}

// One trilinear cell of a 3D texture whose z slices start at z_base.
vec4 inshade_lut3_cell(sampler3D t, ivec3 n, vec3 x, int z_base) {
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

vec4 inshade_lut3_exact(sampler3D t, ivec3 n, vec3 x) { return inshade_lut3_cell(t, n, x, 0); }

// 4D arrays live in a 3D texture of n.x * n.y * (n.z * n.w): slice block w starts at w * n.z.
vec4 inshade_lut4_exact(sampler3D t, ivec4 n, vec4 x) {
    int w0, w1; float fw;
    inshade_lut_axis(x.w, n.w, w0, w1, fw);
    return mix(inshade_lut3_cell(t, n.xyz, x.xyz, w0 * n.z), inshade_lut3_cell(t, n.xyz, x.xyz, w1 * n.z), fw);
}

vec4 inshade_lut1_fast(sampler2D t, int n, float x) {
    float nf = float(n);
    return texture(t, vec2((clamp(x, 0.0, 1.0) * (nf - 1.0) + 0.5) / nf, 0.5));
}

vec4 inshade_lut2_fast(sampler2D t, ivec2 n, vec2 x) {
    vec2 nf = vec2(n);
    return texture(t, (clamp(x, 0.0, 1.0) * (nf - 1.0) + 0.5) / nf);
}

vec4 inshade_lut3_fast(sampler3D t, ivec3 n, vec3 x) {
    vec3 nf = vec3(n);
    return texture(t, (clamp(x, 0.0, 1.0) * (nf - 1.0) + 0.5) / nf);
}

// Two trilinear fetches, one per slice block; z stays inside [0.5, n.z - 0.5] texels of
// its block so neighbouring blocks never bleed in.
vec4 inshade_lut4_fast(sampler3D t, ivec4 n, vec4 x) {
    int w0, w1; float fw;
    inshade_lut_axis(x.w, n.w, w0, w1, fw);
    vec3 nf = vec3(n.xyz);
    vec3 u = clamp(x.xyz, 0.0, 1.0) * (nf - 1.0) + 0.5;
    float depth = float(n.z * n.w);
    vec4 a = texture(t, vec3(u.xy / nf.xy, (u.z + float(w0 * n.z)) / depth));
    vec4 b = texture(t, vec3(u.xy / nf.xy, (u.z + float(w1 * n.z)) / depth));
    return mix(a, b, fw);
}
