// tiny-cuda-nn's OneBlob encoding: the HLSL (and Slang) spelling of one_blob.glsl (the same steps, in the
// same order).

float one_blob_quartic_cdf(float t, float bins) {
    float u = clamp(t * bins, -2.0, 2.0);
    float u2 = u * u;
    return clamp(u * (0.9375 + u2 * (-0.625 + u2 * 0.1875)) + 0.5, 0.0, 1.0);
}

float one_blob_cdf(float b, float x, float bins) {
    return (one_blob_quartic_cdf(b - x, bins) + one_blob_quartic_cdf((b - 1.0) - x, bins))
           + one_blob_quartic_cdf((b + 1.0) - x, bins);
}
