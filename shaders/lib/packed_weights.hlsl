// packed_weights.glsl in HLSL: float16 values in the low 16 bits of each lane -> float32.
float4 inshade_half4(uint4 h) {
    float4 normal = asfloat(((h & 0x8000u) << 16u) | (((h & 0x7FFFu) << 13u) + 0x38000000u));
    float4 sub = float4(h & 0x3FFu) * 5.96046448e-08 * (1.0 - 2.0 * float4((h >> 15u) & 1u));
    float4 is_normal = min(float4(h & 0x7C00u), 1.0);
    return normal * is_normal + sub * (1.0 - is_normal);
}
