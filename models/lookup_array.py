"""Differentiable Indirection arrays (Datta et al. 2023): the multilinear lookup, differentiable in the
cells and in the coordinate, and the cells' quantisation, which the array's twin
(components/lookup_array/torch_twin.py), the cascades and the trainers share.

Texel convention (shared with components/lookup_array/emit.py and lookup_array.glsl there):
corner-aligned. Along an axis of N cells, x in [0, 1] (clamped) maps to u = x * (N - 1); the
two cells are i0 = min(floor(u), N - 2) and i0 + 1, weight f = u - i0. Cells are stored
[N_{d-1}, ..., N_0, C] so that a 2D array is an image [height, width, channels].
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.components import LUT_BITS

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
