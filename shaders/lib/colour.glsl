// Colour transfer helpers. Rendering happens in linear light; these run once, at display.

// sRGB opto-electronic transfer function (IEC 61966-2-1), linear [0,1] -> encoded [0,1].
vec3 srgb_oetf(vec3 linear_rgb) {
    vec3 lo = linear_rgb * 12.92;
    vec3 hi = 1.055 * pow(max(linear_rgb, vec3(0.0)), vec3(1.0 / 2.4)) - 0.055;
    return mix(hi, lo, lessThanEqual(linear_rgb, vec3(0.0031308)));
}

// Inverse of srgb_oetf: encoded [0,1] -> linear [0,1].
vec3 srgb_eotf(vec3 encoded) {
    vec3 lo = encoded / 12.92;
    vec3 hi = pow((max(encoded, vec3(0.0)) + 0.055) / 1.055, vec3(2.4));
    return mix(hi, lo, lessThanEqual(encoded, vec3(0.04045)));
}

