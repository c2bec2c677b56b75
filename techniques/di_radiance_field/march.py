"""The volume march in torch: the twin of shaders/lib/rf_march.glsl (same step positions, same order,
float32). The parity tests compare the two images (>= 50 dB).

Per pixel (the pixel-centre ray of lib/camera's camera_ray; models/sdf.py camera_rays):
 1. unit box [0, 1]^3 entry t0 >= 0 / exit t1 (slab test, |rd| components below 1e-12 replaced by
    1e-12); missed: the background;
 2. the SH basis y_k(rd) (degree 1: 4 values, inshade.sh) once per ray;
 3. for i = 0, 1, ..., max_steps - 1: t = t0 + (i + 0.5) dt; stop when t >= t1;
    x = ro + rd t; (c [12], s) = network(x); sigma = max(s - density_floor, 0) sigma_scale;
    alpha = 1 - exp(-sigma dt);
    rgb = sigmoid(y_0 c[0:3] + y_1 c[3:6] + y_2 c[6:9] + y_3 c[9:12]) (sigmoid(z) = 1 / (1 + exp(-z)));
    C += T alpha rgb; T *= 1 - alpha; stop once T < STOP (early exit: at most STOP of the
    background or of the rest of the ray is left out);
 4. colour = C + T background, alpha = 1 (the constant background is part of the image).
Vectorised over pixels: every pixel runs the same steps, masked once it left the box or stopped.
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.models.sdf import camera_rays
from inshade.models.unit_box import unit_box
from inshade.sh import sh_basis

STOP = 1e-3       # transmittance that ends a ray (lib/rf_march.glsl RF_STOP)


def march(network, uniforms: dict, width: int, height: int, *, step: float, max_steps: int, sigma_scale: float,
          density_floor: float = 0.0, background=(0.0, 0.0, 0.0), stop: float = STOP) -> np.ndarray:
    """[H, W, 4] linear RGBA (row 0 = top) of ``network`` (x [P, 3] -> [P, 13]: colour SH logits,
    sigma / sigma_scale)."""
    ro, rd = camera_rays(uniforms, width, height)
    hit, t0, t1 = unit_box(ro, rd)
    y = sh_basis(rd, 2, xp=torch).float()
    dt = torch.tensor(step, dtype=torch.float32)
    scale = torch.tensor(sigma_scale, dtype=torch.float32)
    floor = torch.tensor(density_floor, dtype=torch.float32)
    colour = torch.zeros(len(ro), 3)
    trans = torch.ones(len(ro))
    live = hit.clone()
    with torch.no_grad():
        for i in range(int(max_steps)):
            t = t0 + (torch.tensor(float(i), dtype=torch.float32) + 0.5) * dt
            live = live & (t < t1)
            idx = live.nonzero().squeeze(1)
            if len(idx) == 0:
                break
            x = ro[idx] + rd[idx] * t[idx, None]
            out = network(x)
            c, sigma = out[:, :12], (out[:, 12] - floor).clamp_min(0.0) * scale
            yy = y[idx]
            z = yy[:, 0:1] * c[:, 0:3] + yy[:, 1:2] * c[:, 3:6] + yy[:, 2:3] * c[:, 6:9] + yy[:, 3:4] * c[:, 9:12]
            rgb = 1.0 / (1.0 + torch.exp(-z))
            alpha = 1.0 - torch.exp(-sigma * dt)
            tr = trans[idx]
            colour[idx] += (tr * alpha)[:, None] * rgb
            trans[idx] = tr * (1.0 - alpha)
            live[idx] = trans[idx] >= stop
    bg = torch.tensor(background, dtype=torch.float32)
    rgb = colour + trans[:, None] * bg
    rgba = torch.cat([rgb, torch.ones(len(rgb), 1)], -1)
    return rgba.reshape(height, width, 4).numpy()


def graph_network(graph):
    """A GraphModule as the march's network (no grad)."""
    def fn(x):
        with torch.no_grad():
            return graph(x)
    return fn
