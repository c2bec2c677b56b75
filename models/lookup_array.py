"""Differentiable Indirection arrays (Datta et al. 2023): multilinear lookups, differentiable in the
cells and in the coordinate.

Texel convention (shared with codegen/lookup_array.py and shaders/lib/lookup_array.glsl):
corner-aligned. Along an axis of N cells, x in [0, 1] (clamped) maps to u = x * (N - 1); the
two cells are i0 = min(floor(u), N - 2) and i0 + 1, weight f = u - i0. Cells are stored
[N_{d-1}, ..., N_0, C] so that a 2D array is an image [height, width, channels].
"""
from __future__ import annotations

import math

import numpy as np
import torch

from inshade.components import LUT_BITS

from .encodings import triangle
from .registry import Component, register

NONLINEARITIES = {
    "none": lambda c, n: c,
    "triangle": lambda c, n: triangle(c),
    "sinusoid": lambda c, n: 0.5 * (1.0 + torch.sin(n * c)),
}


def multilinear(table: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """table [N_{d-1},...,N_0, C], x [..., d] -> [..., C] with the corner-aligned rule."""
    d = x.shape[-1]
    res = list(reversed(table.shape[:-1]))  # N_0 .. N_{d-1}
    lead = x.shape[:-1]
    x = x.reshape(-1, d)
    idx0, frac = [], []
    for k in range(d):
        n = res[k]
        u = x[:, k].clamp(0.0, 1.0) * float(n - 1)
        i0 = torch.floor(u).clamp(0, max(n - 2, 0)).detach()
        idx0.append(i0.long())
        frac.append(u - i0)
    flat = table.reshape(-1, table.shape[-1])
    strides = [int(np.prod(res[:k])) for k in range(d)]  # axis 0 is the fastest
    out = 0.0
    for corner in range(1 << d):
        w = 1.0
        lin = 0
        for k in range(d):
            bit = (corner >> k) & 1
            step = bit if res[k] > 1 else 0
            lin = lin + (idx0[k] + step) * strides[k]
            w = w * (frac[k] if bit else 1.0 - frac[k])
        out = out + w[:, None] * flat[lin]
    return out.reshape(*lead, table.shape[-1])


def quantize(table: np.ndarray, bits: int):
    """Per-channel affine quantisation: table ~= offset + scale * q / (2^bits - 1)."""
    lo = table.reshape(-1, table.shape[-1]).min(0).astype(np.float32)
    hi = table.reshape(-1, table.shape[-1]).max(0).astype(np.float32)
    scale = np.where(hi > lo, hi - lo, 1.0).astype(np.float32)
    levels = (1 << bits) - 1
    q = np.rint((table - lo) / scale * levels).clip(0, levels).astype(LUT_BITS[bits])
    return q, scale, lo


def dequantize(q: np.ndarray, scale: np.ndarray, offset: np.ndarray, bits: int) -> np.ndarray:
    levels = np.float32((1 << bits) - 1)
    return (offset + scale * (q.astype(np.float32) / levels)).astype(np.float32)


@register
class LookupArray(Component):
    """A d-dimensional array of C-channel cells, F(cells) interpolated multilinearly.

    `nonlinearity` F is the paper's periodic wrap ("triangle", or "sinusoid" (1+sin(n c))/2);
    export bakes F into the cells and quantises them to `bits`.
    """

    type = "lookup_array"

    def __init__(self, resolution, channels: int, bits: int = 32, nonlinearity: str = "none",
                 frequency: float = math.pi, init: str | torch.Tensor = "ramp", baked: str = "none"):
        super().__init__()
        self.resolution = [int(n) for n in resolution]
        self.channels, self.bits = int(channels), int(bits)
        self.nonlinearity, self.frequency, self.baked = nonlinearity, float(frequency), baked
        shape = tuple(reversed(self.resolution)) + (self.channels,)
        if isinstance(init, torch.Tensor):
            cells = init.reshape(shape).float()
        elif init == "ramp":  # identity uv-map, repeated over channels (paper 1.3)
            axes = [torch.linspace(0, 1, n) if n > 1 else torch.zeros(1) for n in self.resolution]
            grid = torch.meshgrid(*reversed(axes), indexing="ij")  # [N_{d-1}..N_0]
            coords = list(reversed(grid))  # coords[k] varies along axis k
            cells = torch.stack([coords[c % len(coords)] for c in range(self.channels)], -1)
        elif init == "zeros":
            cells = torch.zeros(shape)
        else:
            raise ValueError(f"unknown init {init!r}")
        self.cells = torch.nn.Parameter(cells.clone())

    def table(self) -> torch.Tensor:
        return NONLINEARITIES[self.nonlinearity](self.cells, self.frequency)

    def forward(self, x):
        return multilinear(self.table(), x)

    def params(self):
        baked = self.nonlinearity if self.nonlinearity != "none" else self.baked
        return {"resolution": self.resolution, "channels": self.channels, "bits": self.bits, "baked": baked}

    def export_tensors(self):
        table = self.table().detach().cpu().float().numpy()
        stored = getattr(self, "_stored", None)
        if stored is not None and np.array_equal(stored[0], table):
            return dict(stored[1])  # imported and untouched: the same integers, bit for bit
        if self.bits == 32:
            return {"cells": np.ascontiguousarray(table, dtype=np.float32)}
        q, scale, offset = quantize(table, self.bits)
        return {"cells": q, "scale": scale, "offset": offset}

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        cells = tensors["cells"]
        if params["bits"] != 32:
            cells = dequantize(cells, tensors["scale"], tensors["offset"], params["bits"])
        m = cls(params["resolution"], params["channels"], params["bits"], "none",
                init=torch.from_numpy(np.array(cells, dtype=np.float32)), baked=params["baked"])
        if params["bits"] != 32:
            m._stored = (np.array(cells, dtype=np.float32), {k: np.array(v) for k, v in tensors.items()})
        return m
