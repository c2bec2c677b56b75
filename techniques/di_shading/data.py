"""The training data of the end-to-end DI shading pipeline (train.py): the plane's pixels seen by
random grazing fly cameras, their uv derivatives as the GPU forms them, the samples' proxy targets and
appearance-filtered references, the seeded batches, and the bricks material.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from inshade.models import footprint_sampler as fp
from inshade.models import pbr_lanes

from .model import Geometry, ShadingError, plane_geometry, reference

VIEW_SIZE = (512, 256)


def plane_camera(rng: np.random.Generator) -> dict:
    """A grazing fly camera over the plane, looking roughly towards the light (-z)."""
    return {"type": "fly", "position": [float(rng.uniform(-4, 4)), float(rng.uniform(0.12, 0.7)),
                                        float(rng.uniform(-1.0, 3.0))],
            "yaw": float(rng.uniform(-30, 30)), "pitch": float(rng.uniform(-22, -3)), "fov_y": 50.0,
            "near": 0.05, "far": 100.0}


def pixel_rays(camera: dict, width: int, height: int):
    """(eye [3], directions [H, W, 3]) as lib/camera camera_ray, image orientation (row 0 = top)."""
    from inshade.models.sdf import camera_rays
    from inshade.scene.camera import camera_from_dict

    u = camera_from_dict(camera).uniforms(width, height)
    ro, rd = camera_rays(u, width, height)
    return torch.tensor(u["u_eye"], dtype=torch.float32), rd.reshape(height, width, 3)


def plane_pixels(camera: dict, width: int, height: int, tile: float = fp.TILE, extent: float = fp.EXTENT):
    """Per pixel of a view: uv (tiled), duv/dx, duv/dy (neighbour differences, as dFdx / dFdy),
    world hit point and hit mask; [H, W, ...]."""
    eye, rd = pixel_rays(camera, width, height)
    t = eye[1] / torch.clamp(-rd[..., 1], min=1e-6)
    p = eye + rd * t[..., None]
    hit = (eye[1] > 0) & (rd[..., 1] < 0) & (torch.maximum(p[..., 0].abs(), p[..., 2].abs()) <= extent)
    uv = torch.stack([p[..., 0], -p[..., 2]], -1) / tile
    # dFdx / dFdy as llvmpipe forms them on 2x2 quads: dx = uv(x0 + 1) - uv(x0) on the pixel's row,
    # x0 = x - x % 2; dy = uv(y0 + 1) - uv(y0) on its column, y0 = y - y % 2 (GL window y, up)
    x = torch.arange(width)
    x0 = torch.clamp(x - x % 2, max=width - 2)
    dx = uv[:, x0 + 1] - uv[:, x0]
    y = height - 1 - torch.arange(height)                   # GL y of each image row
    y0 = torch.clamp(y - y % 2, max=height - 2)
    dy = uv[height - 1 - (y0 + 1)] - uv[height - 1 - y0]
    return uv, dx, dy, p, hit, eye


@dataclass
class Samples:
    x: torch.Tensor          # [N, 3] (fract uv, log2 footprint): the sampler's input
    proxy: torch.Tensor      # [N, 8] emulated trilinear lanes
    ref: torch.Tensor        # [N, 3] appearance-filtered reference, linear
    geo: Geometry

    def index(self, idx):
        return Samples(self.x[idx], self.proxy[idx], self.ref[idx], self.geo.index(idx))


def log2_footprint(dx, dy):
    """lib/footprint footprint_log2: 0.5 log2(max(|dx|^2, |dy|^2))."""
    return 0.5 * torch.log2(torch.clamp(torch.maximum((dx * dx).sum(-1), (dy * dy).sum(-1)), min=1e-30))


def plane_samples(chain, n: int, views: int, seed: int, size=VIEW_SIZE) -> Samples:
    """n hit pixels drawn uniformly from `views` random grazing views (`plane_camera`) at `size`,
    with their proxy targets and appearance-filtered references (computed once): `plane_draw` on
    the CPU (a numpy generator: the same pixels on every device), then `plane_targets` on the
    device `chain` lives on."""
    return plane_targets(chain, plane_draw(n, views, seed, size))


def plane_draw(n: int, views: int, seed: int, size=VIEW_SIZE) -> dict:
    """The pixels of `plane_samples`, on the CPU: {uv (tiled), dx, dy, p, eye} [n, ...]."""
    rng = np.random.default_rng(seed)
    cols = {k: [] for k in ("uv", "dx", "dy", "p", "eye")}
    per = -(-n // views)
    for _ in range(views):
        uv, dx, dy, p, hit, eye = plane_pixels(plane_camera(rng), *size)
        # keep pixels whose footprint is finite (a neighbour off the plane gives a huge one)
        ok = hit & torch.isfinite(log2_footprint(dx, dy)) & (log2_footprint(dx, dy) < 2.0)
        idx = torch.nonzero(ok.reshape(-1))[:, 0]
        pick = idx[torch.from_numpy(rng.choice(len(idx), min(per, len(idx)), replace=False))]
        for k, v in (("uv", uv), ("dx", dx), ("dy", dy), ("p", p)):
            cols[k].append(v.reshape(-1, v.shape[-1])[pick])
        cols["eye"].append(eye.expand(len(pick), 3))
    return {k: torch.cat(v)[:n] for k, v in cols.items()}


def plane_targets(chain, pixels: dict) -> Samples:
    """`plane_draw`'s pixels -> Samples: footprints, geometry, references and proxies, computed on
    the device `chain` lives on (the pixels are moved there)."""
    c = {k: v.to(chain[0].device) for k, v in pixels.items()}
    lf = log2_footprint(c["dx"], c["dy"])
    geo = plane_geometry(c["p"], c["eye"])
    uv = c["uv"] - torch.floor(c["uv"])
    out_ref = []
    with torch.no_grad():
        for s in range(0, len(uv), 16384):
            sl = slice(s, s + 16384)
            out_ref.append(reference(chain, uv[sl], c["dx"][sl], c["dy"][sl], lf[sl], geo.index(sl)))
        proxy = fp.emulated_trilinear(chain, uv, lf)
    return Samples(torch.cat([uv, lf[:, None]], -1), proxy, torch.cat(out_ref), geo)


def batches(data: Samples, batch: int, seed: int):
    """Endless batches of `data`: indices drawn on a seeded CPU generator (the same batches on every
    device), gathered on the device `data` lives on."""
    gen = torch.Generator().manual_seed(seed)
    while True:
        yield data.index(torch.randint(0, len(data.x), (batch,), generator=gen).to(data.x.device))


def material(size: int) -> np.ndarray:
    """The bricks set [N, N, 8] (sRGB albedo, normal, roughness, AO), row 0 = top."""
    if size < 32 or size & (size - 1):
        raise ShadingError(f"size: {size} must be a power of two >= 32 (a full mip chain; bricks courses)")
    return pbr_lanes.bricks(size)
