// spherical_harmonics.glsl in WGSL: irradiance from radiance coefficients (the Lambert lobe's zonal
// convolution). The basis and its constants are the generated chunk sh_basis
// (codegen/spherical_harmonics.py, language "wgsl"), placed before this one.

// sum bands[l] c_lm Y_lm(d)
fn sh_convolved(d: vec3<f32>, coeffs: array<vec3<f32>, SH_COEFFS>, bands: array<f32, SH_DEGREE>) -> vec3<f32> {
    // arrays indexed at run time are copied into variables first
    var y = sh_basis(d);
    var c = coeffs;
    var b = bands;
    var band = SH_BAND;
    var acc = vec3<f32>(0.0);
    for (var i: i32 = 0; i < SH_COEFFS; i++) {
        acc += c[i] * (b[band[i]] * y[i]);
    }
    return acc;
}

// Irradiance at normal n: sum A_l L_lm Y_lm(n), not divided by pi.
fn sh_irradiance(n: vec3<f32>, coeffs: array<vec3<f32>, SH_COEFFS>) -> vec3<f32> {
    return sh_convolved(n, coeffs, SH_LAMBERT);
}
