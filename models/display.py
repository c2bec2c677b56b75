"""The display domain in torch: what a screen shows of linear radiance -- clamped to [0, 1] and
sRGB-encoded -- the domain the BRDF figures' PSNR and the shading losses are measured in. Its numpy
twin is inshade.metrics.srgb_oetf of the clipped radiance; this one is differentiable."""
from __future__ import annotations

import torch


def srgb_display(radiance: torch.Tensor) -> torch.Tensor:
    """Clamp to [0, 1], sRGB-encode (differentiable; the clamp_min keeps the unused branch's
    gradient finite at 0)."""
    x = radiance.clamp(0.0, 1.0)
    return torch.where(x <= 0.0031308, 12.92 * x, 1.055 * x.clamp_min(0.0031308) ** (1.0 / 2.4) - 0.055)
