"""Per-voxel data of appearance prefiltering: coverage masks, directional albedo and the phase
function, ray cast with embree against the geometry inside each voxel only, sharded through the
bake executor (models/bake.py) by chunks of voxel slots.

For voxel slot n (sphere centre c, radius r, box [lo, hi]) and each of its V views w (stratified
over the sphere, drawn from a generator seeded by (seed, n), so a slot's data does not depend on
the chunking or the executor):

- rays: M*M*rays_per_texel orthographic rays, direction -w, through the plane through c
  perpendicular to w, at (x, y) = ((p - c).t / r, (p - c).b / r) jittered inside each mask
  texel (u, v) = [-1 + 2u/M, -1 + 2(u+1)/M] x [-1 + 2v/M, ...] (texel stratified; within a texel
  a Latin hypercube over the rays). Each ray starts where its line enters the box and stops where
  it leaves: embree casts it against the whole scene with tfar = the box exit, so geometry outside
  the voxel never blocks and every accepted hit lies in the voxel (the triangles clipped to it).
- ``coverage`` [N, V, M, M] ([v][u]): the fraction of a texel's rays that hit.
- ``albedo`` [N, V, 3]: mean base colour of the hitting rays (0 if none).
- ``light_local`` [N, V, B, 3]: one incident direction per phase bin (frame.py), jittered inside
  the bin, in w's view-local frame.
- ``phase`` [N, V, B]: mean over the hitting rays of f_white(w, l, n) max(0, n.l) V_in_voxel(l),
  f_white = brdf_np.brdf with base colour 1 (formula there). n is the hit face's geometric
  normal, turned toward the viewer on two-sided faces; a solid face hit from behind (a ray that
  starts inside a closed solid cut by the box) has f = 0. V_in_voxel: a shadow ray from the hit
  point, offset SHADOW_OFFSET along n (the lit side), toward l, is unblocked when embree finds
  no hit before the ray leaves the box (intra-voxel self-shadowing only; single bounce).
  Radiance = phase * albedo * E_light (DAP Eq. 17); the phase-slice target of bin b is
  phase[..., b] * 4 pi / B.

The BRDF (brdf_np.py; base = 1 here), alpha = max(roughness^2, 1e-3), h = normalize(w + l):
  f = (1 - metallic)/pi (1 + (F_D90 - 1)(1 - n.l)^5)(1 + (F_D90 - 1)(1 - n.w)^5)    Burley diffuse,
      F_D90 = 0.5 + 2 roughness (l.h)^2
    + D G1(n.w) G1(n.l) F / (4 (n.l)(n.w))                                           GGX specular,
      D = alpha^2 / (pi ((alpha^2 - 1)(n.h)^2 + 1)^2), G1(c) = 2c / (c + sqrt(alpha^2 + (1 - alpha^2) c^2)),
      F = F0 + (1 - F0)(1 - l.h)^5, F0 = 0.04 (1 - metallic) + metallic
  and 0 where n.l <= 0 or n.w <= 0.

numpy + embreex (through trimesh's wheel); no torch.
"""
from __future__ import annotations

import hashlib
import json
import math
import time
from pathlib import Path

import numpy as np

from inshade.techniques.appearance_prefilter import frame
from inshade.techniques.appearance_prefilter.brdf_np import brdf

SHADOW_OFFSET = 1e-5    # world units; the unit box's float32 ulp is ~6e-8, thin slabs are ~5e-3
CHUNK = 64              # voxels per shard: ~10^5 primary rays, a few 10^6 shadow rays


class DataError(ValueError):
    """Bad bake settings or voxel arrays; the message names the field."""


# --- geometry helpers ---------------------------------------------------------------------------

def box_interval(origin, direction, lo, hi):
    """Parametric (t_in, t_out) of lines origin + t direction through boxes [lo, hi] (all [..., 3])."""
    d = np.where(np.abs(direction) < 1e-12, 1e-12, direction)
    t0 = (lo - origin) / d
    t1 = (hi - origin) / d
    return np.minimum(t0, t1).max(-1), np.maximum(t0, t1).min(-1)


_SCENES: dict = {}


def _embree(common: dict):
    """The embree scene of the bake's geometry, built once per process."""
    key = common["key"]
    if key not in _SCENES:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        scene = rtcore_scene.EmbreeScene()
        TriangleMesh(scene=scene, vertices=common["vertices"].astype(np.float32),
                     indices=common["faces"].astype(np.int32))
        _SCENES.clear()
        _SCENES[key] = scene
    return _SCENES[key]


def _cast(scene, origin, direction, tfar):
    """First-hit face [R] (-1 = none) and distance [R] of rays limited to tfar."""
    if len(origin) == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    out = scene.run(origin.astype(np.float32), direction.astype(np.float32),
                    dists=tfar.astype(np.float32), output=1)
    return out["primID"].astype(np.int64), out["tfar"].astype(np.float64)


def _occluded(scene, origin, direction, tfar):
    if len(origin) == 0:
        return np.zeros(0, bool)
    return scene.run(origin.astype(np.float32), direction.astype(np.float32),
                     dists=tfar.astype(np.float32), query="OCCLUDED") >= 0


# --- one slot's random numbers ------------------------------------------------------------------

def slot_samples(seed: int, slot: int, views: int, mask: int, bins: tuple[int, int], rpt: int) -> dict:
    """The slot's views and jitters, drawn in a fixed order from default_rng([seed, slot])."""
    rng = np.random.default_rng([int(seed), int(slot)])
    w = frame.stratified_sphere(views, rng.random((views, 2)))
    jitter = rng.random((views, mask, mask, rpt, 2))
    order = np.argsort(rng.random((views, mask, mask, rpt)), -1)   # the Latin hypercube's pairing
    light = frame.jittered_bins(bins[0], bins[1], rng.random((views, bins[0] * bins[1], 2)))
    return {"w": w, "jitter": jitter, "order": order, "light": light}


def _texel_points(s: dict, mask: int, rpt: int):
    """Plane coordinates (x, y) [V, M, M, rpt] of the rays, texel (u, v) at [v][u]."""
    k = np.arange(rpt)
    fx = (k + s["jitter"][..., 0]) / rpt
    fy = (s["order"] + s["jitter"][..., 1]) / rpt
    u = np.arange(mask)[None, None, :, None]
    v = np.arange(mask)[None, :, None, None]
    return -1.0 + 2.0 * (u + fx) / mask, -1.0 + 2.0 * (v + fy) / mask


# --- the bake function ----------------------------------------------------------------------------

def voxel_shard(common: dict, args: dict) -> dict:
    """The contract arrays of one chunk of slots (module level: runs in any process)."""
    st = common["settings"]
    V, M, rpt = st["views"], st["mask"], st["rays_per_texel"]
    bins = tuple(st["bins"])
    B = bins[0] * bins[1]
    cells, spheres = args["cells"], args["spheres"].astype(np.float64)
    slots = np.arange(args["start"], args["start"] + len(cells))
    n = len(cells)
    samples = [slot_samples(st["seed"], s, V, M, bins, rpt) for s in slots]
    w = np.stack([s["w"] for s in samples])                            # [n, V, 3]
    if common.get("fixed_views") is not None:                          # one set for every slot
        w = np.broadcast_to(common["fixed_views"], w.shape).copy()
    light_local = np.stack([s["light"] for s in samples])              # [n, V, B, 3]
    pts = [_texel_points(s, M, rpt) for s in samples]
    px = np.stack([p[0] for p in pts])                                 # [n, V, M, M, rpt]
    py = np.stack([p[1] for p in pts])
    size = 1.0 / (1 << cells[:, 0].astype(np.int64))
    lo = cells[:, 1:4].astype(np.float64) * size[:, None]
    hi = lo + size[:, None]
    t, b, _ = frame.view_frame(w)
    c, r = spheres[:, :3].reshape(n, 1, 1, 1, 1, 3), spheres[:, 3].reshape(n, 1, 1, 1, 1, 1)
    shape = (n, V, M, M, rpt)
    p = (c + r *
         (px[..., None] * t[:, :, None, None, None, :] + py[..., None] * b[:, :, None, None, None, :]))
    d = np.broadcast_to(-w[:, :, None, None, None, :], shape + (3,))
    blo = np.broadcast_to(lo[:, None, None, None, None, :], shape + (3,))
    bhi = np.broadcast_to(hi[:, None, None, None, None, :], shape + (3,))
    t_in, t_out = box_interval(p, d, blo, bhi)
    through = (t_in < t_out).reshape(-1)
    origin = (p + t_in[..., None] * d).reshape(-1, 3)
    face = np.full(through.shape, -1, np.int64)
    dist = np.zeros(through.shape)
    scene = _embree(common)
    face[through], dist[through] = _cast(scene, origin[through], d.reshape(-1, 3)[through],
                                         (t_out - t_in).reshape(-1)[through])
    hit = face >= 0
    coverage = hit.reshape(shape).mean(-1)

    # per hitting ray: its voxel-view (row of [n*V]), the hit point and the viewer-facing normal
    ray_view = np.repeat(np.arange(n * V), M * M * rpt)[hit]
    f_hit = face[hit]
    n_hits = np.bincount(ray_view, minlength=n * V)
    base = common["base_colour"][f_hit].astype(np.float64)
    albedo = np.stack([np.bincount(ray_view, base[:, ch], n * V) for ch in range(3)], 1)
    albedo = albedo / np.maximum(n_hits, 1)[:, None]
    w_ray = w.reshape(-1, 3)[ray_view]
    nrm = common["face_normals"][f_hit]
    facing = (nrm * w_ray).sum(-1)
    nrm = np.where((common["two_sided"][f_hit] & (facing < 0.0))[:, None], -nrm, nrm)
    x = origin[hit] + dist[hit, None] * d.reshape(-1, 3)[hit]

    # shadow rays: every (hit, bin) whose light is on the lit side of a front-facing hit
    l_world = frame.to_world(light_local, w[:, :, None, :]).reshape(n * V, B, 3)
    l_ray = l_world[ray_view]                                          # [H, B, 3]
    cos = (nrm[:, None, :] * l_ray).sum(-1)
    lit = (cos > 0.0) & ((nrm * w_ray).sum(-1) > 0.0)[:, None]
    hi_idx, bin_idx = np.nonzero(lit)
    s_org = x[hi_idx] + SHADOW_OFFSET * nrm[hi_idx]
    s_dir = l_ray[hi_idx, bin_idx]
    vox = ray_view[hi_idx] // V
    _, s_out = box_interval(s_org, s_dir, lo[vox], hi[vox])
    visible = np.ones(len(hi_idx), bool)
    inside = s_out > 0.0
    visible[inside] = ~_occluded(scene, s_org[inside], s_dir[inside], s_out[inside])
    f_white = brdf(nrm[hi_idx], w_ray[hi_idx], s_dir, np.ones((len(hi_idx), 1)),
                   common["roughness"][f_hit[hi_idx]], common["metallic"][f_hit[hi_idx]])[:, 0]
    contrib = f_white * cos[hi_idx, bin_idx] * visible
    phase = np.bincount(ray_view[hi_idx] * B + bin_idx, contrib, n * V * B).reshape(n * V, B)
    phase = phase / np.maximum(n_hits, 1)[:, None]
    return {"views": w.astype(np.float32), "coverage": coverage.astype(np.float32),
            "albedo": albedo.reshape(n, V, 3).astype(np.float32),
            "light_local": light_local.astype(np.float32),
            "phase": phase.reshape(n, V, B).astype(np.float32),
            "ray_counts": np.array([int(through.sum()), int(inside.sum())], np.int64)}


# --- the driver ----------------------------------------------------------------------------------

def _check(cells, spheres, views, mask, bins, rays_per_texel, chunk):
    cells = np.asarray(cells)
    spheres = np.asarray(spheres)
    if cells.ndim != 2 or cells.shape[1] != 4 or cells.dtype != np.uint32:
        raise DataError(f"cells: expected uint32 [N, 4], got {cells.dtype} {cells.shape}")
    if spheres.shape != (len(cells), 4) or spheres.dtype != np.float32:
        raise DataError(f"spheres: expected float32 [{len(cells)}, 4], got {spheres.dtype} {spheres.shape}")
    if not np.all(np.isfinite(spheres)) or (len(spheres) and spheres[:, 3].min() <= 0.0):
        raise DataError("spheres: values must be finite with radius > 0")
    if len(cells) and (cells[:, 0].max() > 9 or np.any(cells[:, 1:] >= (1 << cells[:, :1].astype(np.int64)))):
        raise DataError("cells: an (i, j, k) index lies outside its scale's grid (or scale > 9)")
    for name, v in (("views", views), ("mask", mask), ("rays_per_texel", rays_per_texel), ("chunk", chunk)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise DataError(f"{name}: must be an int >= 1, got {v!r}")
    if (not isinstance(bins, (tuple, list)) or len(bins) != 2 or
            not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= 1 for v in bins)):
        raise DataError(f"bins: must be (BT, BP), two ints >= 1, got {bins!r}")
    return cells, spheres


def _digest(common: dict, cells, spheres) -> str:
    h = hashlib.sha256(json.dumps(common["settings"], sort_keys=True).encode())
    for k in ("vertices", "faces", "base_colour", "roughness", "metallic", "two_sided"):
        h.update(np.ascontiguousarray(common[k]).tobytes())
    h.update(cells.tobytes())
    h.update(spheres.tobytes())
    return h.hexdigest()[:20]


def bake_voxel_data(scene, cells, spheres, *, views: int = 16, mask: int = 8, bins=(4, 8),
                    rays_per_texel: int = 1, seed: int = 0, executor=None, cache_dir=None,
                    progress: bool | None = True, chunk: int = CHUNK, fixed_views=None) -> dict:
    """The contract's per-voxel arrays for every slot of (cells, spheres), plus ``cells``,
    ``spheres``, ``ray_counts`` int64 [2] (primary rays through a box, shadow rays cast) and
    ``seconds`` (float64 [1]). Shards of ``chunk`` slots are cached under
    ``cache_dir/dap-<digest of geometry, materials, voxels and settings>/`` and resume.

    ``fixed_views`` [V, 3] (unit, toward the viewer): the same views for every slot in place of
    the per-slot stratified draws (the paper's prerendering uses one shared set, §3.5; tests use
    it to look along chosen axes)."""
    from inshade.models.bake import IN_PROCESS, Shard, run_shards
    from inshade.progress import progress as progress_bar

    cells, spheres = _check(cells, spheres, views, mask, bins, rays_per_texel, chunk)
    if fixed_views is not None:
        fixed_views = np.asarray(fixed_views, np.float64)
        if fixed_views.shape != (views, 3) or not np.all(np.isfinite(fixed_views)) or \
                np.abs(np.linalg.norm(fixed_views, axis=1) - 1.0).max() > 1e-6:
            raise DataError(f"fixed_views: expected [{views}, 3] finite unit vectors, got shape {fixed_views.shape}")
    mesh = scene.mesh
    common = {"vertices": np.asarray(mesh.vertices, np.float64), "faces": np.asarray(mesh.faces, np.int64),
              "face_normals": np.asarray(mesh.face_normals, np.float64),
              "base_colour": np.asarray(scene.base_colour, np.float32),
              "roughness": np.asarray(scene.roughness, np.float32),
              "metallic": np.asarray(scene.metallic, np.float32),
              "two_sided": np.asarray(scene.two_sided, bool),
              "settings": {"views": int(views), "mask": int(mask), "bins": [int(bins[0]), int(bins[1])],
                           "rays_per_texel": int(rays_per_texel), "seed": int(seed),
                           "fixed_views": None if fixed_views is None else fixed_views.tolist()},
              "fixed_views": fixed_views}
    key = _digest(common, cells, spheres)
    common["key"] = key
    shards = [Shard(f"voxels-{i:08d}", {"start": i, "cells": cells[i:i + chunk], "spheres": spheres[i:i + chunk]})
              for i in range(0, len(cells), chunk)]
    shard_dir = Path(cache_dir) / f"dap-{key}" if cache_dir is not None else None
    start = time.perf_counter()
    with progress_bar(total=len(cells), desc="voxel data", unit="voxel", enabled=progress) as bar:
        results = run_shards(voxel_shard, shards, common, shard_dir, executor or IN_PROCESS,
                             on_done=lambda s: bar.update(len(s.args["cells"])))
    seconds = time.perf_counter() - start
    out = {k: np.concatenate([r[k] for r in results]) if results else np.zeros((0,), np.float32)
           for k in ("views", "coverage", "albedo", "light_local", "phase")}
    out["ray_counts"] = np.sum([r["ray_counts"] for r in results], 0).astype(np.int64) if results \
        else np.zeros(2, np.int64)
    out["cells"], out["spheres"] = cells, spheres
    out["seconds"] = np.array([seconds])
    return out


def phase_slice(phase: np.ndarray, bins) -> np.ndarray:
    """The phase-slice target P_b = phase[..., b] * 4 pi / B (one-sample bin estimate)."""
    return phase * (4.0 * math.pi / (bins[0] * bins[1]))
