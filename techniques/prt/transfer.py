"""Ground-truth transfer for the learnt-transfer network (Learnt Transfer, Dhawal et al. 2022): surface samples and
T_k(p, n) = integral V(p, w) max(0, w.n) y_k(w) dw by casting visibility rays.

The estimator's ray directions and their SH projection: techniques/prt/transfer_directions.py; the
surface samples: transfer_surface.py; the input checks and ``TransferError``: transfer_inputs.py; a
dataset's bound, digest and file: transfer_dataset.py. This module casts the rays and builds datasets.

Visibility:

- SDFs (any module with ``__call__(p[N, 3]) -> d[N]`` and ``.scene.trace/.center/.radius``):
  shadow rays start at ``p + n * offset`` (``offset = OFFSET_EPS * hit_eps``), are sphere traced
  with the scene's ``step_scale`` and ``hit_eps``; ``d < hit_eps`` is occluded, leaving the bound
  sphere is unoccluded, and a ray still undecided after ``max_steps`` (``SHADOW_STEPS`` by
  default: grazing rays creep along a surface) counts as unoccluded, as the shader's primary
  trace treats it as a miss (on sdf_creature 160 steps vs 1000 changes the diffuse shading by
  70 dB PSNR; 96 steps: 62 dB). Active-set compaction: only undecided rays are evaluated each step,
  in batches of ~1M rays (fastest measured: per-call overhead dominates smaller batches).
- meshes (``trimesh.Trimesh``): ``mesh.ray.intersects_any`` (embree when ``trimesh.ray.has_embree``)
  from ``p + n * offset`` (``offset = MESH_OFFSET * bounding-box diagonal``).

``build_dataset`` caches (safetensors, keyed by a hash of geometry + settings) and records the
measured throughput (``rays_per_second``) in the dataset's metadata.

Devices: ``device`` (a torch.device or its name, default the CPU) is where SDF evaluation runs --
the marching-cubes grid, the Newton projection and the shadow-ray sphere tracing. Random numbers
are drawn on CPU generators and the transfer is projected and returned on the CPU, so a seed gives
the same directions on every device and the CPU result does not depend on this option. Mesh
visibility is embree's (CPU) whatever the device.
"""
from __future__ import annotations

import hashlib
import json
import shutil
import time
import warnings
from pathlib import Path

import numpy as np
import torch

from inshade.techniques.prt.transfer_dataset import geometry_bound, geometry_digest, load_dataset, save_dataset
from inshade.techniques.prt.transfer_directions import (DEGREE, chunk_generator, hemisphere_directions,
                                                        project_visibility)
from inshade.techniques.prt.transfer_inputs import (TransferError, check_count, check_mesh, check_points, check_sdf,
                                                    is_mesh)
from inshade.techniques.prt.transfer_surface import sample_mesh_surface, sample_sdf_surface, sdf_on_device

VERSION = 1                 # of the estimator; part of the cache key
OFFSET_EPS = 4.0            # SDF shadow-ray origin offset, in units of the scene's hit_eps
# SDF shadow-ray schemes: (origin offset, hit threshold), both in units of the scene's hit_eps.
# "offset4" (the default, what built the shipped assets): offset OFFSET_EPS, threshold 1 -- slots
# narrower than ~2 hit_eps are closed and rays grazing a concave crease stop early. "fine": offset
# 1/2, threshold 1/8 -- against a reference trace (offset 0.1, threshold 0.01, step scale 0.5) the
# diffuse shading of prt_mechanical's samples moves from 50.8 dB (46.5 near occluders) to 62.9 dB
# (61.5) PSNR, at ~2.5x the trace time (techniques/prt/thin.py shadow_study, docs/bench/prt_thin.md).
SHADOW_SCHEMES = {"offset4": (OFFSET_EPS, 1.0), "fine": (0.5, 0.125)}
DEFAULT_SHADOW = "offset4"
SHADOW_STEPS = 160          # SDF shadow-ray step cap
MESH_OFFSET = 1e-4          # mesh shadow-ray origin offset, fraction of the bounding-box diagonal
HOLDOUT_DIRS = 1024        # rays per held-out sample (the reference the network is measured against)
# near-occluder training samples (``build_dataset(near_points=...)``, SDFs): drawn with density ~ 1 +
# NEAR_BOOST x near_occluders.occluder_proximity at NEAR_DELTA x the bound radius, from their own seed
# (seed + NEAR_SEED), added to the uniform training samples; the held-out samples stay uniform
NEAR_BOOST = 3.0
NEAR_DELTA = 0.03
NEAR_SEED = 1_000_003
CHUNK_RAYS = 1 << 20        # rays per batch (memory ~100 bytes/ray at peak)


def _bar(total, desc, progress, unit="ray"):
    from inshade.progress import progress as progress_bar

    # tqdm on a TTY, a line every ~30 s off it; progress=False: silent
    return progress_bar(total=total, desc=desc, unit=unit, unit_scale=True, enabled=progress)


# ---------------------------------------------------------------------------------------------
# SDFs

def shadow_trace(sdf, o: torch.Tensor, d: torch.Tensor, center: torch.Tensor, radius: float,
                 step_scale: float, hit_eps: float, max_steps: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(occluded [R], undecided [R]) bools for rays o + t d (unit d), with active-set compaction;
    undecided rays ran out of steps before a hit or the bounding sphere's exit (not occluded)."""
    oc = o - center
    b = (oc * d).sum(-1)
    h = b * b - ((oc * oc).sum(-1) - radius * radius)
    t1 = torch.where(h > 0, -b + torch.sqrt(h.clamp_min(0.0)), torch.zeros_like(b))
    occluded = torch.zeros(o.shape[0], dtype=torch.bool, device=o.device)
    idx = (t1 > 0).nonzero().squeeze(1)
    o, d, t1 = o[idx], d[idx], t1[idx]
    t = torch.zeros_like(t1)
    for _ in range(max_steps):
        if idx.numel() == 0:
            break
        dist = sdf(o + d * t[:, None])
        hit = dist < hit_eps
        occluded[idx[hit]] = True
        t = t + dist * step_scale
        go = ~hit & (t <= t1)
        if not bool(go.all()):
            idx, o, d, t, t1 = idx[go], o[go], d[go], t[go], t1[go]
    undecided = torch.zeros_like(occluded)
    undecided[idx] = True
    return occluded, undecided


def _transfer(p, nrm, n_dirs: int, seed: int, start: int, chunk_rays: int, offset: float, occluded, desc: str,
              progress) -> torch.Tensor:
    """Transfer [N, 16] at points p with normals nrm, ``chunk_rays`` rays at a time: hemisphere
    directions from the chunk's random stream (CPU draws), shadow rays from p + offset n, and
    ``occluded(origins [R, 3], dirs [R, 3])`` -> CPU bool [R] for the geometry's own ray test."""
    per = max(1, chunk_rays // n_dirs)
    gen = chunk_generator(seed, start, per)
    out = torch.empty(p.shape[0], DEGREE * DEGREE)
    with torch.no_grad(), _bar(p.shape[0] * n_dirs, desc, progress) as bar:
        for i in range(0, p.shape[0], per):
            pc, nc = p[i:i + per], nrm[i:i + per]
            dirs = hemisphere_directions(nc, n_dirs, gen)                    # [n, D, 3]
            o = (pc + nc * offset)[:, None].expand_as(dirs).reshape(-1, 3)
            occ = occluded(o, dirs.reshape(-1, 3))
            out[i:i + per] = project_visibility(~occ.reshape(dirs.shape[:2]), dirs)
            bar.update(dirs.shape[0] * n_dirs)
    return out


def sdf_transfer(sdf, p, nrm, n_dirs: int = 256, seed: int = 0, progress: bool | None = False,
                 max_steps: int | None = None, chunk_rays: int = CHUNK_RAYS, device="cpu",
                 start: int = 0, shadow: str = DEFAULT_SHADOW) -> torch.Tensor:
    """Ground-truth transfer [N, 16] float32 (on the CPU) at points p [N, 3] with normals nrm [N, 3]
    (any points: surface samples or G-buffer hits) of an SDF module, the shadow rays traced on
    ``device``; see the module docstring. ``start``: these points follow ``start`` others of the
    same estimate (a shard, see ``chunk_generator``). ``shadow``: a ``SHADOW_SCHEMES`` name."""
    scene = check_sdf(sdf)
    device = torch.device(device)
    sdf = sdf_on_device(sdf, device)
    p, nrm = check_points(p, nrm)
    n_dirs = check_count(n_dirs, "n_dirs")
    if shadow not in SHADOW_SCHEMES:
        raise TransferError(f"shadow: must be one of {list(SHADOW_SCHEMES)}, got {shadow!r}")
    tr = scene.trace
    hit_eps, step_scale = float(tr["hit_eps"]), float(tr["step_scale"])
    steps = int(max_steps if max_steps is not None else max(SHADOW_STEPS, int(tr["max_steps"])))
    offset, threshold = (k * hit_eps for k in SHADOW_SCHEMES[shadow])
    center = torch.tensor(scene.center, dtype=torch.float32, device=device)
    radius = float(scene.radius)

    def occluded(o, d):
        return shadow_trace(sdf, o.to(device), d.to(device), center, radius, step_scale, threshold, steps)[0].cpu()

    return _transfer(p, nrm, n_dirs, seed, start, chunk_rays, offset, occluded, "transfer (sdf)", progress)


# ---------------------------------------------------------------------------------------------
# meshes

def mesh_transfer(mesh, p, nrm, n_dirs: int = 256, seed: int = 0, progress: bool | None = False,
                  chunk_rays: int = CHUNK_RAYS, start: int = 0) -> torch.Tensor:
    """Ground-truth transfer [N, 16] float32 at points p [N, 3] with normals nrm [N, 3] of a
    trimesh.Trimesh, by ``mesh.ray.intersects_any`` (embree when available). ``start``: as in
    ``sdf_transfer``."""
    import trimesh

    mesh = check_mesh(mesh)
    p, nrm = check_points(p, nrm)
    n_dirs = check_count(n_dirs, "n_dirs")
    if not trimesh.ray.has_embree:
        warnings.warn("embreex is not installed: trimesh falls back to its pure-Python ray caster, "
                      "which is ~100x slower (pip install embreex)", stacklevel=2)
    offset = MESH_OFFSET * float(np.linalg.norm(mesh.extents))

    def occluded(o, d):
        return torch.from_numpy(np.asarray(mesh.ray.intersects_any(o.numpy().astype(np.float64),
                                                                   d.numpy().astype(np.float64)), bool))

    return _transfer(p, nrm, n_dirs, seed, start, chunk_rays, offset, occluded, "transfer (mesh)", progress)


# ---------------------------------------------------------------------------------------------
# datasets

def build_dataset(geometry, n_points: int, n_dirs: int = 256, cache_dir=None, seed: int = 0,
                  progress: bool | None = None, holdout: int | None = None,
                  holdout_dirs: int = HOLDOUT_DIRS, device="cpu", executor=None,
                  chunk_rays: int = CHUNK_RAYS, shadow: str = DEFAULT_SHADOW, near_points: int = 0) -> dict:
    """Surface samples + ground-truth transfer of an SDF module or a trimesh.Trimesh.

    Returns {"position" [N, 3], "normal" [N, 3], "transfer" [N, 16] (float32 tensors; the training
    set), "heldout_position" / "heldout_normal" / "heldout_transfer" [M, ...] (``holdout`` further
    samples, default min(2000, N/20), whose transfer is cast with ``holdout_dirs`` rays so that the
    held-out error measures the network, not the estimator's noise: at 128 rays the estimate alone
    is only ~46 dB diffuse PSNR from a 2048-ray one), "center", "radius" (the bound), "n_points",
    "n_dirs", "n_heldout", "heldout_dirs", "seed", "kind" ("sdf" | "mesh"), "key" (cache key),
    "seconds" (sampling + rays), "ray_seconds", "rays" (all, held-out included),
    "rays_per_second", "cached" (bool)}. With ``cache_dir`` the result is stored as
    ``transfer-<key>.safetensors`` and read back on a later call with the same geometry and
    settings (seconds/throughput are then the original run's).

    The rays are a sharded bake (models/bake.py; ``executor``: in-process by default, a process
    pool or Ray): one shard per chunk of ``chunk_rays`` rays, cached in ``transfer-<key>.shards/``
    while the bake runs (a rerun resumes there; removed once the dataset is written). The shards
    replay the unsharded estimate's random stream (``chunk_generator``), so the data is bit-identical
    whatever the executor and to an unsharded run. ``shadow``: the SDF shadow-ray scheme
    (``SHADOW_SCHEMES``; part of the cache key unless it is the default). ``near_points`` (SDFs):
    that many further training samples drawn near occluders (``NEAR_BOOST``, ``NEAR_DELTA``:
    contact shadows, slots, parts resting on a plate, where the transfer changes fastest and the
    network's error concentrates), cast with ``n_dirs`` rays and appended to the training set
    (``n_near`` in the result; part of the cache key when > 0); the held-out samples stay the
    uniform ones, so held-out metrics compare with a uniform dataset's."""
    mesh = is_mesh(geometry)
    if not mesh:
        check_sdf(geometry)
    n_points = check_count(n_points, "n_points")
    n_dirs = check_count(n_dirs, "n_dirs")
    holdout = min(2000, max(1, n_points // 20)) if holdout is None else check_count(holdout, "holdout")
    holdout_dirs = check_count(holdout_dirs, "holdout_dirs")
    settings, near_points, device = _cache_settings(mesh, n_points, n_dirs, seed, holdout, holdout_dirs, shadow,
                                                    near_points, device)
    key = hashlib.sha256((geometry_digest(geometry) + json.dumps(settings, sort_keys=True)).encode()).hexdigest()[:24]
    path = Path(cache_dir) / f"transfer-{key}.safetensors" if cache_dir is not None else None
    if path is not None and path.is_file():
        data = load_dataset(path)
        if data.get("key") == key:
            data["cached"] = True
            return data
    shard_dir = Path(cache_dir) / f"transfer-{key}.shards" if cache_dir is not None else None
    data = _bake_dataset(geometry, mesh, key, n_points=n_points, n_dirs=n_dirs, holdout=holdout,
                         holdout_dirs=holdout_dirs, near_points=near_points, seed=seed, device=device,
                         executor=executor, chunk_rays=chunk_rays, shadow=shadow, shard_dir=shard_dir,
                         progress=progress)
    if path is not None:
        save_dataset(data, path)
        shutil.rmtree(shard_dir, ignore_errors=True)    # the dataset file holds them all now
    return data


def _cache_settings(mesh: bool, n_points: int, n_dirs: int, seed, holdout: int, holdout_dirs: int, shadow: str,
                    near_points, device) -> tuple[dict, int, torch.device]:
    """The settings that ``build_dataset``'s cache key hashes with the geometry, once ``shadow`` and
    ``near_points`` are checked; with near_points (0 for None) and device (a torch.device)."""
    settings = {"version": VERSION, "n_points": n_points, "n_dirs": n_dirs, "seed": int(seed),
                "holdout": holdout, "holdout_dirs": holdout_dirs,
                "offset": MESH_OFFSET if mesh else OFFSET_EPS, "shadow_steps": SHADOW_STEPS}
    if shadow not in SHADOW_SCHEMES:
        raise TransferError(f"shadow: must be one of {list(SHADOW_SCHEMES)}, got {shadow!r}")
    if shadow != DEFAULT_SHADOW and not mesh:
        settings["shadow"] = shadow
    near_points = 0 if near_points is None else int(near_points)
    if near_points:
        check_count(near_points, "near_points")
        if mesh:
            raise TransferError("near_points: near-occluder samples need an SDF (the proximity is a distance query)")
        settings.update({"near_points": near_points, "near_boost": NEAR_BOOST, "near_delta": NEAR_DELTA})
    # SDF data traced on a GPU may differ from the CPU's in the last bits: its own cache entry (the
    # CPU keys stay as they were; mesh rays are embree's on every device)
    device = torch.device(device)
    if device.type != "cpu" and not mesh:
        settings["device"] = device.type
    return settings, near_points, device


def _bake_dataset(geometry, mesh: bool, key: str, *, n_points: int, n_dirs: int, holdout: int, holdout_dirs: int,
                  near_points: int, seed, device: torch.device, executor, chunk_rays: int, shadow: str,
                  shard_dir: Path | None, progress) -> dict:
    """``build_dataset``'s dict, computed: the surface samples (training, held-out, then the near-occluder
    ones), their rays cast as a sharded bake, and the throughput."""
    from inshade.models.bake import IN_PROCESS

    executor = executor or IN_PROCESS
    center, radius = geometry_bound(geometry)
    start = time.perf_counter()
    total = n_points + holdout
    source = geometry                               # as given (CPU): what other processes receive
    if mesh:
        p, nrm = sample_mesh_surface(geometry, total, seed)
    else:
        geometry = sdf_on_device(geometry, device)     # moved once for sampling and rays
        p, nrm = sample_sdf_surface(geometry, total, seed, device=device)
    sets = [("train", p[:n_points], nrm[:n_points], n_dirs, seed),
            ("heldout", p[n_points:], nrm[n_points:], holdout_dirs, seed + 1)]
    if near_points:
        from inshade.techniques.prt.near_occluders import sample_near_occluders

        p_near, n_near = sample_near_occluders(geometry, near_points, seed=seed + NEAR_SEED, boost=NEAR_BOOST,
                                               delta=NEAR_DELTA * radius, device=device)
        sets.append(("near", p_near, n_near, n_dirs, seed + 2))
    ray_start = time.perf_counter()
    rays = (n_points + near_points) * n_dirs + holdout * holdout_dirs
    transfer, held = _cast_rays(sets, source, geometry, mesh, device, executor, chunk_rays, shadow, shard_dir, rays,
                                progress)
    end = time.perf_counter()
    train_p, train_n = p[:n_points], nrm[:n_points]
    if near_points:
        train_p, train_n = torch.cat([train_p, p_near]), torch.cat([train_n, n_near])
    return {"position": train_p.contiguous(), "normal": train_n.contiguous(), "transfer": transfer,
            "heldout_position": p[n_points:].contiguous(), "heldout_normal": nrm[n_points:].contiguous(),
            "heldout_transfer": held, "center": list(center), "radius": radius,
            "n_points": n_points, "n_near": near_points, "n_dirs": n_dirs, "n_heldout": holdout,
            "heldout_dirs": holdout_dirs,
            "seed": int(seed), "kind": "mesh" if mesh else "sdf",
            "key": key, "seconds": round(end - start, 3), "ray_seconds": round(end - ray_start, 3),
            "rays": rays, "rays_per_second": round(rays / max(end - ray_start, 1e-9), 1),
            "embree": bool(mesh and _has_embree()), "torch_threads": torch.get_num_threads(),
            "device": "cpu" if mesh else str(device),
            "cached": False}


def _cast_rays(sets: list, source, geometry, mesh: bool, device: torch.device, executor, chunk_rays: int,
               shadow: str, shard_dir: Path | None, rays: int, progress) -> tuple[torch.Tensor, torch.Tensor]:
    """The transfer of every (name, points, normals, n_dirs, seed) set, one ``transfer_shard`` per chunk run by
    ``executor``: (training then near-occluder transfer, held-out transfer)."""
    from inshade.models.bake import run_shards

    # a GPU worker of Ray sees only the GPU it was given, as cuda:0
    worker_device = "cuda" if executor.kind == "ray" and device.type == "cuda" else str(device)
    common = {"geometry": source if executor.remote else geometry, "mesh": mesh,
              "device": worker_device if executor.remote else device, "threads": torch.get_num_threads(),
              "chunk_rays": int(chunk_rays), "shadow": shadow}
    shards = transfer_shards(sets, chunk_rays, num_gpus=0.0 if mesh or device.type == "cpu" else 1.0)
    with _bar(rays, "transfer rays", progress) as bar:
        results = run_shards(transfer_shard, shards, common, shard_dir, executor,
                             on_done=lambda s: bar.update(s.args["points"].shape[0] * s.args["n_dirs"]))
    # copies: Ray hands back read-only arrays
    parts = {name: [torch.tensor(r["transfer"]) for s, r in zip(shards, results) if s.args["set"] == name]
             for name, *_ in sets}
    return torch.cat(parts["train"] + parts.get("near", [])), torch.cat(parts["heldout"])


def transfer_shards(sets, chunk_rays: int = CHUNK_RAYS, num_gpus: float = 0.0) -> list:
    """One ``inshade.models.bake.Shard`` per chunk of each (name, points, normals, n_dirs, seed) set, in
    order; a shard's args carry its points, normals and offset into the set (``start``)."""
    from inshade.models.bake import Shard

    shards = []
    for name, p, nrm, n_dirs, seed in sets:
        per = max(1, int(chunk_rays) // n_dirs)
        for i in range(0, p.shape[0], per):
            shards.append(Shard(f"{name}-{i // per:05d}", {
                "set": name, "start": i, "n_dirs": int(n_dirs), "seed": int(seed),
                "points": p[i:i + per].numpy(), "normals": nrm[i:i + per].numpy()}, num_gpus))
    return shards


def transfer_shard(common: dict, args: dict) -> dict:
    """The bake function of ``build_dataset`` (runs in any process): {"transfer": [n, 16] float32}
    of one shard. Torch's thread count is the driver's, so worker results match in-process ones."""
    if common["threads"] > 0:
        torch.set_num_threads(common["threads"])
    p, nrm = torch.from_numpy(args["points"]), torch.from_numpy(args["normals"])
    kw = dict(n_dirs=args["n_dirs"], seed=args["seed"], start=args["start"], chunk_rays=common["chunk_rays"])
    if common["mesh"]:
        out = mesh_transfer(common["geometry"], p, nrm, **kw)
    else:
        out = sdf_transfer(common["geometry"], p, nrm, device=common["device"],
                           shadow=common.get("shadow", DEFAULT_SHADOW), **kw)
    return {"transfer": out.numpy()}


def _has_embree() -> bool:
    import trimesh

    return bool(trimesh.ray.has_embree)
