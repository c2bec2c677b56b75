// Latent texture pyramid lookups in WGSL (latent_pyramid.glsl for OpenGL; the torch twin and the
// texel convention in models/latent_pyramid.py): one level per query, bilinear within it, texel
// centres at (i + 0.5) / N, wrap = repeat. `level` is already floored and clamped by the caller.
// *_exact: 4 textureLoad at the level with integer repeat wrap + fp32 mix. *_fast:
// textureSampleLevel at the integer level through the texture's sampler (hardware bilinear, repeat).

fn inshade_latent_exact(t: texture_2d<f32>, n0: i32, uv: vec2<f32>, level: i32) -> vec4<f32> {
    let n = n0 >> u32(level);
    let s = uv * f32(n) - 0.5;
    let fl = floor(s);
    let f = s - fl;
    let wrap = vec2<i32>(n - 1);   // n is a power of two: & wraps negatives too
    let i0 = vec2<i32>(fl) & wrap;
    let i1 = (i0 + vec2<i32>(1)) & wrap;
    let a = mix(textureLoad(t, vec2<i32>(i0.x, i0.y), level), textureLoad(t, vec2<i32>(i1.x, i0.y), level), f.x);
    let b = mix(textureLoad(t, vec2<i32>(i0.x, i1.y), level), textureLoad(t, vec2<i32>(i1.x, i1.y), level), f.x);
    return mix(a, b, f.y);
}

fn inshade_latent_fast(t: texture_2d<f32>, s: sampler, uv: vec2<f32>, level: i32) -> vec4<f32> {
    return textureSampleLevel(t, s, uv, f32(level));
}

// floor(level) clamped to [0, levels - 1].
fn inshade_latent_level(level: f32, levels: i32) -> i32 {
    return i32(clamp(floor(level), 0.0, f32(levels - 1)));
}
