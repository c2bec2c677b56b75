"""Latent texture pyramid (Real-Time Neural Appearance Models, §4.1): the bilinear lookup within one
level and the fp16 rounding of texels that the trainable components share (the pyramid's twin is
components/latent_pyramid/torch_twin.py).

Texel convention (shared with components/latent_pyramid/emit.py and latent_pyramid.glsl there):
level k is [N, N, C] with N = resolution >> k, rows are v, columns u; texel centres at
(i + 0.5) / N; wrap = repeat. A query (u, v, level) floors `level` and clamps it to
[0, levels - 1] (the stochastic choice between two levels is the caller's); then
t = u * N - 0.5, i0 = floor(t), f = t - i0, columns i0 & (N - 1) and (i0 + 1) & (N - 1)
(N is a power of two, so & is the repeat wrap for negative indices too), the same for rows.
"""
from __future__ import annotations

import torch


def _round_fp16(x: torch.Tensor) -> torch.Tensor:
    """fp16 rounding in the forward pass, identity in the backward pass (straight-through), so
    the trainer optimises fp32 texels while the loss sees what an RGBA16F texture holds."""
    return x + (x.half().float() - x).detach()


def bilinear_repeat(level: torch.Tensor, uv: torch.Tensor) -> torch.Tensor:
    """level [N, N, C], uv [M, 2] -> [M, C]: bilinear, texel centres at (i + 0.5) / N, repeat."""
    n = level.shape[0]
    t = uv * float(n) - 0.5
    i0 = torch.floor(t)
    f = (t - i0).to(level.dtype)
    i0 = i0.long()
    x0, y0 = i0[:, 0] & (n - 1), i0[:, 1] & (n - 1)
    x1, y1 = (x0 + 1) & (n - 1), (y0 + 1) & (n - 1)
    fx, fy = f[:, :1], f[:, 1:]
    top = level[y0, x0] * (1 - fx) + level[y0, x1] * fx
    bottom = level[y1, x0] * (1 - fx) + level[y1, x1] * fx
    return top * (1 - fy) + bottom * fy
