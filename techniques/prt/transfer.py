"""Ground-truth transfer for the learnt-transfer network (Learnt Transfer, Dhawal et al. 2022): surface samples and
T_k(p, n) = integral V(p, w) max(0, w.n) y_k(w) dw by casting visibility rays.

``y_k`` is ``inshade.sh.sh_basis`` (real orthonormal, index l*l + l + m), degree 4 (16 lanes).

Estimator: cosine-weighted hemisphere samples about n, so every ray counts and
``T_k ~ (pi / D) sum_d V_d y_k(w_d)`` (the clamped cosine is the sampling density, pdf cos/pi).
The D samples are a 2D Fibonacci lattice in the unit square, shifted per point by a random
Cranley-Patterson offset (mod 1), mapped to the disk (r = sqrt(u)) and lifted to the hemisphere
in an orthonormal frame about n. Stratified, unbiased, and decorrelated between neighbouring
points (no coherent banding for a network to learn). Unoccluded, the estimate is exact for band 0
(pi * 0.2821) and within ~1/D of ``lambert_bands`` x basis for the other bands.

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

Surface samples: meshes with ``trimesh.sample.sample_surface`` (area weighted) and barycentric-
interpolated, normalised vertex normals (what the rasteriser interpolates). SDFs: marching cubes
over the bound, area-weighted samples of that mesh, Newton-projected onto the zero set, kept inside
the bound sphere, normals by the SDF's own estimator (``sdf.normals`` if it has one, else the
central differences of ``models.sdf.normals``, as the shader computes them: n is a network input).

``build_dataset`` caches (safetensors, keyed by a hash of geometry + settings) and records the
measured throughput (``rays_per_second``) in the dataset's metadata.

Devices: ``device`` (a torch.device or its name, default the CPU) is where SDF evaluation runs --
the marching-cubes grid, the Newton projection and the shadow-ray sphere tracing. Random numbers
are drawn on CPU generators and the transfer is projected and returned on the CPU, so a seed gives
the same directions on every device and the CPU result does not depend on this option. Mesh
visibility is embree's (CPU) whatever the device.
"""
from __future__ import annotations

import copy
import hashlib
import json
import math
import shutil
import time
import warnings
from pathlib import Path

import numpy as np
import torch

from inshade.files import atomic_files
from inshade.sh import sh_basis

DEGREE = 4
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
CHUNK_RAYS = 1 << 20        # rays per batch (memory ~100 bytes/ray at peak)
GOLDEN = (1.0 + math.sqrt(5.0)) / 2.0


class TransferError(ValueError):
    """Bad input to transfer data generation; the message names the argument or file."""


# ---------------------------------------------------------------------------------------------
# directions

def _rotation(gen: torch.Generator) -> torch.Tensor:
    """A uniformly random rotation matrix (unit quaternion from 4 normals), float64."""
    q = torch.randn(4, generator=gen, dtype=torch.float64)
    w, x, y, z = (q / q.norm()).tolist()
    return torch.tensor([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]],
                        dtype=torch.float64)


def sphere_directions(n: int, seed: int = 0) -> torch.Tensor:
    """``n`` unit directions [n, 3] float32: a spherical Fibonacci set (equal-area, low
    discrepancy), randomly rotated by ``seed`` so repeated estimates are independent."""
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise TransferError(f"n: must be a positive int, got {n!r}")
    i = torch.arange(n, dtype=torch.float64) + 0.5
    z = 1.0 - 2.0 * i / n
    r = torch.sqrt((1.0 - z * z).clamp_min(0.0))
    phi = 2.0 * math.pi * torch.remainder(i / GOLDEN, 1.0)
    d = torch.stack([r * torch.cos(phi), r * torch.sin(phi), z], -1)
    d = d @ _rotation(torch.Generator().manual_seed(int(seed))).T
    return (d / d.norm(dim=-1, keepdim=True)).float()


def _lattice(n: int) -> torch.Tensor:
    """2D Fibonacci lattice [n, 2] in [0, 1)^2 (float64)."""
    i = torch.arange(n, dtype=torch.float64)
    return torch.stack([(i + 0.5) / n, torch.remainder(i / GOLDEN, 1.0)], -1)


def _frame(nrm: torch.Tensor):
    """Orthonormal tangents (t, b) of unit normals [N, 3] (Duff et al. 2017, branchless)."""
    x, y, z = nrm.unbind(-1)
    s = torch.where(z >= 0, torch.ones_like(z), -torch.ones_like(z))
    a = -1.0 / (s + z)
    b = x * y * a
    t = torch.stack([1.0 + s * x * x * a, s * b, -s * x], -1)
    bt = torch.stack([b, s + y * y * a, -y], -1)
    return t, bt


def hemisphere_directions(nrm: torch.Tensor, n_dirs: int, gen: torch.Generator) -> torch.Tensor:
    """Cosine-weighted stratified directions [N, n_dirs, 3] about unit normals [N, 3] (see the
    module docstring); float32."""
    lat = _lattice(n_dirs)[None]                                            # [1, D, 2]
    shift = torch.rand(nrm.shape[0], 1, 2, generator=gen, dtype=torch.float64)
    u = torch.remainder(lat + shift, 1.0)                                   # [N, D, 2]
    r = torch.sqrt(u[..., 0])
    phi = 2.0 * math.pi * u[..., 1]
    lx, ly = r * torch.cos(phi), r * torch.sin(phi)
    lz = torch.sqrt((1.0 - u[..., 0]).clamp_min(0.0))
    n64 = nrm.double()
    t, b = _frame(n64)
    d = lx[..., None] * t[:, None] + ly[..., None] * b[:, None] + lz[..., None] * n64[:, None]
    return d.float()


def _project(visible: torch.Tensor, dirs: torch.Tensor) -> torch.Tensor:
    """(pi / D) sum_d V_d y_k(w_d): visible [N, D] bool, dirs [N, D, 3] -> [N, 16] float32."""
    y = sh_basis(dirs, DEGREE, torch)                                       # [N, D, 16]
    v = visible.to(y.dtype)
    return torch.einsum("nd,ndk->nk", v, y) * (math.pi / dirs.shape[1])


def _generator(seed: int, start: int, per: int) -> torch.Generator:
    """The direction generator of an estimate over points ``start:``, chunked ``per`` points at a
    time: seeded by ``seed`` and advanced past the draws of the ``start`` points before (one
    ``hemisphere_directions`` draw per chunk, replayed chunk by chunk). A shard that starts on a
    chunk boundary thus draws exactly what the unsharded estimate draws for its points, whichever
    worker runs it, and computes the same chunks: sharded results are bit-identical to one run."""
    if isinstance(start, bool) or not isinstance(start, (int, np.integer)) or start < 0 or start % per:
        raise TransferError(f"start: must be a multiple of the chunk ({per} points), got {start!r}")
    gen = torch.Generator().manual_seed(int(seed))
    for i in range(0, int(start), per):
        torch.rand(min(per, start - i), 1, 2, generator=gen, dtype=torch.float64)
    return gen


# ---------------------------------------------------------------------------------------------
# input checks

def _check_points(p, nrm, where: str = "points"):
    if not isinstance(p, torch.Tensor):
        p = torch.as_tensor(np.asarray(p, np.float32))
    if not isinstance(nrm, torch.Tensor):
        nrm = torch.as_tensor(np.asarray(nrm, np.float32))
    if p.ndim != 2 or p.shape[1] != 3:
        raise TransferError(f"{where}: positions must be [N, 3], got shape {tuple(p.shape)}")
    if nrm.shape != p.shape:
        raise TransferError(f"{where}: normals must match positions [N, 3], got {tuple(nrm.shape)} "
                            f"for {tuple(p.shape)}")
    p, nrm = p.detach().float(), nrm.detach().float()
    bad = ~(torch.isfinite(p).all(-1) & torch.isfinite(nrm).all(-1))
    if bad.any():
        raise TransferError(f"{where}: {int(bad.sum())} point(s) have NaN/inf position or normal "
                            f"(first at index {int(bad.nonzero()[0])})")
    length = nrm.norm(dim=-1)
    if (length < 1e-6).any():
        raise TransferError(f"{where}: normal at index {int((length < 1e-6).nonzero()[0])} is zero")
    return p, nrm / length[:, None]


def _check_count(v, name: str) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
        raise TransferError(f"{name}: must be a positive int, got {v!r}")
    return int(v)


def _check_sdf(sdf):
    scene = getattr(sdf, "scene", None)
    if not callable(sdf) or scene is None or not all(hasattr(scene, a) for a in ("trace", "center", "radius")):
        raise TransferError(f"geometry: not an SDF module (needs __call__(p) and .scene with "
                            f"trace/center/radius): {type(sdf).__name__}")
    return scene


def _check_mesh(mesh):
    import trimesh

    if not isinstance(mesh, trimesh.Trimesh):
        raise TransferError(f"geometry: expected a trimesh.Trimesh, got {type(mesh).__name__}")
    if len(mesh.faces) == 0:
        raise TransferError("mesh: has no faces")
    if not np.isfinite(mesh.vertices).all():
        raise TransferError("mesh: vertices contain NaN/inf")
    return mesh


def _bar(total, desc, progress, unit="ray"):
    from inshade.progress import progress as progress_bar

    # tqdm on a TTY, a line every ~30 s off it; progress=False: silent
    return progress_bar(total=total, desc=desc, unit=unit, unit_scale=True, enabled=progress)


# ---------------------------------------------------------------------------------------------
# SDF geometry

def _sdf_normals(sdf, p: torch.Tensor) -> torch.Tensor:
    own = getattr(sdf, "normals", None)
    if callable(own):
        return own(p)
    from inshade.models.sdf import normals

    return normals(sdf, p)


def _eval_chunked(sdf, p: torch.Tensor, chunk: int = 1 << 18, device=None) -> torch.Tensor:
    """sdf(p) chunk by chunk, evaluated on ``device`` (default p's), returned on p's device."""
    with torch.no_grad():
        return torch.cat([sdf(p[i:i + chunk].to(device or p.device)).to(p.device)
                          for i in range(0, p.shape[0], chunk)])


def _on_device(sdf, device: torch.device):
    """The SDF module with its tensors on ``device``: itself when they are there already (or it has
    none, as an analytic SdfModule), else a moved copy (the caller's module stays where it is)."""
    if not isinstance(sdf, torch.nn.Module):
        return sdf
    probe = torch.empty(0, device=device).device        # "cuda" -> "cuda:<current>", as tensors report it
    tensors = [*sdf.parameters(), *sdf.buffers()]
    if all(t.device == probe for t in tensors):
        return sdf
    return copy.deepcopy(sdf).to(probe)


def sample_sdf_surface(sdf, n_points: int, seed: int = 0, resolution: int = 128, newton: int = 4,
                       device="cpu"):
    """``n_points`` surface samples (p [N, 3], unit normals [N, 3], float32) of an SDF module,
    area weighted: marching cubes at ``resolution`` over the bound's box, area-weighted samples of
    that mesh, ``newton`` Newton steps p -= d * n onto the zero set (n: the SDF's normal estimator,
    not autograd: hard booleans and box corners have NaN autograd gradients); only points inside
    the bound sphere with |d| < hit_eps are kept. SDF evaluations run on ``device``; the samples
    come back on the CPU."""
    import trimesh
    from skimage.measure import marching_cubes

    scene = _check_sdf(sdf)
    n_points = _check_count(n_points, "n_points")
    device = torch.device(device)
    sdf = _on_device(sdf, device)
    c = np.asarray(scene.center, np.float64)
    r = float(scene.radius)
    axis = np.linspace(-r, r, resolution)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3) + c
    d = _eval_chunked(sdf, torch.from_numpy(grid).float(), device=device).reshape(resolution, resolution, resolution)
    d = d.numpy()
    if not (d.min() < 0.0 < d.max()):
        raise TransferError(f"{getattr(scene, 'path', None) or 'sdf'}: no surface inside the bound "
                            f"(distances in [{d.min():.3g}, {d.max():.3g}])")
    step = 2.0 * r / (resolution - 1)
    verts, faces, _, _ = marching_cubes(d, 0.0, spacing=(step, step, step))
    mesh = trimesh.Trimesh(verts + (c - r), faces, process=False)
    hit_eps = float(scene.trace["hit_eps"])
    rng = np.random.default_rng(seed)
    kept_p, kept_n, have = [], [], 0
    for _ in range(8):              # top up: some samples land outside the bound or off the surface
        want = int((n_points - have) * 1.3) + 64
        pts, _ = trimesh.sample.sample_surface(mesh, want, seed=rng)
        p = torch.from_numpy(np.asarray(pts, np.float32)).to(device)
        with torch.no_grad():
            for _ in range(newton):
                p = p - sdf(p)[:, None] * _sdf_normals(sdf, p)
            dist = sdf(p).cpu()
            nrm = _sdf_normals(sdf, p).cpu()
        p = p.cpu()
        inside = (p.double() - torch.from_numpy(c)).norm(dim=-1) < r
        ok = inside & (dist.abs() < hit_eps) & torch.isfinite(nrm).all(-1) & torch.isfinite(p).all(-1)
        kept_p.append(p[ok])
        kept_n.append(nrm[ok])
        have += int(ok.sum())
        if have >= n_points:
            break
    if have < n_points:
        raise TransferError(f"sdf: only {have} of {n_points} surface samples projected onto the surface")
    return torch.cat(kept_p)[:n_points].contiguous(), torch.cat(kept_n)[:n_points].contiguous()


def _shadow_trace(sdf, o: torch.Tensor, d: torch.Tensor, center: torch.Tensor, radius: float,
                  step_scale: float, hit_eps: float, max_steps: int) -> torch.Tensor:
    """Occluded [R] bool for rays o + t d (unit d), with active-set compaction."""
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
    return occluded


def sdf_transfer(sdf, p, nrm, n_dirs: int = 256, seed: int = 0, progress: bool | None = False,
                 max_steps: int | None = None, chunk_rays: int = CHUNK_RAYS, device="cpu",
                 start: int = 0, shadow: str = DEFAULT_SHADOW) -> torch.Tensor:
    """Ground-truth transfer [N, 16] float32 (on the CPU) at points p [N, 3] with normals nrm [N, 3]
    (any points: surface samples or G-buffer hits) of an SDF module, the shadow rays traced on
    ``device``; see the module docstring. ``start``: these points follow ``start`` others of the
    same estimate (a shard, see ``_generator``). ``shadow``: a ``SHADOW_SCHEMES`` name."""
    scene = _check_sdf(sdf)
    device = torch.device(device)
    sdf = _on_device(sdf, device)
    p, nrm = _check_points(p, nrm)
    n_dirs = _check_count(n_dirs, "n_dirs")
    if shadow not in SHADOW_SCHEMES:
        raise TransferError(f"shadow: must be one of {list(SHADOW_SCHEMES)}, got {shadow!r}")
    tr = scene.trace
    hit_eps, step_scale = float(tr["hit_eps"]), float(tr["step_scale"])
    steps = int(max_steps if max_steps is not None else max(SHADOW_STEPS, int(tr["max_steps"])))
    offset, threshold = (k * hit_eps for k in SHADOW_SCHEMES[shadow])
    center = torch.tensor(scene.center, dtype=torch.float32, device=device)
    radius = float(scene.radius)
    per = max(1, chunk_rays // n_dirs)
    gen = _generator(seed, start, per)
    out = torch.empty(p.shape[0], DEGREE * DEGREE)
    with torch.no_grad(), _bar(p.shape[0] * n_dirs, "transfer (sdf)", progress) as bar:
        for i in range(0, p.shape[0], per):
            pc, nc = p[i:i + per], nrm[i:i + per]
            dirs = hemisphere_directions(nc, n_dirs, gen)                    # [n, D, 3], CPU draws
            o = (pc + nc * offset)[:, None].expand_as(dirs).reshape(-1, 3)
            occ = _shadow_trace(sdf, o.to(device), dirs.reshape(-1, 3).to(device), center, radius, step_scale,
                                threshold, steps).cpu()
            out[i:i + per] = _project(~occ.reshape(dirs.shape[:2]), dirs)
            bar.update(dirs.shape[0] * n_dirs)
    return out


# ---------------------------------------------------------------------------------------------
# meshes

def sample_mesh_surface(mesh, n_points: int, seed: int = 0):
    """Area-weighted samples (p [N, 3], unit normals [N, 3], float32) of a trimesh.Trimesh; the
    normals are the barycentric interpolation of the vertex normals, normalised."""
    import trimesh

    mesh = _check_mesh(mesh)
    n_points = _check_count(n_points, "n_points")
    pts, fi, bary = trimesh.sample.sample_surface(mesh, n_points, seed=int(seed), return_barycentric=True)
    vn = np.asarray(mesh.vertex_normals, np.float64)[mesh.faces[fi]]        # [N, 3 corners, 3]
    nrm = np.einsum("nc,ncx->nx", np.asarray(bary, np.float64), vn)
    length = np.linalg.norm(nrm, axis=-1, keepdims=True)
    # a degenerate interpolation (opposing vertex normals) falls back to the face normal
    nrm = np.where(length > 1e-8, nrm / np.maximum(length, 1e-30), mesh.face_normals[fi])
    return torch.from_numpy(np.asarray(pts, np.float32)), torch.from_numpy(nrm.astype(np.float32))


def mesh_transfer(mesh, p, nrm, n_dirs: int = 256, seed: int = 0, progress: bool | None = False,
                  chunk_rays: int = CHUNK_RAYS, start: int = 0) -> torch.Tensor:
    """Ground-truth transfer [N, 16] float32 at points p [N, 3] with normals nrm [N, 3] of a
    trimesh.Trimesh, by ``mesh.ray.intersects_any`` (embree when available). ``start``: as in
    ``sdf_transfer``."""
    import trimesh

    mesh = _check_mesh(mesh)
    p, nrm = _check_points(p, nrm)
    n_dirs = _check_count(n_dirs, "n_dirs")
    if not trimesh.ray.has_embree:
        warnings.warn("embreex is not installed: trimesh falls back to its pure-Python ray caster, "
                      "which is ~100x slower (pip install embreex)", stacklevel=2)
    offset = MESH_OFFSET * float(np.linalg.norm(mesh.extents))
    per = max(1, chunk_rays // n_dirs)
    gen = _generator(seed, start, per)
    out = torch.empty(p.shape[0], DEGREE * DEGREE)
    with torch.no_grad(), _bar(p.shape[0] * n_dirs, "transfer (mesh)", progress) as bar:
        for i in range(0, p.shape[0], per):
            pc, nc = p[i:i + per], nrm[i:i + per]
            dirs = hemisphere_directions(nc, n_dirs, gen)
            o = (pc + nc * offset)[:, None].expand_as(dirs).reshape(-1, 3)
            occ = mesh.ray.intersects_any(o.numpy().astype(np.float64), dirs.reshape(-1, 3).numpy().astype(np.float64))
            occ = torch.from_numpy(np.asarray(occ, bool)).reshape(dirs.shape[:2])
            out[i:i + per] = _project(~occ, dirs)
            bar.update(dirs.shape[0] * n_dirs)
    return out


# ---------------------------------------------------------------------------------------------
# datasets

def _is_mesh(geometry) -> bool:
    try:
        import trimesh
    except ImportError:  # pragma: no cover
        return False
    return isinstance(geometry, trimesh.Trimesh)


def geometry_bound(geometry) -> tuple[tuple[float, float, float], float]:
    """(center, radius) of the sphere the network's positions are normalised by: the SDF scene's
    bound, or a mesh's bounding-box centre and the distance to its farthest vertex."""
    if _is_mesh(geometry):
        c = np.asarray(geometry.bounds, np.float64).mean(0)
        r = float(np.linalg.norm(np.asarray(geometry.vertices) - c, axis=-1).max())
        return tuple(float(x) for x in c), r
    scene = _check_sdf(geometry)
    return tuple(float(x) for x in scene.center), float(scene.radius)


def geometry_digest(geometry) -> str:
    """sha256 of what the transfer depends on: mesh vertices + faces, or the SDF scene
    (description tree, bound, trace settings) and any tensors of the SDF module (neural SDFs)."""
    h = hashlib.sha256()
    if _is_mesh(geometry):
        h.update(b"mesh")
        h.update(np.ascontiguousarray(geometry.vertices, np.float64).tobytes())
        h.update(np.ascontiguousarray(geometry.faces, np.int64).tobytes())
        return h.hexdigest()
    scene = _check_sdf(geometry)
    h.update(b"sdf")
    h.update(type(geometry).__name__.encode())
    h.update(repr(getattr(scene, "root", None)).encode())
    h.update(json.dumps({"center": list(scene.center), "radius": scene.radius,
                         "trace": dict(scene.trace)}, sort_keys=True).encode())
    if isinstance(geometry, torch.nn.Module):
        for name, t in sorted(geometry.state_dict().items()):
            h.update(name.encode())
            h.update(t.detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()


def build_dataset(geometry, n_points: int, n_dirs: int = 256, cache_dir=None, seed: int = 0,
                  progress: bool | None = None, holdout: int | None = None,
                  holdout_dirs: int = HOLDOUT_DIRS, device="cpu", executor=None,
                  chunk_rays: int = CHUNK_RAYS, shadow: str = DEFAULT_SHADOW) -> dict:
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

    The rays are a sharded bake (inshade/bake.py; ``executor``: in-process by default, a process
    pool or Ray): one shard per chunk of ``chunk_rays`` rays, cached in ``transfer-<key>.shards/``
    while the bake runs (a rerun resumes there; removed once the dataset is written). The shards
    replay the unsharded estimate's random stream (``_generator``), so the data is bit-identical
    whatever the executor and to an unsharded run. ``shadow``: the SDF shadow-ray scheme
    (``SHADOW_SCHEMES``; part of the cache key unless it is the default)."""
    mesh = _is_mesh(geometry)
    if not mesh:
        _check_sdf(geometry)
    n_points = _check_count(n_points, "n_points")
    n_dirs = _check_count(n_dirs, "n_dirs")
    holdout = min(2000, max(1, n_points // 20)) if holdout is None else _check_count(holdout, "holdout")
    holdout_dirs = _check_count(holdout_dirs, "holdout_dirs")
    settings = {"version": VERSION, "n_points": n_points, "n_dirs": n_dirs, "seed": int(seed),
                "holdout": holdout, "holdout_dirs": holdout_dirs,
                "offset": MESH_OFFSET if mesh else OFFSET_EPS, "shadow_steps": SHADOW_STEPS}
    if shadow not in SHADOW_SCHEMES:
        raise TransferError(f"shadow: must be one of {list(SHADOW_SCHEMES)}, got {shadow!r}")
    if shadow != DEFAULT_SHADOW and not mesh:
        settings["shadow"] = shadow
    # SDF data traced on a GPU may differ from the CPU's in the last bits: its own cache entry (the
    # CPU keys stay as they were; mesh rays are embree's on every device)
    device = torch.device(device)
    if device.type != "cpu" and not mesh:
        settings["device"] = device.type
    key = hashlib.sha256((geometry_digest(geometry) + json.dumps(settings, sort_keys=True)).encode()).hexdigest()[:24]
    path = Path(cache_dir) / f"transfer-{key}.safetensors" if cache_dir is not None else None
    if path is not None and path.is_file():
        data = load_dataset(path)
        if data.get("key") == key:
            data["cached"] = True
            return data
    from inshade.bake import IN_PROCESS, run_shards

    executor = executor or IN_PROCESS
    center, radius = geometry_bound(geometry)
    start = time.perf_counter()
    total = n_points + holdout
    source = geometry                               # as given (CPU): what other processes receive
    if mesh:
        p, nrm = sample_mesh_surface(geometry, total, seed)
    else:
        geometry = _on_device(geometry, device)     # moved once for sampling and rays
        p, nrm = sample_sdf_surface(geometry, total, seed, device=device)
    ray_start = time.perf_counter()
    # a GPU worker of Ray sees only the GPU it was given, as cuda:0
    worker_device = "cuda" if executor.kind == "ray" and device.type == "cuda" else str(device)
    common = {"geometry": source if executor.remote else geometry, "mesh": mesh,
              "device": worker_device if executor.remote else device, "threads": torch.get_num_threads(),
              "chunk_rays": int(chunk_rays), "shadow": shadow}
    sets = (("train", p[:n_points], nrm[:n_points], n_dirs, seed),
            ("heldout", p[n_points:], nrm[n_points:], holdout_dirs, seed + 1))
    shards = transfer_shards(sets, chunk_rays, num_gpus=0.0 if mesh or device.type == "cpu" else 1.0)
    shard_dir = Path(cache_dir) / f"transfer-{key}.shards" if cache_dir is not None else None
    with _bar(n_points * n_dirs + holdout * holdout_dirs, "transfer rays", progress) as bar:
        results = run_shards(transfer_shard, shards, common, shard_dir, executor,
                             on_done=lambda s: bar.update(s.args["points"].shape[0] * s.args["n_dirs"]))
    # copies: Ray hands back read-only arrays
    parts = {name: [torch.tensor(r["transfer"]) for s, r in zip(shards, results) if s.args["set"] == name]
             for name, *_ in sets}
    transfer, held = torch.cat(parts["train"]), torch.cat(parts["heldout"])
    end = time.perf_counter()
    rays = n_points * n_dirs + holdout * holdout_dirs
    data = {"position": p[:n_points].contiguous(), "normal": nrm[:n_points].contiguous(), "transfer": transfer,
            "heldout_position": p[n_points:].contiguous(), "heldout_normal": nrm[n_points:].contiguous(),
            "heldout_transfer": held, "center": list(center), "radius": radius,
            "n_points": n_points, "n_dirs": n_dirs, "n_heldout": holdout, "heldout_dirs": holdout_dirs,
            "seed": int(seed), "kind": "mesh" if mesh else "sdf",
            "key": key, "seconds": round(end - start, 3), "ray_seconds": round(end - ray_start, 3),
            "rays": rays, "rays_per_second": round(rays / max(end - ray_start, 1e-9), 1),
            "embree": bool(mesh and _has_embree()), "torch_threads": torch.get_num_threads(),
            "device": "cpu" if mesh else str(device),
            "cached": False}
    if path is not None:
        save_dataset(data, path)
        shutil.rmtree(shard_dir, ignore_errors=True)    # the dataset file holds them all now
    return data


def transfer_shards(sets, chunk_rays: int = CHUNK_RAYS, num_gpus: float = 0.0) -> list:
    """One ``inshade.bake.Shard`` per chunk of each (name, points, normals, n_dirs, seed) set, in
    order; a shard's args carry its points, normals and offset into the set (``start``)."""
    from inshade.bake import Shard

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


TENSORS = ("position", "normal", "transfer", "heldout_position", "heldout_normal", "heldout_transfer")


def save_dataset(data: dict, path) -> Path:
    """Writes a dataset (tensors + JSON metadata in the safetensors header) atomically."""
    from safetensors.torch import save_file

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {k: v for k, v in data.items() if k not in TENSORS and k != "cached"}
    with atomic_files(path) as tmp:
        save_file({k: data[k].contiguous() for k in TENSORS if k in data}, str(tmp),
                  metadata={"format": "inshade.transfer_data", "meta": json.dumps(meta, sort_keys=True)})
    return path


def load_dataset(path) -> dict:
    """Reads a dataset written by ``save_dataset`` (TransferError naming the file if it is not one)."""
    from safetensors import safe_open

    path = Path(path)
    try:
        with safe_open(str(path), framework="pt") as f:
            header = f.metadata() or {}
            if header.get("format") != "inshade.transfer_data":
                raise TransferError(f"{path}: format: not an inshade transfer dataset")
            data = json.loads(header["meta"])
            for k in TENSORS:
                if k in f.keys():
                    data[k] = f.get_tensor(k).float()
    except TransferError:
        raise
    except Exception as exc:  # safetensors raises several types for corrupt files
        raise TransferError(f"{path}: unreadable transfer dataset ({exc})") from None
    missing = [k for k in TENSORS[:3] if k not in data]
    if missing:
        raise TransferError(f"{path}: {missing[0]}: missing")
    n = data["position"].shape[0]
    if data["normal"].shape != (n, 3) or data["transfer"].shape != (n, DEGREE * DEGREE):
        raise TransferError(f"{path}: transfer: shapes do not match ({n} points)")
    return data
