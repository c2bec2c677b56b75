// Colour transfer in WGSL: colour.glsl's srgb_eotf (encoded [0,1] -> linear [0,1]).
fn srgb_eotf(encoded: vec3<f32>) -> vec3<f32> {
    let lo = encoded / 12.92;
    let hi = pow((max(encoded, vec3<f32>(0.0)) + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, encoded <= vec3<f32>(0.04045));
}
