// tiny-cuda-nn's OneBlob encoding: the WGSL spelling of one_blob.glsl (the same steps, in the same order).

fn one_blob_quartic_cdf(t: f32, bins: f32) -> f32 {
    let u = clamp(t * bins, -2.0, 2.0);
    let u2 = u * u;
    return clamp(u * (0.9375 + u2 * (-0.625 + u2 * 0.1875)) + 0.5, 0.0, 1.0);
}

fn one_blob_cdf(b: f32, x: f32, bins: f32) -> f32 {
    return (one_blob_quartic_cdf(b - x, bins) + one_blob_quartic_cdf((b - 1.0) - x, bins))
           + one_blob_quartic_cdf((b + 1.0) - x, bins);
}
