"""Torch twin of shaders/lib/unit_box.glsl: the unit box [0,1]^3 along rays, same float32 operations."""
from __future__ import annotations

import torch

TINY = 1e-12      # |rd component| below this is replaced by it (a finite slab test)


def unit_box(ro: torch.Tensor, rd: torch.Tensor):
    """(hit, t0, t1) for rays [N, 3]: entry t0 >= 0, exit t1, hit = t1 >= t0."""
    tiny = torch.tensor(TINY, dtype=rd.dtype, device=rd.device)
    inv = 1.0 / torch.where(rd.abs() < tiny, tiny, rd)
    a = (0.0 - ro) * inv
    c = (1.0 - ro) * inv
    lo, hi = torch.minimum(a, c), torch.maximum(a, c)
    t0 = torch.maximum(torch.maximum(lo[:, 0], lo[:, 1]), lo[:, 2].clamp_min(0.0))
    t1 = torch.minimum(hi[:, 0], torch.minimum(hi[:, 1], hi[:, 2]))
    return t1 >= t0, t0, t1
