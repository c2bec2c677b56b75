"""Latent texture pyramid (Real-Time Neural Appearance Models, §4.1): trainable texels, one
bilinear lookup within one level per query.

Texel convention (shared with codegen/latent_pyramid.py and shaders/lib/latent_pyramid.glsl):
level k is [N, N, C] with N = resolution >> k, rows are v, columns u; texel centres at
(i + 0.5) / N; wrap = repeat. A query (u, v, level) floors `level` and clamps it to
[0, levels - 1] (the stochastic choice between two levels is the caller's); then
t = u * N - 0.5, i0 = floor(t), f = t - i0, columns i0 & (N - 1) and (i0 + 1) & (N - 1)
(N is a power of two, so & is the repeat wrap for negative indices too), the same for rows.
"""
from __future__ import annotations

import numpy as np
import torch

from .registry import Component, register


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


@register
class LatentPyramid(Component):
    """`levels` trainable latent images (nn.Parameter each, `self.texels[k]` is [res >> k,
    res >> k, channels]). forward(x [..., 3] = (u, v, level)) -> [..., channels], batched over
    mixed levels; gradients reach the texels (and u, v). precision "f16" rounds the texels to
    fp16 in forward (straight-through) and at export."""

    type = "latent_pyramid"

    def __init__(self, resolution: int, levels: int, channels: int = 8, precision: str = "f32",
                 init: str | list = "normal", scale: float = 0.1, seed: int = 0):
        super().__init__()
        self.resolution, self.levels, self.channels = int(resolution), int(levels), int(channels)
        self.precision = precision
        if isinstance(init, (list, tuple)):
            arrays = [torch.as_tensor(np.asarray(a, np.float32)) for a in init]
        elif init in ("normal", "zeros"):
            gen = torch.Generator().manual_seed(seed)
            arrays = [scale * torch.randn((self.resolution >> k, self.resolution >> k, self.channels), generator=gen)
                      if init == "normal" else torch.zeros((self.resolution >> k, self.resolution >> k, self.channels))
                      for k in range(self.levels)]
        else:
            raise ValueError(f"unknown init {init!r} (choose 'normal', 'zeros' or a list of arrays)")
        if len(arrays) != self.levels:
            raise ValueError(f"latent_pyramid: {len(arrays)} level arrays for levels={self.levels}")
        for k, a in enumerate(arrays):
            want = (self.resolution >> k, self.resolution >> k, self.channels)
            if tuple(a.shape) != want:
                raise ValueError(f"latent_pyramid: level{k} has shape {list(a.shape)}, expected {list(want)}")
        self.texels = torch.nn.ParameterList([torch.nn.Parameter(a.clone().float()) for a in arrays])

    @classmethod
    def from_arrays(cls, arrays, precision: str = "f32") -> "LatentPyramid":
        """From level arrays [res >> k, res >> k, C], finest first."""
        arrays = [np.asarray(a, np.float32) for a in arrays]
        return cls(arrays[0].shape[0], len(arrays), arrays[0].shape[-1], precision, init=arrays)

    def level(self, k: int) -> torch.Tensor:
        """Level k as the lookup sees it (fp16-rounded for precision f16)."""
        t = self.texels[k]
        return _round_fp16(t) if self.precision == "f16" else t

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        lead = x.shape[:-1]
        x = x.reshape(-1, 3)
        lvl = torch.floor(x[:, 2].detach()).clamp(0, self.levels - 1).long()
        out = x.new_zeros((x.shape[0], self.channels))
        for k in range(self.levels):
            idx = torch.nonzero(lvl == k).squeeze(1)
            if idx.numel():
                out = out.index_copy(0, idx, bilinear_repeat(self.level(k), x[idx, :2]).to(out.dtype))
        return out.reshape(*lead, self.channels)

    def params(self):
        return {"resolution": self.resolution, "levels": self.levels, "channels": self.channels,
                "precision": self.precision}

    def export_tensors(self):
        return {f"level{k}": np.ascontiguousarray(self.level(k).detach().cpu().float().numpy())
                for k in range(self.levels)}

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        return cls(params["resolution"], params["levels"], params["channels"], params["precision"],
                   init=[tensors[f"level{k}"] for k in range(params["levels"])])
