"""Ground-truth transfer data of a large SDF scene for sub-scene PRT (Learnt Transfer, Dhawal et al. 2022 §4.4).

``scene_dataset(sdf, points, dirs, ...)``: area-weighted surface samples of the WHOLE scene
(``transfer_surface.sample_sdf_surface`` at a marching-cubes ``resolution`` fine enough for the scene's
thin parts: the atrium's banners are 0.16 thick, so 256 over its 21-unit bound), their transfer
cast against the whole scene (``transfer.sdf_transfer``: visibility is never cut at a region
boundary), and ``holdout`` further samples cast with ``holdout_dirs`` rays (the reference the
networks are measured against). The region split (regions.py) only filters these points, so
every region network, the one-network baselines and the merge statistics share one bake.

Cached as ``transfer_dataset.save_dataset`` files keyed by the geometry digest and the settings.
"""
from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import torch

from inshade.techniques.prt import transfer, transfer_dataset, transfer_inputs, transfer_surface

VERSION = 1


def scene_dataset(sdf, points: int, dirs: int, holdout: int = 3000, holdout_dirs: int = 512, seed: int = 0,
                  resolution: int = 256, cache=None, progress: bool | None = None) -> dict:
    """The dataset dict of ``transfer.build_dataset`` (same keys) for ``sdf`` (an SDF module)."""
    for name, v in (("points", points), ("dirs", dirs), ("holdout", holdout), ("holdout_dirs", holdout_dirs),
                    ("resolution", resolution)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise transfer_inputs.TransferError(f"{name}: must be a positive int, got {v!r}")
    settings = {"version": VERSION, "estimator": transfer.VERSION, "points": points, "dirs": dirs,
                "holdout": holdout, "holdout_dirs": holdout_dirs, "seed": seed, "resolution": resolution,
                "offset": transfer.OFFSET_EPS, "shadow_steps": transfer.SHADOW_STEPS}
    text = transfer_dataset.geometry_digest(sdf) + json.dumps(settings, sort_keys=True)
    key = hashlib.sha256(text.encode()).hexdigest()[:24]
    path = Path(cache) / f"regions-{key}.safetensors" if cache is not None else None
    if path is not None and path.is_file():
        data = transfer_dataset.load_dataset(path)
        if data.get("key") == key:
            data["cached"] = True
            return data
    start = time.perf_counter()
    p, n = transfer_surface.sample_sdf_surface(sdf, points + holdout, seed=seed, resolution=resolution)
    ray_start = time.perf_counter()
    t = transfer.sdf_transfer(sdf, p[:points], n[:points], n_dirs=dirs, seed=seed, progress=progress)
    th = transfer.sdf_transfer(sdf, p[points:], n[points:], n_dirs=holdout_dirs, seed=seed + 1, progress=progress)
    end = time.perf_counter()
    center, radius = transfer_dataset.geometry_bound(sdf)
    rays = points * dirs + holdout * holdout_dirs
    data = {"position": p[:points].contiguous(), "normal": n[:points].contiguous(), "transfer": t,
            "heldout_position": p[points:].contiguous(), "heldout_normal": n[points:].contiguous(),
            "heldout_transfer": th, "center": list(center), "radius": radius, "n_points": points,
            "n_dirs": dirs, "n_heldout": holdout, "heldout_dirs": holdout_dirs, "seed": seed, "kind": "sdf",
            "resolution": resolution, "key": key, "seconds": round(end - start, 3),
            "ray_seconds": round(end - ray_start, 3), "rays": rays,
            "rays_per_second": round(rays / max(end - ray_start, 1e-9), 1), "torch_threads": torch.get_num_threads(),
            "cached": False}
    if path is not None:
        transfer_dataset.save_dataset(data, path)
    return data
