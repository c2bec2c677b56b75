"""Latent texture pyramid (Real-Time Neural Appearance Models, §4.1): the torch twin, trainable texels,
one bilinear lookup within one level per query (texel convention: models/latent_pyramid.py)."""
from __future__ import annotations

import numpy as np
import torch

from inshade.models.latent_pyramid import _round_fp16, bilinear_repeat
from inshade.models.registry import Component, register
from inshade.models.unorm_lanes import UnormLanes
from inshade.components.unorm import decode


@register
class LatentPyramid(UnormLanes, Component):
    """`levels` trainable latent images (nn.Parameter each, `self.texels[k]` is [res >> k,
    res >> k, channels]). forward(x [..., 3] = (u, v, level)) -> [..., channels], batched over
    mixed levels; gradients reach the texels (and u, v). precision "f16" rounds the texels to
    fp16 in forward (straight-through) and at export; "u8" blends the unit values q / 255 and decodes
    offset + scale * blend per channel, one range over all levels (models/unorm_lanes.py)."""

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
        if precision == "u8":
            self.calibrate()

    def unorm_values(self) -> torch.Tensor:
        return torch.cat([t.reshape(-1, self.channels) for t in self.texels])

    @classmethod
    def from_arrays(cls, arrays, precision: str = "f32") -> "LatentPyramid":
        """From level arrays [res >> k, res >> k, C], finest first."""
        arrays = [np.asarray(a, np.float32) for a in arrays]
        return cls(arrays[0].shape[0], len(arrays), arrays[0].shape[-1], precision, init=arrays)

    def level(self, k: int) -> torch.Tensor:
        """Level k as the lookup sees it (fp16-rounded for precision f16, unit values q / 255 for u8)."""
        return {"f16": _round_fp16, "u8": self.unit}.get(self.precision, lambda t: t)(self.texels[k])

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        lead = x.shape[:-1]
        x = x.reshape(-1, 3)
        lvl = torch.floor(x[:, 2].detach()).clamp(0, self.levels - 1).long()
        out = x.new_zeros((x.shape[0], self.channels))
        for k in range(self.levels):
            idx = torch.nonzero(lvl == k).squeeze(1)
            if idx.numel():
                out = out.index_copy(0, idx, bilinear_repeat(self.level(k), x[idx, :2]).to(out.dtype))
        if self.precision == "u8":
            out = self.decode(out)
        return out.reshape(*lead, self.channels)

    def params(self):
        return {"resolution": self.resolution, "levels": self.levels, "channels": self.channels,
                "precision": self.precision}

    def export_tensors(self):
        if self.precision == "u8":
            return {**{f"level{k}": self.codes(t) for k, t in enumerate(self.texels)}, **self.unorm_range()}
        return {f"level{k}": np.ascontiguousarray(self.level(k).detach().cpu().float().numpy())
                for k in range(self.levels)}

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        u8 = params["precision"] == "u8"
        levels = [decode(tensors[f"level{k}"], tensors["scale"], tensors["offset"]) if u8 else tensors[f"level{k}"]
                  for k in range(params["levels"])]
        m = cls(params["resolution"], params["levels"], params["channels"], params["precision"], init=levels)
        if u8:
            m.calibrate(tensors["scale"], tensors["offset"])
        return m
