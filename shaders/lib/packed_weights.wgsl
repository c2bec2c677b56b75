// packed_weights.glsl in WGSL: float16 values in the low 16 bits of each lane -> float32.
fn inshade_half4(h: vec4<u32>) -> vec4<f32> {
    let normal = bitcast<vec4<f32>>(((h & vec4<u32>(0x8000u)) << vec4<u32>(16u))
                                    | (((h & vec4<u32>(0x7FFFu)) << vec4<u32>(13u)) + vec4<u32>(0x38000000u)));
    let sub = vec4<f32>(h & vec4<u32>(0x3FFu)) * 5.96046448e-08
              * (1.0 - 2.0 * vec4<f32>((h >> vec4<u32>(15u)) & vec4<u32>(1u)));
    let is_normal = min(vec4<f32>(h & vec4<u32>(0x7C00u)), vec4<f32>(1.0));
    return normal * is_normal + sub * (1.0 - is_normal);
}
