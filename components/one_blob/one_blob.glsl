// tiny-cuda-nn's OneBlob encoding (encodings/oneblob.h); torch twin: torch_twin.py (OneBlob),
// every step one float32 rounding in the same order.

// quartic_cdf(t, inv_radius = bins) of tiny-cuda-nn's common_device.h: the integral of the kernel
// 15/16 (1 - u^2)^2 up to u = t * bins, clamped to [0, 1]; its polynomial in Horner form with exact
// coefficients (15/16, -10/16, 3/16), which compilers leave as written. u is clamped to [-2, 2]
// first: the kernel is flat beyond |u| = 1, so no value changes, and u^5 stays finite.
float one_blob_quartic_cdf(float t, float bins) {
    float u = clamp(t * bins, -2.0, 2.0);
    float u2 = u * u;
    return clamp(u * (0.9375 + u2 * (-0.625 + u2 * 0.1875)) + 0.5, 0.0, 1.0);
}

// The blob at x, wrapped once each way with period 1: its mass below the bin boundary b. b - 1 and
// b + 1 are exact, so each argument is one rounding (a compiler may fold (b - x) - 1 into this form).
float one_blob_cdf(float b, float x, float bins) {
    return (one_blob_quartic_cdf(b - x, bins) + one_blob_quartic_cdf((b - 1.0) - x, bins))
           + one_blob_quartic_cdf((b + 1.0) - x, bins);
}
