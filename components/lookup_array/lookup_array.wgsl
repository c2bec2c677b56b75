// Differentiable Indirection lookups in WGSL (lookup_array.glsl for OpenGL; the torch twin in
// torch_twin.py). Corner-aligned: along an axis of n cells, x in [0,1] (clamped) maps to
// u = x * (n - 1); cells i0 = min(floor(u), n - 2) and i0 + 1 are mixed with weight u - i0.
// *_exact: textureLoad + fp32 mix. *_fast: hardware linear filtering at (u + 0.5) / n, level 0,
// through the texture's sampler.

struct InshadeLutAxis { i0: i32, i1: i32, f: f32 }

fn inshade_lut_axis(x: f32, n: i32) -> InshadeLutAxis {
    let u = clamp(x, 0.0, 1.0) * f32(n - 1);
    let fl = min(floor(u), f32(max(n - 2, 0)));
    let i0 = i32(fl);
    return InshadeLutAxis(i0, min(i0 + 1, n - 1), u - fl);
}

fn inshade_lut1_exact(t: texture_2d<f32>, n: i32, x: f32) -> vec4<f32> {
    let a = inshade_lut_axis(x, n);
    return mix(textureLoad(t, vec2<i32>(a.i0, 0), 0), textureLoad(t, vec2<i32>(a.i1, 0), 0), a.f);
}

fn inshade_lut2_exact(t: texture_2d<f32>, n: vec2<i32>, x: vec2<f32>) -> vec4<f32> {
    let ax = inshade_lut_axis(x.x, n.x);
    let ay = inshade_lut_axis(x.y, n.y);
    let a = mix(textureLoad(t, vec2<i32>(ax.i0, ay.i0), 0), textureLoad(t, vec2<i32>(ax.i1, ay.i0), 0), ax.f);
    let b = mix(textureLoad(t, vec2<i32>(ax.i0, ay.i1), 0), textureLoad(t, vec2<i32>(ax.i1, ay.i1), 0), ax.f);
    return mix(a, b, ay.f);
}

// One trilinear cell of a 3D texture whose cells start at texel `base` (a slice block of a 4D array).
fn inshade_lut3_cell_at(t: texture_3d<f32>, n: vec3<i32>, x: vec3<f32>, base: vec3<i32>) -> vec4<f32> {
    let ax = inshade_lut_axis(x.x, n.x);
    let ay = inshade_lut_axis(x.y, n.y);
    let az = inshade_lut_axis(x.z, n.z);
    let p = vec3<i32>(ax.i0, ay.i0, az.i0) + base;
    let q = vec3<i32>(ax.i1, ay.i1, az.i1) + base;
    let a = mix(textureLoad(t, vec3<i32>(p.x, p.y, p.z), 0), textureLoad(t, vec3<i32>(q.x, p.y, p.z), 0), ax.f);
    let b = mix(textureLoad(t, vec3<i32>(p.x, q.y, p.z), 0), textureLoad(t, vec3<i32>(q.x, q.y, p.z), 0), ax.f);
    let c = mix(textureLoad(t, vec3<i32>(p.x, p.y, q.z), 0), textureLoad(t, vec3<i32>(q.x, p.y, q.z), 0), ax.f);
    let d = mix(textureLoad(t, vec3<i32>(p.x, q.y, q.z), 0), textureLoad(t, vec3<i32>(q.x, q.y, q.z), 0), ax.f);
    return mix(mix(a, b, ay.f), mix(c, d, ay.f), az.f);
}

fn inshade_lut3_exact(t: texture_3d<f32>, n: vec3<i32>, x: vec3<f32>) -> vec4<f32> {
    return inshade_lut3_cell_at(t, n, x, vec3<i32>(0, 0, 0));
}

// 4D arrays live in a 3D texture of n.x * n.y * (n.z * n.w): slice block w starts at w * n.z.
fn inshade_lut4_exact(t: texture_3d<f32>, n: vec4<i32>, x: vec4<f32>) -> vec4<f32> {
    let aw = inshade_lut_axis(x.w, n.w);
    return mix(inshade_lut3_cell_at(t, n.xyz, x.xyz, vec3<i32>(0, 0, aw.i0 * n.z)),
               inshade_lut3_cell_at(t, n.xyz, x.xyz, vec3<i32>(0, 0, aw.i1 * n.z)), aw.f);
}

fn inshade_lut1_fast(t: texture_2d<f32>, s: sampler, n: i32, x: f32) -> vec4<f32> {
    let nf = f32(n);
    return textureSampleLevel(t, s, vec2<f32>((clamp(x, 0.0, 1.0) * (nf - 1.0) + 0.5) / nf, 0.5), 0.0);
}

fn inshade_lut2_fast(t: texture_2d<f32>, s: sampler, n: vec2<i32>, x: vec2<f32>) -> vec4<f32> {
    let nf = vec2<f32>(n);
    return textureSampleLevel(t, s, (clamp(x, vec2<f32>(0.0), vec2<f32>(1.0)) * (nf - 1.0) + 0.5) / nf, 0.0);
}

fn inshade_lut3_fast(t: texture_3d<f32>, s: sampler, n: vec3<i32>, x: vec3<f32>) -> vec4<f32> {
    let nf = vec3<f32>(n);
    return textureSampleLevel(t, s, (clamp(x, vec3<f32>(0.0), vec3<f32>(1.0)) * (nf - 1.0) + 0.5) / nf, 0.0);
}

// Two trilinear fetches, one per slice block; z stays inside [0.5, n.z - 0.5] texels of
// its block so neighbouring blocks never bleed in.
fn inshade_lut4_fast(t: texture_3d<f32>, s: sampler, n: vec4<i32>, x: vec4<f32>) -> vec4<f32> {
    let aw = inshade_lut_axis(x.w, n.w);
    let nf = vec3<f32>(n.xyz);
    let u = clamp(x.xyz, vec3<f32>(0.0), vec3<f32>(1.0)) * (nf - 1.0) + 0.5;
    let depth = f32(n.z * n.w);
    let a = textureSampleLevel(t, s, vec3<f32>(u.xy / nf.xy, (u.z + f32(aw.i0 * n.z)) / depth), 0.0);
    let b = textureSampleLevel(t, s, vec3<f32>(u.xy / nf.xy, (u.z + f32(aw.i1 * n.z)) / depth), 0.0);
    return mix(a, b, aw.f);
}

// Layouts for arrays whose natural texture exceeds the limits (emit.py).
// 4D folded along another axis of the 3D texture: `fold` is the unit axis (x, y or z) that
// holds the n.w slice blocks, block w starting at w * n.xyz * fold.
fn inshade_lut4_exact_fold(t: texture_3d<f32>, n: vec4<i32>, fold: vec3<i32>, x: vec4<f32>) -> vec4<f32> {
    let aw = inshade_lut_axis(x.w, n.w);
    return mix(inshade_lut3_cell_at(t, n.xyz, x.xyz, aw.i0 * n.xyz * fold),
               inshade_lut3_cell_at(t, n.xyz, x.xyz, aw.i1 * n.xyz * fold), aw.f);
}

fn inshade_lut4_fast_fold(t: texture_3d<f32>, s: sampler, n: vec4<i32>, fold: vec3<i32>, x: vec4<f32>) -> vec4<f32> {
    let aw = inshade_lut_axis(x.w, n.w);
    let nf = vec3<f32>(n.xyz);
    let u = clamp(x.xyz, vec3<f32>(0.0), vec3<f32>(1.0)) * (nf - 1.0) + 0.5;
    let size = nf * (1.0 + f32(n.w - 1) * vec3<f32>(fold));
    let a = textureSampleLevel(t, s, (u + f32(aw.i0) * nf * vec3<f32>(fold)) / size, 0.0);
    let b = textureSampleLevel(t, s, (u + f32(aw.i1) * nf * vec3<f32>(fold)) / size, 0.0);
    return mix(a, b, aw.f);
}

// Any array, exact path, cells in C order (x fastest) wrapped into rows of a 2D texture `w`
// texels wide: linear cell i lives at texel (i % w, i / w).
fn inshade_lut_wrapped_fetch(t: texture_2d<f32>, i: i32, w: i32) -> vec4<f32> {
    return textureLoad(t, vec2<i32>(i % w, i / w), 0);
}

fn inshade_lut1_exact_wrapped(t: texture_2d<f32>, n: i32, w: i32, x: f32) -> vec4<f32> {
    let a = inshade_lut_axis(x, n);
    return mix(inshade_lut_wrapped_fetch(t, a.i0, w), inshade_lut_wrapped_fetch(t, a.i1, w), a.f);
}

fn inshade_lut2_exact_wrapped(t: texture_2d<f32>, n: vec2<i32>, w: i32, x: vec2<f32>) -> vec4<f32> {
    let ax = inshade_lut_axis(x.x, n.x);
    let ay = inshade_lut_axis(x.y, n.y);
    let y0 = ay.i0 * n.x;
    let y1 = ay.i1 * n.x;
    let a = mix(inshade_lut_wrapped_fetch(t, y0 + ax.i0, w), inshade_lut_wrapped_fetch(t, y0 + ax.i1, w), ax.f);
    let b = mix(inshade_lut_wrapped_fetch(t, y1 + ax.i0, w), inshade_lut_wrapped_fetch(t, y1 + ax.i1, w), ax.f);
    return mix(a, b, ay.f);
}

// One trilinear cell of a wrapped 3D array whose cells start at linear index `base`.
fn inshade_lut3_cell_wrapped(t: texture_2d<f32>, n: vec3<i32>, x: vec3<f32>, base: i32, w: i32) -> vec4<f32> {
    let ax = inshade_lut_axis(x.x, n.x);
    let ay = inshade_lut_axis(x.y, n.y);
    let az = inshade_lut_axis(x.z, n.z);
    let y0 = ay.i0 * n.x;
    let y1 = ay.i1 * n.x;
    let z0 = base + az.i0 * n.x * n.y;
    let z1 = base + az.i1 * n.x * n.y;
    let a = mix(inshade_lut_wrapped_fetch(t, z0 + y0 + ax.i0, w), inshade_lut_wrapped_fetch(t, z0 + y0 + ax.i1, w), ax.f);
    let b = mix(inshade_lut_wrapped_fetch(t, z0 + y1 + ax.i0, w), inshade_lut_wrapped_fetch(t, z0 + y1 + ax.i1, w), ax.f);
    let c = mix(inshade_lut_wrapped_fetch(t, z1 + y0 + ax.i0, w), inshade_lut_wrapped_fetch(t, z1 + y0 + ax.i1, w), ax.f);
    let d = mix(inshade_lut_wrapped_fetch(t, z1 + y1 + ax.i0, w), inshade_lut_wrapped_fetch(t, z1 + y1 + ax.i1, w), ax.f);
    return mix(mix(a, b, ay.f), mix(c, d, ay.f), az.f);
}

fn inshade_lut3_exact_wrapped(t: texture_2d<f32>, n: vec3<i32>, w: i32, x: vec3<f32>) -> vec4<f32> {
    return inshade_lut3_cell_wrapped(t, n, x, 0, w);
}

fn inshade_lut4_exact_wrapped(t: texture_2d<f32>, n: vec4<i32>, w: i32, x: vec4<f32>) -> vec4<f32> {
    let aw = inshade_lut_axis(x.w, n.w);
    let block = n.x * n.y * n.z;
    return mix(inshade_lut3_cell_wrapped(t, n.xyz, x.xyz, aw.i0 * block, w),
               inshade_lut3_cell_wrapped(t, n.xyz, x.xyz, aw.i1 * block, w), aw.f);
}
