"""Torch twin of shaders/lib/field_march.glsl: the same march, step for step, in float32, with
any torch function of (position, direction) -> (rgb, density) as the field (the user's own module,
or the bundle's graph)."""
from __future__ import annotations

import numpy as np
import torch

from inshade.codegen.field import STOP
from inshade.models.sdf import camera_rays


def _box(ro, rd, lo, hi):
    d = torch.where(rd.abs() < 1e-12, torch.full_like(rd, 1e-12), rd)
    inv = 1.0 / d
    a, c = (lo - ro) * inv, (hi - ro) * inv
    near, far = torch.minimum(a, c), torch.maximum(a, c)
    t0 = torch.maximum(torch.maximum(near[:, 0], near[:, 1]), torch.maximum(near[:, 2], torch.zeros_like(near[:, 2])))
    t1 = torch.minimum(far[:, 0], torch.minimum(far[:, 1], far[:, 2]))
    return t0, t1


def march(field, settings: dict, uniforms: dict, width: int, height: int) -> np.ndarray:
    """[H, W, 4] linear RGBA (row 0 = top) of ``field`` ([N, 6] -> [N, 4] or a tuple of outputs
    concatenated, position then direction in, rgb then density out) marched as the shader does;
    ``settings``: codegen/field.py ``field_settings``; ``uniforms``: the camera's."""
    ro, rd = camera_rays(uniforms, width, height)
    lo, hi = (torch.tensor(c, dtype=torch.float32) for c in settings["box"])
    step = torch.tensor(settings["step"], dtype=torch.float32)
    bg = torch.tensor(settings["background"], dtype=torch.float32)
    t0, t1 = _box(ro, rd, lo, hi)
    active = t1 >= t0
    colour = torch.zeros(ro.shape[0], 3)
    trans = torch.ones(ro.shape[0])
    with torch.no_grad():
        for i in range(settings["max_steps"]):
            t = t0 + (float(i) + 0.5) * step
            active = active & (t < t1)
            if not active.any():
                break
            idx = active.nonzero().squeeze(1)
            p = ro[idx] + rd[idx] * t[idx, None]
            y = _flat(field(torch.cat([p, rd[idx]], -1)))
            sigma = y[:, 3].clamp_min(0.0)
            alpha = 1.0 - torch.exp(-sigma * step)
            colour[idx] = colour[idx] + (trans[idx] * alpha)[:, None] * y[:, :3]
            trans[idx] = trans[idx] * (1.0 - alpha)
            active[idx] = trans[idx] >= STOP
    out = torch.cat([colour + trans[:, None] * bg, torch.ones(ro.shape[0], 1)], -1)
    return out.reshape(height, width, 4).numpy()


def _flat(y) -> torch.Tensor:
    if isinstance(y, (tuple, list)):
        return torch.cat([v.reshape(v.shape[0], -1) for v in y], -1)
    return y
