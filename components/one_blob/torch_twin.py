"""tiny-cuda-nn's OneBlob encoding: the torch twin."""
from __future__ import annotations

import torch

from inshade.models.registry import WithParams, register


def quartic_cdf(t: torch.Tensor, n_bins: int) -> torch.Tensor:
    """tiny-cuda-nn's quartic_cdf(t, inv_radius = n_bins) (common_device.h): the integral of the kernel
    15/16 (1 - u^2)^2 up to u = t * n_bins, clamped to [0, 1]. tiny-cuda-nn writes the polynomial
    15/16 u (1 - 2/3 u^2 + 1/5 u^4) + 1/2; expanded it is u (15/16 + u^2 (-10/16 + u^2 3/16)) + 1/2,
    with exact coefficients: this Horner form is what compilers leave alone (llvmpipe expands the
    product form itself), and it is within a few ulp of 1/2 of tiny-cuda-nn's. u is clamped to
    [-2, 2] first: the kernel is flat beyond |u| = 1, so no value changes, and u^5 stays finite."""
    u = (t * float(n_bins)).clamp(-2.0, 2.0)
    u2 = u * u
    return (u * (0.9375 + u2 * (-0.625 + u2 * 0.1875)) + 0.5).clamp(0.0, 1.0)


@register
class OneBlob(WithParams):
    """tiny-cuda-nn's OneBlob encoding (encodings/oneblob.h: kernel_one_blob_soa and the fused device
    function, which compute the same sums). Per input x and bin k < B = n_bins:

        cdf(b) = (K(b - x) + K((b - 1) - x)) + K((b + 1) - x),   K = quartic_cdf(., B)
        out[i * B + k] = cdf((k + 1) / B) - cdf(k / B)

    i.e. the mass in bin k of a quartic blob of radius 1/B at x, wrapped once each way with period
    1 (the three terms). Lanes are input-major. b and b -/+ 1 are exact (B a power of two), so each
    argument is one rounding; tiny-cuda-nn writes (b - x) -/+ 1 (two roundings, up to one ulp of
    the argument apart, i.e. up to ~1.1e-7 * B in an output), which GLSL compilers may legally
    refold into this form, so this form is the one both executors can hold bit-identical."""

    type = "one_blob"
    fields = {"n_bins": (int, 16)}

    def forward(self, x):
        b = torch.arange(self.n_bins + 1, dtype=torch.float32) / self.n_bins
        x = x[..., None]                                          # cdf at [..., d, B + 1] boundaries
        n = self.n_bins
        cdf = (quartic_cdf(b - x, n) + quartic_cdf((b - 1.0) - x, n)) + quartic_cdf((b + 1.0) - x, n)
        return (cdf[..., 1:] - cdf[..., :-1]).flatten(-2)
