"""DI-SDF data: the mesh and its bound frame, the training samples with truncated signed
distances, their batches and the cascaded array's nearest-sample init, and the evaluation set and
metrics (the same numbers for the DI-SDF and the MLP SDF in techniques/di_sdf/bench.py).

Samples (paper: 1e9 near-surface + 2e7 uniform; here 4e5 by default: 12 s on the 2 shared cores
when quiet, 40 s under load, for a 40k-face mesh): surface points
pushed along a Gaussian (σ drawn from ``near_sigmas``, in normalised units) plus uniform points in
the cube. Signed distance: exact point-triangle distance to the candidate faces of the k nearest
dense surface samples (scipy cKDTree, queried only within the band -- points with no sample
closer than τ plus the sample spacing are beyond the band and get ±τ), sign from ray parity
through embree (``trimesh`` with ``embreex``). The cascaded array starts from the nearest
training sample's truncated distance at each cell (KD-tree, the paper's init); the primary is the
identity ramp.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import torch

MARGIN = 1.1                        # bound radius: the farthest vertex from the box centre, times this
UNIFORM_FRACTION = 0.25             # share of the samples uniform in the bound cube (the rest near the surface)
NEAR_SIGMAS = (0.005, 0.02, 0.05)   # Gaussian offsets off the surface, normalised units
KNN = 8                     # candidate faces per query point (from the k nearest surface samples)
SURFACE_SAMPLES = 200_000   # dense surface sample for the distance queries


class DiSdfError(ValueError):
    """A mesh or a setting DI-SDF cannot use; the message names the file / option."""


# ---------------------------------------------------------------------------------------------
# mesh and its frame

def load_mesh(path):
    """A closed triangle mesh from a file (inshade.geometry.mesh.load_mesh); one DiSdfError naming the file."""
    from inshade.geometry.mesh import MeshError, load_mesh as _load

    try:
        return check_mesh(_load(path, require_watertight=True), str(path))
    except MeshError as e:
        raise DiSdfError(str(e)) from None


def check_mesh(mesh, where: str = "mesh"):
    import trimesh

    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise DiSdfError(f"{where}: no triangles")
    if not np.all(np.isfinite(mesh.vertices)):
        raise DiSdfError(f"{where}: vertices are not finite")
    if not mesh.is_watertight:
        raise DiSdfError(f"{where}: not watertight ({len(mesh.faces)} faces); a signed distance needs a closed "
                         "surface (repair it, e.g. trimesh.repair.fill_holes, or remesh)")
    if mesh.volume < 0:
        mesh = mesh.copy()
        mesh.invert()
    return mesh


@dataclass(frozen=True)
class Frame:
    """The bound sphere: ``center`` and ``radius`` (world); q = (p - center) / radius."""

    center: tuple
    radius: float

    def normalise(self, p):
        return (np.asarray(p, np.float64) - np.asarray(self.center)) / self.radius

    def world(self, q):
        return np.asarray(self.center) + np.asarray(q, np.float64) * self.radius


def mesh_frame(mesh, margin: float = MARGIN) -> Frame:
    """Centre of the bounding box; radius = margin * the farthest vertex (float32-rounded)."""
    c = mesh.bounds.mean(0)
    r = float(np.linalg.norm(mesh.vertices - c, axis=1).max()) * float(margin)
    return Frame(tuple(float(np.float32(x)) for x in c), float(np.float32(r)))


# ---------------------------------------------------------------------------------------------
# samples and signed distance

class DistanceQuery:
    """Signed distance to a closed mesh, exact within ``band`` (world units), ±band beyond it."""

    def __init__(self, mesh, band: float, seed: int = 0, surface_samples: int = SURFACE_SAMPLES):
        import trimesh
        from scipy.spatial import cKDTree

        self.mesh = mesh
        pts, self.faces = trimesh.sample.sample_surface(mesh, surface_samples, seed=seed)
        self.tree = cKDTree(pts)
        # Mean spacing of the surface sample; a point within `band` of the surface has a sample
        # within band + a few spacings, so the bounded query finds it.
        spacing = math.sqrt(mesh.area / surface_samples)
        self.band = float(band)
        self.reach = self.band + 4.0 * spacing

    def __call__(self, points: np.ndarray, chunk: int = 65536) -> np.ndarray:
        import trimesh

        from inshade.progress import progress as progress_bar

        points = np.asarray(points, np.float64)
        out = np.full(len(points), self.band)
        starts = range(0, len(points), chunk)
        for s in progress_bar(starts, desc="signed distance", enabled=len(starts) >= 4):
            q = points[s:s + chunk]
            dist, idx = self.tree.query(q, k=KNN, distance_upper_bound=self.reach, workers=-1)
            near = np.isfinite(dist[:, 0])
            d = np.full(len(q), self.band)
            if near.any():
                qq, ii = q[near], idx[near]
                ii = np.where(ii < self.tree.n, ii, ii[:, :1])        # pad misses with the nearest
                tri = self.mesh.triangles[self.faces[ii.reshape(-1)]]
                rep = np.repeat(qq, KNN, 0)
                cp = trimesh.triangles.closest_point(tri, rep)
                d[near] = np.minimum(np.linalg.norm(cp - rep, axis=1).reshape(-1, KNN).min(1), self.band)
            inside = self.mesh.ray.contains_points(q)
            out[s:s + chunk] = np.where(inside, -d, d)
        return out


@dataclass
class Samples:
    q: np.ndarray        # float32 [N, 3] normalised positions in [-1, 1]^3
    d: np.ndarray        # float32 [N] truncated distance, normalised units, in [-τ, τ]
    near: np.ndarray     # bool [N]: a near-surface sample (else uniform)
    seconds: float = 0.0


def make_samples(mesh, frame: Frame, n: int, truncation: float, *, uniform_fraction: float = UNIFORM_FRACTION,
                 near_sigmas=NEAR_SIGMAS, seed: int = 0, query: DistanceQuery | None = None) -> Samples:
    """``n`` training samples: (1 - uniform_fraction) near the surface (surface points plus a
    Gaussian offset, σ drawn per point from ``near_sigmas``, normalised units), the rest uniform in
    the cube [-1, 1]^3; targets clamp(d / radius, -τ, τ)."""
    import trimesh

    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    query = query or DistanceQuery(mesh, truncation * frame.radius, seed)
    n_near = int(round(n * (1.0 - uniform_fraction)))
    surf, _ = trimesh.sample.sample_surface(mesh, n_near, seed=seed + 1)
    sig = np.asarray(near_sigmas, np.float64)[rng.integers(0, len(near_sigmas), n_near)] * frame.radius
    near_p = surf + rng.normal(size=(n_near, 3)) * sig[:, None]
    q = np.concatenate([frame.normalise(near_p), rng.uniform(-1.0, 1.0, (n - n_near, 3))])
    q = np.clip(q, -1.0, 1.0)
    d = query(frame.world(q)) / frame.radius
    near = np.arange(n) < n_near
    return Samples(q.astype(np.float32), np.clip(d, -truncation, truncation).astype(np.float32), near,
                   time.perf_counter() - t0)


def sample_batches(samples: Samples, batch: int, seed: int = 0, device="cpu"):
    """Endless (x in [0, 1]^3, target [B, 1]) batches on ``device``: epochs over the samples in a
    seeded random order (drawn on a CPU generator, then moved: the same order on every device)."""
    x = torch.from_numpy(samples.q * np.float32(0.5) + np.float32(0.5)).to(device)
    y = torch.from_numpy(samples.d)[:, None].to(device)
    gen = torch.Generator().manual_seed(seed)
    while True:
        order = torch.randperm(len(x), generator=gen).to(device)
        for s in range(0, len(x) - batch + 1 if len(x) >= batch else 1, batch):
            idx = order[s:s + batch]
            yield x[idx], y[idx]


def nearest_init(samples: Samples):
    """The paper's cascaded init: at each cell point x in [0, 1]^3 (the primary is the identity
    ramp, so x is also a position), the truncated distance of the nearest training sample."""
    from scipy.spatial import cKDTree

    tree = cKDTree(samples.q * 0.5 + 0.5)

    def target(x):
        _, i = tree.query(np.asarray(x, np.float64), k=1, workers=-1)
        return samples.d[i][:, None]
    return target



# ---------------------------------------------------------------------------------------------
# evaluation (shared with the MLP SDF comparison in techniques/di_sdf/bench.py)

@dataclass
class EvalSet:
    surface: np.ndarray          # world points on the mesh [S, 3]
    surface_normals: np.ndarray  # their face normals [S, 3]
    uniform: np.ndarray          # world points uniform in the bound cube [U, 3]
    inside: np.ndarray           # bool [U]: inside the mesh


def eval_set(mesh, frame: Frame, n_surface: int = 20000, n_uniform: int = 100000, seed: int = 123) -> EvalSet:
    import trimesh

    pts, fid = trimesh.sample.sample_surface(mesh, n_surface, seed=seed)
    u = frame.world(np.random.default_rng(seed).uniform(-1.0, 1.0, (n_uniform, 3)))
    return EvalSet(pts.astype(np.float32), mesh.face_normals[fid].astype(np.float32), u.astype(np.float32),
                   mesh.ray.contains_points(u))


def sdf_metrics(sdf, ev: EvalSet, normal_eps: float, radius: float) -> dict:
    """Surface error (mean and 95th percentile |d| at mesh surface points, world units and per
    bound radius), IoU of inside (d < 0) on uniform points in the bound cube, and the normal angle
    error (degrees; central differences with ``normal_eps``, as the shader) at the surface points.
    ``sdf``: any p [N, 3] -> d [N] torch callable (NetworkSdfModule, SdfModule)."""
    from inshade.models.sdf import normals

    with torch.no_grad():
        surf = torch.from_numpy(ev.surface)
        d_s = sdf(surf).double().numpy()
        d_u = sdf(torch.from_numpy(ev.uniform)).numpy()
        n = normals(sdf, surf, normal_eps).double().numpy()
    pred_in = d_u < 0
    iou = float((pred_in & ev.inside).sum() / max(1, (pred_in | ev.inside).sum()))
    cos = np.clip((n * ev.surface_normals).sum(1), -1.0, 1.0)
    ang = np.degrees(np.arccos(np.where(np.isfinite(cos), cos, -1.0)))
    return {"surface_mae": float(np.abs(d_s).mean()), "surface_p95": float(np.percentile(np.abs(d_s), 95)),
            "surface_mae_per_radius": float(np.abs(d_s).mean() / radius), "iou": iou,
            "normal_deg_mean": float(ang.mean()), "normal_deg_median": float(np.median(ang))}
