"""DI-SDF: a truncated signed distance field learned from a mesh as a Differentiable Indirection
cascade (Differentiable Indirection, Datta et al. 2023 §4.1 and supp. §1.6).

    3D primary array (N_p³ × 3 channels, identity ramp, triangle F, 8-bit)
      -> 3D cascaded array (N_c³ × 1 channel: truncated distance, 8-bit)

The bundle graph is ``q -> to_unit -> primary -> cascaded``: ``q = (p - center) / radius`` is the
network-SDF contract (models/network_sdf.py, codegen/network_sdf.py: the graph sees the bound
sphere's unit ball, its output times ``radius`` is the world distance) and ``to_unit`` is a fixed
dense node ``0.5 q + 0.5`` that maps the cube [-1, 1]³ around that ball to the arrays' [0, 1]³.

Truncation (the band is ``truncation`` = τ, in normalised units, i.e. a fraction of the bound
radius; default 0.1): the target is ``clamp(d / radius, -τ, τ)``. The paper truncates to ±1 (a
sign field: only the zero crossing is learned); a linear band of a few primary cells keeps what a
sphere tracer and central-difference normals need -- distances near the surface -- and is the
paper's choice in the limit τ -> 0. After training the cascaded cells are clamped to [-τ, τ], so
every interpolated distance lies in the band too: the tracer (lib/sdf.glsl ``sdf_trace``) then
never steps more than ``τ · radius · step_scale``, i.e. its step is ``min(d, τ) · step_scale``
by construction, and stays inside the bound sphere. Far from the surface the field is flat at
+τ (steps of τ, ~2/τ of them across the bound), so ``max_steps`` is sized from τ (``trace_settings``).

Samples (paper: 1e9 near-surface + 2e7 uniform; here 4e5 by default: 12 s on the 2 shared cores
when quiet, 40 s under load, for a 40k-face mesh): surface points
pushed along a Gaussian (σ drawn from ``near_sigmas``, in normalised units) plus uniform points in
the cube. Signed distance: exact point-triangle distance to the candidate faces of the k nearest
dense surface samples (scipy cKDTree, queried only within the band -- points with no sample
closer than τ plus the sample spacing are beyond the band and get ±τ), sign from ray parity
through embree (``trimesh`` with ``embreex``). The cascaded array starts from the nearest
training sample's truncated distance at each cell (KD-tree, the paper's init); the primary is the
identity ramp. L1 loss, Adam with a cosine schedule, the primary's half-cell gradient clip
(notes §4.3), 8-bit export; the byte budget is solved by ``indirection.size_cascade``.

    from inshade.techniques.di_sdf.train import fit, load_mesh
    result = fit(load_mesh("bunny.ply"), budget_bytes=64 * 1024)
    result.bundle.save("trained/di_sdf")

Command: ``inshade train di_sdf [--mesh PATH] [--preset quick|ship] --budget-kb 64 --out DIR
[--device auto|cpu|cuda[:N]]`` (writes the bundle, scene.json, metrics.json and preview.png). The cascade
trains on the device; the signed distances (scipy, embree), the metrics, the export and the preview run on
the CPU. ``--preset ship`` without ``--mesh`` is exactly what built trained/di_sdf (3000 steps on the
procedural rabbit); ``quick``, the default, trains 1500 steps; metrics.json records the preset and the
resolved settings.
"""
from __future__ import annotations

import argparse
import datetime
import json
import math
import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from inshade.files import atomic_write
from inshade import asset_folder, command
from inshade.devices import DeviceError, add_device_argument, resolve_device
from inshade.lit_settings import lit_settings
from inshade.mesh import DEFAULT_OUT as DEFAULT_MESH

from inshade.models import indirection as di
from inshade.models.graph import GraphModule
from inshade.models.mlp import Dense
from inshade.models.network_sdf import NetworkSdfModule
from inshade.models.threads import torch_threads

KIND = "di_sdf"
RENDER_PROGRAM = "passes/sdf_diffuse.frag"
# Measured on the 2-core CPU with a ~40k-face mesh: lr 1e-2 + cosine reaches in ~1 min what the
# paper's 1e-3 does not in 5 (as for texture compression); rho 2 is the middle of the paper's
# [1.5, 2.5] for SDFs. monotonicity 0.2 (the paper's soft-monotonicity regulariser on the primary):
# without it the rabbit (inshade.mesh, 43.2 KB, 3000 steps) grows a floater between its ears -- a
# fold of the primary that maps free space onto the inside -- with it the floater is gone, at
# surface MAE 1.05e-3 vs 0.85e-3 of the radius, IoU 0.9918 vs 0.9928 (lr 3e-3 also removes it,
# at 1.30e-3 / 0.9887 in 1500 steps).
DEFAULTS = dict(budget_kb=64.0, rho=2.0, truncation=0.1, steps=1500, lr=1e-2, batch=16384, schedule="cosine",
                samples=400_000, uniform_fraction=0.25, near_sigmas=(0.005, 0.02, 0.05), margin=1.1, seed=0,
                clip_primary="auto", monotonicity=0.2)
# --preset: "ship" is what built trained/di_sdf; "quick" keeps the 1500-step default.
PRESETS = {"quick": dict(steps=1500), "ship": dict(steps=3000)}
SETTINGS = ("budget_kb", "rho", "truncation", "steps", "lr", "batch", "samples", "schedule", "monotonicity", "seed")
ALBEDO = (0.8, 0.8, 0.8)
KNN = 8                     # candidate faces per query point (from the k nearest surface samples)
SURFACE_SAMPLES = 200_000   # dense surface sample for the distance queries


def preset_settings(preset: str, asset: str | None = None) -> dict:
    """The settings ``--preset PRESET`` resolves to with no other option (one asset: ``asset`` is ignored)."""
    return {k: PRESETS[preset].get(k, DEFAULTS[k]) for k in SETTINGS}


class DiSdfError(ValueError):
    """A mesh or a setting DI-SDF cannot use; the message names the file / option."""


# ---------------------------------------------------------------------------------------------
# mesh and its frame

def load_mesh(path):
    """A closed triangle mesh from a file (inshade.mesh.load_mesh); one DiSdfError naming the file."""
    from inshade.mesh import MeshError, load_mesh as _load

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


def mesh_frame(mesh, margin: float = DEFAULTS["margin"]) -> Frame:
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


def make_samples(mesh, frame: Frame, n: int, truncation: float, *, uniform_fraction: float = DEFAULTS["uniform_fraction"],
                 near_sigmas=DEFAULTS["near_sigmas"], seed: int = 0, query: DistanceQuery | None = None) -> Samples:
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
# sizing, graph, trace settings

def plan(budget_bytes: float, rho: float = DEFAULTS["rho"]) -> di.Sizing:
    """Largest 8-bit 3D/3ch -> 3D/1ch cascade within the budget (N_p multiple of 8, N_c of 4)."""
    try:
        return di.size_cascade(int(budget_bytes), float(rho), primary_dims=3, primary_channels=3,
                               cascaded_dims=3, cascaded_channels=1)
    except ValueError as e:
        raise DiSdfError(f"--budget-kb {budget_bytes / 1024:g}: {e}") from None


def to_unit_node() -> Dense:
    """Fixed affine q in [-1, 1]^3 -> x = 0.5 q + 0.5 in [0, 1]^3 (exact in float32)."""
    d = Dense(3, 3, bias=True)
    with torch.no_grad():
        d.linear.weight.copy_(torch.eye(3) * 0.5)
        d.linear.bias.fill_(0.5)
    return d


def export_graph(core: GraphModule) -> GraphModule:
    """The bundle graph q -> to_unit -> primary -> cascaded (the trained arrays, shared)."""
    g = GraphModule([("q", 3, "position")])
    g.add("to_unit", to_unit_node(), "q")
    g.add("primary", core.nodes["primary"], "to_unit")
    g.add("cascaded", core.nodes["cascaded"], "primary")
    g.output("distance", "cascaded", "sdf")
    for p in g.parameters():
        p.requires_grad_(False)
    return g


def trace_settings(frame: Frame, truncation: float, n_primary: int, step_scale: float = 0.8) -> dict:
    """Sphere tracing for a truncated field. Steps are at most τ·radius·step_scale; crossing the
    bound (diameter 2 radius) flat at +τ takes 2 / (τ step_scale) steps, plus 48 to converge (grazing
    rays approach slowly). hit_eps: a twentieth of a primary cell; normal_eps: half a primary cell (the
    field is trilinear per cell: a smaller step sees cell facets, a larger one blurs detail)."""
    cell = 2.0 / (n_primary - 1) * frame.radius
    return {"max_steps": int(min(1024, math.ceil(2.0 / (truncation * step_scale)) + 48)),
            "step_scale": step_scale, "hit_eps": 0.05 * cell, "normal_eps": 0.5 * cell}


def fast_path_bound(bundle) -> float:
    """World-space bound on |fast - exact| of ``scene_sdf`` (hardware-filtered lookups): the
    lookup-array bound of tests/test_lookup_array.py, ``3 * 2^-8 * D + 2^-9 * scale`` per 3D array
    (D its largest adjacent-cell difference), with the primary's error e_k on channel k carried
    through the cascaded array's slope along axis k, ``D_c * (N_c - 1)``:

        e = 3 * 2^-8 * D_c + 2^-9 * s_c + sum_k D_c * (N_c - 1) * (3 * 2^-8 * D_p,k + 2^-9 * s_p,k)

    times the bound radius."""
    from inshade.bundle import Bundle

    g = GraphModule.from_bundle(Bundle(bundle.meta, bundle.tensors))
    tp = g.nodes["primary"].table().detach().double().numpy()
    tc = g.nodes["cascaded"].table().detach().double().numpy()
    d_p = np.array([max(float(np.abs(np.diff(tp[..., k], axis=a)).max()) for a in range(3)) for k in range(3)])
    d_c = max(float(np.abs(np.diff(tc[..., 0], axis=a)).max()) for a in range(3))
    s_p = bundle.tensors["primary.scale"].astype(np.float64)
    (s_c,) = bundle.tensors["cascaded.scale"].astype(np.float64)
    n_c = bundle.node("cascaded").params["resolution"][0]
    e_p = 3 * 2.0 ** -8 * d_p + 2.0 ** -9 * s_p
    e = 3 * 2.0 ** -8 * d_c + 2.0 ** -9 * s_c + float(np.sum(d_c * (n_c - 1) * e_p))
    return e * float(bundle.meta["render"]["sdf"]["radius"])


def sdf_module(bundle) -> NetworkSdfModule:
    """The torch scene of an exported DI-SDF bundle (trace/center/radius from render.sdf)."""
    return NetworkSdfModule.from_bundle(bundle)


# ---------------------------------------------------------------------------------------------
# metrics (shared with the MLP SDF comparison in techniques/di_sdf/bench.py)

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


# ---------------------------------------------------------------------------------------------
# fit

@dataclass
class Result:
    graph: GraphModule
    bundle: object
    module: NetworkSdfModule
    history: di.History
    frame: Frame
    sizing: di.Sizing
    metrics: dict = field(default_factory=dict)


def fit(mesh, budget_bytes: float = DEFAULTS["budget_kb"] * 1024, *, rho: float = DEFAULTS["rho"],
        truncation: float = DEFAULTS["truncation"], steps: int = DEFAULTS["steps"], lr: float = DEFAULTS["lr"],
        batch: int = DEFAULTS["batch"], schedule: str = DEFAULTS["schedule"], samples: int = DEFAULTS["samples"],
        uniform_fraction: float = DEFAULTS["uniform_fraction"], near_sigmas=DEFAULTS["near_sigmas"],
        margin: float = DEFAULTS["margin"], seed: int = DEFAULTS["seed"], clip_primary=DEFAULTS["clip_primary"],
        monotonicity: float = DEFAULTS["monotonicity"], name: str = KIND, provenance: dict | None = None,
        progress: bool | None = None, evaluate: bool = True, threads: int | None = 1, device="cpu") -> Result:
    """Learn a DI-SDF of ``mesh`` (a closed trimesh) within ``budget_bytes`` (8-bit cells).
    Returns the Result; the bundle holds 8-bit arrays and ``render.sdf`` (frame + trace settings).
    ``threads``: torch intra-op threads while fitting (None: leave torch's setting). ``device``
    (a torch.device or its name): where the cascade trains; the Result's graph is on the CPU."""
    with torch_threads(threads):
        return _fit(mesh, budget_bytes, rho, truncation, steps, lr, batch, schedule, samples, uniform_fraction,
                    near_sigmas, margin, seed, clip_primary, monotonicity, name, provenance, progress, evaluate,
                    torch.device(device))


def _fit(mesh, budget_bytes, rho, truncation, steps, lr, batch, schedule, samples, uniform_fraction, near_sigmas,
         margin, seed, clip_primary, monotonicity, name, provenance, progress, evaluate, device) -> Result:
    mesh = check_mesh(mesh)
    if not 0.0 < truncation <= 1.0:
        raise DiSdfError(f"--truncation must be in (0, 1] (a fraction of the bound radius), got {truncation}")
    if steps < 0 or batch < 1 or samples < batch:
        raise DiSdfError(f"need steps >= 0, batch >= 1 and samples >= batch (got {steps}, {batch}, {samples})")
    sizing = plan(budget_bytes, rho)
    frame = mesh_frame(mesh, margin)
    query = DistanceQuery(mesh, truncation * frame.radius, seed)
    train = make_samples(mesh, frame, samples, truncation, uniform_fraction=uniform_fraction,
                         near_sigmas=near_sigmas, seed=seed, query=query)
    held = make_samples(mesh, frame, min(32768, samples), truncation, uniform_fraction=uniform_fraction,
                        near_sigmas=near_sigmas, seed=seed + 7, query=query)
    torch.manual_seed(seed)
    # initialised on the CPU, then moved: the same start on every device
    core = di.cascade(3, 1, sizing.n_primary, sizing.n_cascaded, cascaded_init="downsample",
                      cascaded_init_args={"target": nearest_init(train)}, input_name="x",
                      output_name="distance").to(device)
    x_eval = torch.from_numpy(held.q * np.float32(0.5) + np.float32(0.5)).to(device)
    t0 = time.perf_counter()
    history = di.train_cascade(core, sample_batches(train, batch, seed, device), steps, lr=lr, schedule=schedule,
                               seed=seed, eval_set=(x_eval, torch.from_numpy(held.d)[:, None].to(device)),
                               clip_primary=clip_primary, monotonicity=monotonicity, peak=2.0 * truncation,
                               progress=progress, desc=name)
    seconds = time.perf_counter() - t0
    core.cpu()    # clamp, metrics and export on the CPU
    with torch.no_grad():   # the band is a property of the array (see the module docstring)
        core.nodes["cascaded"].cells.clamp_(-truncation, truncation)
    graph = export_graph(core)
    trace = trace_settings(frame, truncation, sizing.n_primary)
    module = NetworkSdfModule(graph, trace, frame.center, frame.radius, ALBEDO, name)
    quant = di.quantised_copy(graph, 8)
    with torch.no_grad():
        l1_float = float(torch.mean(torch.abs(graph(torch.from_numpy(held.q))[:, 0] - torch.from_numpy(held.d))))
        l1_q = float(torch.mean(torch.abs(quant(torch.from_numpy(held.q))[:, 0] - torch.from_numpy(held.d))))
    metrics = {
        "bytes": sizing.bytes, "budget_bytes": int(budget_bytes), "n_primary": sizing.n_primary,
        "n_cascaded": sizing.n_cascaded, "rho": round(sizing.rho, 4), "truncation": truncation,
        "bytes_with_headers": sizing.bytes + 8 * 4 + 48,   # + per-channel scale/offset, + the fixed affine
        "center": list(frame.center), "radius": frame.radius, "faces": int(len(mesh.faces)),
        "samples": samples, "sample_seconds": round(train.seconds, 2), "train_seconds": round(seconds, 2),
        "steps": steps, "device": str(device), "heldout_l1_float": l1_float, "heldout_l1_quantised": l1_q,
        "history": [{"step": r["step"], "loss": round(r["loss"], 6), "seconds": round(r["seconds"], 2)}
                    for r in history.records],
    }
    prov = {
        "technique": "Differentiable Indirection SDF (Datta et al. 2023): 3D primary (3 ch, ramp, triangle F) -> "
                     "3D cascaded (1 ch, truncated distance, nearest-sample init); 8-bit arrays",
        "training": f"{samples} samples ({1 - uniform_fraction:.0%} near-surface, sigma {list(near_sigmas)} of the "
                    f"radius; rest uniform in the bound cube), truncation {truncation} of the radius, L1, Adam lr "
                    f"{lr:g}, {schedule}, batch {batch}, {steps} steps, primary clip {clip_primary}, seed {seed}",
        "contract": "q = (p - center) / radius; distance = radius * graph(q) (models/network_sdf.py)",
        "device": str(device),
        "torch": torch.__version__,
        "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }
    prov.update(provenance or {})
    bundle = graph.export(KIND, name, provenance=prov, metrics=metrics, render=module.render_meta())
    if evaluate:
        from inshade.bundle import Bundle

        qmod = NetworkSdfModule.from_bundle(Bundle(bundle.meta, bundle.tensors))
        metrics.update(sdf_metrics(qmod, eval_set(mesh, frame), trace["normal_eps"], frame.radius))
        bundle = graph.export(KIND, name, provenance=prov, metrics=metrics, render=module.render_meta())
    return Result(graph, bundle, module, history, frame, sizing, metrics)


# ---------------------------------------------------------------------------------------------
# asset folder

def orbit_camera(frame: Frame, yaw: float = -30.0, pitch: float = -20.0) -> dict:
    """An orbit camera framing the bound sphere (fov 40°)."""
    dist = frame.radius / math.sin(math.radians(20.0)) * 1.05
    return {"type": "orbit", "fov_y": 40.0, "target": list(frame.center), "distance": round(dist, 6),
            "yaw": yaw, "pitch": pitch}


def scene_dict(name: str, title: str, frame: Frame, lut_filter: str = "exact", size: int = 256) -> dict:
    cam = orbit_camera(frame)
    return {
        "format": "inshade.scene", "version": 1, "name": name, "title": title,
        "program": RENDER_PROGRAM, "size": [size, size], "networks": [],
        "sdf": {"network": "."},
        "camera": cam,
        "bookmarks": {"front": orbit_camera(frame, 0.0, -10.0), "top": orbit_camera(frame, -30.0, -80.0)},
        "lights": [], "environment": {"sky": "noon", "rotation": 0.0, "degree": 4},
        "display": {"mode": "final", "modes": ["final", "network"], "split": 0.5},
        "settings": {
            **lit_settings(),
            "lut_filter": {"type": "choice", "default": lut_filter, "choices": ["exact", "fast"],
                           "codegen": "lut_filter", "label": "LUT filtering"},
        },
        "requires": {"gl": 330},
    }


def render_torch(bundle, camera: dict, size: int, sky: str = "noon") -> dict:
    """The sdf_diffuse pass in torch (models/sdf.py render) for a DI-SDF bundle."""
    from inshade.codegen.sdf import environment_sh
    from inshade.runtime.camera import camera_from_dict

    cam = camera_from_dict(camera)
    return render_module(sdf_module(bundle), cam.uniforms(size, size), size, environment_sh(sky, 0.0))


def render_module(module, uniforms, size, sh) -> dict:
    """models/sdf.py ``render`` for any SDF module with ``.scene`` and ``.albedo`` (``render`` itself
    takes an analytic scene): {"rgba" [H, W, 4] linear, "hit" [H, W], "t" [H, W]}."""
    from inshade.models import sdf as sdf_mod

    coeffs = torch.as_tensor(np.asarray(sh, np.float32))
    ro, rd = sdf_mod.camera_rays(uniforms, size, size)
    hit, t = sdf_mod.trace(module, ro, rd)
    out = sdf_mod.sh_background_t(coeffs, rd)
    with torch.no_grad():
        if hit.any():
            idx = hit.nonzero().squeeze(1)
            p = ro[idx] + rd[idx] * t[idx, None]
            n = sdf_mod.normals(module, p)
            out[idx] = module.albedo(p) * sdf_mod.sh_irradiance_t(coeffs, n) * sdf_mod.INV_PI
    rgba = torch.cat([out, torch.ones(out.shape[0], 1)], -1)
    return {"rgba": rgba.reshape(size, size, 4).numpy(), "hit": hit.reshape(size, size).numpy(),
            "t": t.reshape(size, size).numpy()}


def write_asset(result: Result, out, title: str, lut_filter: str = "exact", preview_size: int = 128) -> Path:
    """bundle.json + weights.safetensors + scene.json + preview.png (torch render of the 8-bit bundle)."""
    from inshade.runtime.image_io import write_png

    out = Path(out)
    result.bundle.save(out)
    scene = scene_dict(out.name, title, result.frame, lut_filter)
    atomic_write(out / "scene.json", json.dumps(scene, indent=1) + "\n")
    img = render_torch(result.bundle, scene["camera"], preview_size)
    write_png(out / "preview.png", img["rgba"][..., :3])
    return out


# ---------------------------------------------------------------------------------------------
# command line

def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    d = DEFAULTS
    p.add_argument("--mesh", help="closed triangle mesh (PLY/OBJ/STL/GLB ...; default: the procedural rabbit, "
                   f"generated into {DEFAULT_MESH}, the shipped asset's)")
    asset_folder.add_arguments(p, "di_sdf_<mesh>")
    p.add_argument("--budget-kb", type=float, default=d["budget_kb"], help="bytes of 8-bit cells, KiB (default %(default)s)")
    p.add_argument("--rho", type=float, default=d["rho"], help="N_p / N_c (default %(default)s)")
    p.add_argument("--truncation", type=float, default=d["truncation"],
                   help="truncation band, fraction of the bound radius (default %(default)s)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="quick",
                   help="ship: exactly what built trained/di_sdf (3000 steps); quick: 1500 steps; "
                        "options given explicitly override it (default %(default)s)")
    p.add_argument("--steps", type=int, help="training steps (default: the preset's)")
    p.add_argument("--lr", type=float, default=d["lr"], help="Adam learning rate (default %(default)s)")
    p.add_argument("--batch", type=int, default=d["batch"], help="samples per step (default %(default)s)")
    p.add_argument("--samples", type=int, default=d["samples"], help="training samples (default %(default)s)")
    p.add_argument("--schedule", choices=sorted(di.SCHEDULES), default=d["schedule"])
    p.add_argument("--monotonicity", type=float, default=d["monotonicity"],
                   help="soft-monotonicity weight on the primary (paper supp. §2; default %(default)s)")
    p.add_argument("--seed", type=int, default=d["seed"])
    add_device_argument(p)
    p.add_argument("--lut-filter", choices=("exact", "fast"), default="exact", help="the scene's default LUT path")
    p.add_argument("--title", help="scene title")
    return p


def run(args, argv=None) -> int:
    device = resolve_device(args.device)   # first: a CUDA the machine lacks fails before any work
    args.out = str(asset_folder.claim(args.out, f"di_sdf_{Path(args.mesh or DEFAULT_MESH).stem}", force=args.force))
    if args.steps is None:
        args.steps = PRESETS[args.preset]["steps"]
    if args.mesh is None:     # the procedural rabbit (deterministic), as neural_sdf does
        from inshade.mesh import write_bunny

        args.mesh = str(DEFAULT_MESH if DEFAULT_MESH.is_file() else write_bunny(DEFAULT_MESH))
    mesh = load_mesh(args.mesh)
    argv = list(sys.argv[1:] if argv is None else argv)
    name = Path(args.out).name
    provenance_command = shlex.join(["inshade", "train", "di_sdf", *argv])
    result = fit(mesh, args.budget_kb * 1024, rho=args.rho, truncation=args.truncation, steps=args.steps, lr=args.lr,
                 batch=args.batch, samples=args.samples, schedule=args.schedule, seed=args.seed, name=name,
                 monotonicity=args.monotonicity, device=device,
                 provenance={"command": provenance_command, "mesh": str(args.mesh)})
    title = args.title or f"DI-SDF: {Path(args.mesh).name}, {result.metrics['bytes'] / 1024:.1f} KiB"
    out = write_asset(result, args.out, title, args.lut_filter)
    m = result.metrics
    # metrics.json: the preset, the settings it resolved to (tests/test_presets.py holds the shipped
    # asset's equal to preset_settings("ship")) and the bundle's metrics without the loss history
    settings = {k: getattr(args, k) for k in SETTINGS}
    atomic_write(out / "metrics.json", json.dumps({"command": provenance_command, "preset": args.preset,
                                                   "settings": settings,
                                                   **{k: v for k, v in m.items() if k != "history"}},
                                                  indent=1) + "\n")
    print(f"wrote {out}: {m['bytes']} bytes (N_p {m['n_primary']}, N_c {m['n_cascaded']}), surface MAE "
          f"{m['surface_mae_per_radius']:.2e} radius, IoU {m['iou']:.4f}, normals {m['normal_deg_mean']:.2f} deg, "
          f"samples {m['sample_seconds']:.1f} s, training {m['train_seconds']:.1f} s")
    return 0


def main(argv=None) -> int:
    return command.main("inshade train di_sdf", __doc__, add_arguments, run, argv, errors=(DiSdfError, DeviceError))

