"""Training points near occluders (thin.py's study found the network's error concentrates there):

- ``occluder_proximity(sdf, p, n, delta)``: 1 - clamp(sdf(p + delta n) / delta, 0, 1): 0 on an open
  flat surface, towards 1 where another surface lies within ``delta`` of the point along its
  normal (contact shadows, slots, gear teeth on a plate).
- ``sample_near_occluders(sdf, n_points, seed, boost, delta)``: surface samples drawn without
  replacement from a 4x uniform pool with probability ~ 1 + boost x proximity.
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.techniques.prt.transfer_surface import sample_sdf_surface


def occluder_proximity(sdf, p, n, delta: float, device=None) -> torch.Tensor:
    """[N] on p's device; the SDF is evaluated on ``device`` (default p's)."""
    with torch.no_grad():
        q = p + n * delta
        d = sdf(q.to(device or q.device)).to(q.device)
        return (1.0 - (d / delta).clamp(0.0, 1.0)).float()


def sample_near_occluders(sdf, n_points: int, seed: int = 0, boost: float = 3.0, delta: float | None = None,
                          device="cpu"):
    """(p, n) float32 on the CPU: see the module docstring; ``delta`` defaults to 3% of the bound
    radius; SDF evaluations on ``device`` (the SDF module is expected there)."""
    delta = float(delta if delta is not None else 0.03 * float(sdf.scene.radius))
    p, n = sample_sdf_surface(sdf, 4 * n_points, seed=seed, device=device)
    w = (1.0 + boost * occluder_proximity(sdf, p, n, delta, device=device)).double().numpy()
    rng = np.random.default_rng(seed)
    keep = np.sort(rng.choice(len(w), size=n_points, replace=False, p=w / w.sum()))
    return p[keep].contiguous(), n[keep].contiguous()
