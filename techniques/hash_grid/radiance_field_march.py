"""The radiance field's march in torch: the twin of shaders/lib/radiance_field_march.glsl (same
steps, same order, float32), and the batched form training composites with.

Per pixel (the pixel-centre ray of lib/camera's camera_ray; models/sdf.py camera_rays):
 1. into the box: ro = (eye - aabb.min) * (1 / side), rd unchanged; unit box entry t0 >= 0, exit
    t1 (models/unit_box.py); missed: the background;
 2. i = 0; for n < max_steps: stop when i >= max_steps; t = t0 + (i + 0.5) dt; stop when t >= t1;
    x = ro + rd t;
    - skipping (empty_space "skip"): cell c = clamp(floor(x G), 0, G - 1); if its bit is 0, leave the
      cell: t_exit = the cell's far slab along the ray, i = max(i + 1, floor((t_exit - t0) / dt - 0.5))
      -- the last sample before the exit: every sample passed over is at least dt inside the empty
      cell, whatever the rounding, and the landing one is tested again -- and go on;
    - (density, rgb) = field(x, rd); alpha = 1 - exp(-density sigma_scale dt);
      C += T alpha rgb; T *= 1 - alpha; i += 1; stop once T < STOP;
 3. colour = C + T background.
So a sample in an unoccupied cell contributes nothing and costs no network evaluation; with
"evaluate" every sample is evaluated (the comparison that shows what the grid drops).

Training (``candidates``, ``composite``): the same sample positions of a batch of rays, the
occupied ones packed per ray in order, composited as C = sum_k T_k alpha_k rgb_k + T_end background
with T_k = exp(-sum_{j<k} sigma_j dt) (the same product), samples after T < STOP left out.
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.models.sdf import camera_rays
from inshade.models.unit_box import TINY, unit_box

from .radiance_field_render import MarchSettings


def f32(v) -> torch.Tensor:
    return torch.tensor(v, dtype=torch.float32)


def box_rays(uniforms: dict, width: int, height: int, m: MarchSettings):
    """(ro [P, 3] in box units, rd [P, 3] unit) of a camera's pixels, row 0 = top."""
    ro, rd = camera_rays(uniforms, width, height)
    return (ro - torch.tensor(m.aabb_min, dtype=torch.float32)) * f32(m.inv_side), rd


def _cell_exit(ro, rd, cell, res: int):
    """t where the ray leaves the cell ``cell`` [P, 3] (int) of a res^3 grid (its far slabs)."""
    size = f32(np.float32(1.0) / np.float32(res))
    lo = cell.float() * size
    hi = (cell + 1).float() * size
    inv = 1.0 / torch.where(rd.abs() < TINY, f32(TINY), rd)
    a, b = (lo - ro) * inv, (hi - ro) * inv
    far = torch.maximum(a, b)
    return torch.minimum(far[:, 0], torch.minimum(far[:, 1], far[:, 2]))


def cells_of(x: torch.Tensor, res: int) -> torch.Tensor:
    return torch.floor(x * float(res)).long().clamp(0, res - 1)


def march(field, occupancy: torch.Tensor | None, ro: torch.Tensor, rd: torch.Tensor, m: MarchSettings):
    """(rgb [P, 3], evaluations [P] int) of rays in box units. ``field(x, d) -> (density [Q],
    rgb [Q, 3])``; ``occupancy`` a bool [G, G, G] ([k, j, i]) grid, None: evaluate every sample."""
    hit, t0, t1 = unit_box(ro, rd)
    dt, inv_dt = f32(m.step), f32(np.float32(1.0) / np.float32(m.step))
    scale = f32(m.sigma_scale)
    res = m.occupancy_resolution
    colour = torch.zeros(len(ro), 3)
    trans = torch.ones(len(ro))
    evals = torch.zeros(len(ro), dtype=torch.long)
    index = torch.zeros(len(ro), dtype=torch.long)
    live = hit.clone()
    with torch.no_grad():
        for _ in range(m.max_steps):
            live &= index < m.max_steps
            t = t0 + (index.float() + 0.5) * dt
            live &= t < t1
            idx = live.nonzero().squeeze(1)
            if not len(idx):
                break
            x = ro[idx] + rd[idx] * t[idx, None]
            if occupancy is not None:
                c = cells_of(x, res)
                empty = ~occupancy[c[:, 2], c[:, 1], c[:, 0]]
                if empty.any():
                    e = idx[empty]
                    t_exit = _cell_exit(ro[e], rd[e], c[empty], res)
                    landing = torch.floor((t_exit - t0[e]) * inv_dt - 0.5).long()
                    index[e] = torch.maximum(index[e] + 1, landing)
                    idx, x = idx[~empty], x[~empty]
                    if not len(idx):
                        continue
            density, rgb = field(x, rd[idx])
            alpha = 1.0 - torch.exp(-(density * scale) * dt)
            tr = trans[idx]
            colour[idx] += (tr * alpha)[:, None] * rgb
            trans[idx] = tr * (1.0 - alpha)
            evals[idx] += 1
            index[idx] += 1
            live[idx] = trans[idx] >= m.stop
    return colour + trans[:, None] * torch.tensor(m.background, dtype=torch.float32), evals


def graph_field(graph):
    """A bundle graph (inputs x, d; outputs density, rgb) as the march's field."""
    def field(x, d):
        with torch.no_grad():
            out = graph(torch.cat([x, d], -1))
        return out[:, 0], out[:, 1:4]
    return field


def render(field, occupancy, uniforms: dict, width: int, height: int, m: MarchSettings, chunk: int = 1 << 14):
    """([H, W, 3] linear RGB, [H, W] evaluations) of a camera (row 0 = top)."""
    ro, rd = box_rays(uniforms, width, height, m)
    parts = [march(field, occupancy, ro[s:s + chunk], rd[s:s + chunk], m) for s in range(0, len(ro), chunk)]
    rgb = torch.cat([p[0] for p in parts]).reshape(height, width, 3).numpy()
    return rgb, torch.cat([p[1] for p in parts]).reshape(height, width).numpy()


# --- training ----------------------------------------------------------------------------------------

def candidates(ro: torch.Tensor, rd: torch.Tensor, occupied: torch.Tensor, m: MarchSettings):
    """The occupied sample positions of a batch of rays, packed per ray in march order:
    (x [R, K, 3], valid [R, K] bool), K the most any ray has."""
    hit, t0, t1 = unit_box(ro, rd)
    steps = torch.arange(m.max_steps, dtype=torch.float32)
    t = t0[:, None] + (steps[None] + 0.5) * f32(m.step)                # [R, S]
    inside = hit[:, None] & (t < t1[:, None])
    x = ro[:, None] + rd[:, None] * t[..., None]
    c = cells_of(x, m.occupancy_resolution)
    keep = inside & occupied[c[..., 2], c[..., 1], c[..., 0]]
    count = keep.sum(1)
    k = max(int(count.max()), 1) if len(count) else 1
    rank = keep.cumsum(1) - 1
    r, s = keep.nonzero(as_tuple=True)
    packed = torch.zeros(len(ro), k, 3)
    packed[r, rank[r, s]] = x[r, s]
    valid = torch.arange(k)[None] < count[:, None]
    return packed, valid


def transmittance(sigma_dt: torch.Tensor) -> torch.Tensor:
    """T before each sample [R, K] of optical depths sigma dt [R, K] (exclusive cumulative sum)."""
    depth = torch.cumsum(sigma_dt, 1)
    return torch.exp(-torch.cat([torch.zeros_like(depth[:, :1]), depth[:, :-1]], 1))


def composite(sigma_dt: torch.Tensor, rgb: torch.Tensor, background: torch.Tensor) -> torch.Tensor:
    """[R, 3] colour of packed samples (sigma dt [R, K], rgb [R, K, 3]; padding has sigma dt 0)."""
    trans = transmittance(sigma_dt)
    weight = trans * (1.0 - torch.exp(-sigma_dt))
    end = trans[:, -1] * torch.exp(-sigma_dt[:, -1])
    return (weight[..., None] * rgb).sum(1) + end[:, None] * background
