// float16 values in the low 16 bits of each lane -> the float32 of the same value, with integer
// operations only (GLSL 3.30 has no half type and no unpackHalf2x16): a normal half's sign,
// exponent (re-biased by 127 - 15) and mantissa moved into place; a subnormal one (and zero) as
// mantissa * 2^-24. Both are finite, and the one not taken adds 0. (components/dense/emit_packed.py)
vec4 inshade_half4(uvec4 h) {
    vec4 normal = uintBitsToFloat(((h & 0x8000u) << 16u) | (((h & 0x7FFFu) << 13u) + 0x38000000u));
    vec4 sub = vec4(h & 0x3FFu) * 5.96046448e-08 * (1.0 - 2.0 * vec4((h >> 15u) & 1u));
    vec4 is_normal = min(vec4(h & 0x7C00u), 1.0);
    return normal * is_normal + sub * (1.0 - is_normal);
}
