// Spherical-harmonics lighting: reconstruction, irradiance (Lambert) and zonal convolution
// (Phong) from coefficients passed as uniform vec3 arrays. Python twins in inshade/sh.py
// (sh_evaluate, sh_irradiance, convolve_zonal); the basis and constants come from the
// generated chunk <sh_basis> (codegen/spherical_harmonics.py: chunks=sh_chunks(degree)).
// Directions are unit vectors in the right-handed, y-up world frame.
#include <sh_basis>

// sum_i c_i y_i
vec3 sh_dot(in float y[SH_COEFFS], in vec3 coeffs[SH_COEFFS]) {
    vec3 acc = vec3(0.0);
    for (int i = 0; i < SH_COEFFS; ++i) {
        acc += coeffs[i] * y[i];
    }
    return acc;
}

// The band-limited function itself at direction d (e.g. the environment's radiance).
vec3 sh_radiance(vec3 d, in vec3 coeffs[SH_COEFFS]) {
    float y[SH_COEFFS];
    sh_basis(d, y);
    return sh_dot(y, coeffs);
}

// A zonal convolution evaluated at d: sum bands[l] c_lm Y_lm(d), with per-band factors from
// inshade.sh.phong_bands / zonal_bands (e.g. glossy Phong at the reflection direction).
vec3 sh_convolved(vec3 d, in vec3 coeffs[SH_COEFFS], in float bands[SH_DEGREE]) {
    float y[SH_COEFFS];
    sh_basis(d, y);
    vec3 acc = vec3(0.0);
    for (int i = 0; i < SH_COEFFS; ++i) {
        acc += coeffs[i] * (bands[SH_BAND[i]] * y[i]);
    }
    return acc;
}

// Irradiance at normal n from radiance coefficients: sum A_l L_lm Y_lm(n), the Lambert lobe's
// convolution, not divided by pi (diffuse outgoing radiance is albedo / pi * this).
vec3 sh_irradiance(vec3 n, in vec3 coeffs[SH_COEFFS]) {
    return sh_convolved(n, coeffs, SH_LAMBERT);
}

// The environment as a background at direction d: the series smoothed by SH_BACKGROUND (a Hann
// window, so a truncated environment does not ring into black bands), clamped at 0.
vec3 sh_background(vec3 d, in vec3 coeffs[SH_COEFFS]) {
    return max(sh_convolved(d, coeffs, SH_BACKGROUND), vec3(0.0));
}
