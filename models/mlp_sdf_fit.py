"""Fitting an MLP SDF (models/mlp_sdf.py) to a watertight mesh: training points with exact signed
distances, the fit loop with its Lipschitz penalty, the held-out evaluation, and ``fit_mesh``,
which runs all of it and returns the folded network as a NetworkSdfModule with its metrics.

Data: area-weighted surface samples (trimesh, seeded) pushed off the surface by Gaussian offsets
(two scales, ``SIGMAS`` x radius) plus uniform samples in the bound's cube; exact signed distances
from the mesh by point-cloud-utils (libigl, C++; ~20k points/s on one shared core, where trimesh's
``closest_point`` does ~250/s), with trimesh (``closest_point`` + embree ``contains``) as the slow
fallback. The mesh must be watertight (inshade.geometry.mesh.load_mesh(require_watertight=True)).

Loss: L1 on distance / radius plus ``lipschitz_weight * relu(log L - log lipschitz_target)``, L the
bound of models/mlp_sdf.py, so the exported ``step_scale = min(0.9, 1/L)`` is safe. The price is
detail: on the procedural rabbit (32x3, 3000 steps) target 1.5 gives a Chamfer distance of
0.022 r and IoU 0.88, target 4 (step_scale 0.25) 0.014 r and 0.91, no penalty (bound ~30,
unsafe steps) 0.015 r after 400 steps; thin parts (the ears) need a larger target or network.
The bound sphere (mesh's, grown by 8%) and ``max_steps`` (trace_settings) cap every ray.

Metrics (held out, world units and relative to the radius): mean |network| on surface samples,
mean |d error| on near-surface and uniform samples, inside/outside IoU on uniform samples, and a
symmetric Chamfer distance between marching cubes of the network (64^3) and the mesh.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from inshade.geometry.mesh import bounding_sphere, load_mesh
from inshade.geometry.sdf import DEFAULT_ALBEDO, f32

from .graph import GraphModule
from .mlp_sdf import build, fold_beta, lipschitz_bound, trace_settings
from .network_sdf import NetworkSdfModule

SIGMAS = (0.01, 0.05)            # Gaussian offsets off the surface, x radius
BOUND_MARGIN = 0.08              # the bound sphere is the mesh's grown by 8% (room for normals, offsets)
DEFAULTS = dict(width=32, layers=3, freqs=0, activation="softplus", steps=3000, batch=8192, lr=2e-3,
                samples=300_000, seed=0, lipschitz_target=4.0, lipschitz_weight=0.05, hit_eps=1e-3)


# ---------------------------------------------------------------------------------------------
# data

def signed_distance(mesh, points: np.ndarray) -> np.ndarray:
    """Exact signed distance (negative inside) of points [N, 3] to a watertight mesh, float64."""
    points = np.ascontiguousarray(points, np.float64)
    try:
        import point_cloud_utils as pcu
    except ImportError:
        import trimesh

        _, dist, _ = trimesh.proximity.closest_point(mesh, points)
        return np.where(mesh.contains(points), -dist, dist)
    sd, _, _ = pcu.signed_distance_to_mesh(points, np.ascontiguousarray(mesh.vertices, np.float64),
                                           np.ascontiguousarray(mesh.faces, np.int64))
    return np.asarray(sd, np.float64)


def sample_points(mesh, center, radius: float, n: int, seed: int = 0, progress: bool = False) -> dict:
    """{"surface": [n/4, 3] points on the mesh, "near": [n/2, 3] Gaussian-offset points and
    "uniform": [n/4, 3] points in the bound's cube, each with "<name>_sdf"} (world units)."""
    import trimesh

    from inshade.progress import progress as progress_bar

    rng = np.random.default_rng(seed)
    n_s, n_n = n // 4, n // 2
    n_u = n - n_s - n_n
    surface, _ = trimesh.sample.sample_surface(mesh, n_s + n_n, seed=seed)
    sig = np.repeat(np.asarray(SIGMAS) * radius, (n_n + 1) // 2)[:n_n]
    near = surface[n_s:] + rng.normal(size=(n_n, 3)) * sig[:, None]
    uniform = np.asarray(center) + rng.uniform(-radius, radius, (n_u, 3))
    out = {"surface": surface[:n_s], "near": near, "uniform": uniform}
    for name in ("near", "uniform"):
        pts = out[name]
        chunks = np.array_split(np.arange(len(pts)), max(1, len(pts) // 20000))
        sd = [signed_distance(mesh, pts[c]) for c in progress_bar(chunks, desc=f"sdf {name}", enabled=progress)]
        out[name + "_sdf"] = np.concatenate(sd)
    out["surface_sdf"] = np.zeros(n_s)
    return out


# ---------------------------------------------------------------------------------------------
# fit and evaluation

def fit(graph: GraphModule, data: dict, center, radius: float, *, steps: int, batch: int, lr: float, seed: int,
        lipschitz_target: float, lipschitz_weight: float, progress: bool | None = None,
        desc: str = "mlp sdf") -> dict:
    """Adam on the L1 error of the normalised distance (surface, near and uniform samples
    mixed), cosine-decayed lr, plus the Lipschitz penalty. Runs on the graph's device (batch
    indices drawn on a CPU generator, then moved). Deterministic for a seed and device."""
    from .fit_loop import adam, cosine, fit as fit_steps

    device = next(graph.parameters()).device
    c = np.asarray(center, np.float64)
    inv_r = 1.0 / radius
    parts = ("surface", "near", "uniform")
    x = torch.from_numpy(np.concatenate([(data[k] - c) * inv_r for k in parts]).astype(np.float32)).to(device)
    y = torch.from_numpy(np.concatenate([data[k + "_sdf"] * inv_r for k in parts]).astype(np.float32)).to(device)
    opt = adam(graph.parameters(), lr=lr)
    gen = torch.Generator().manual_seed(seed)
    log_target = math.log(lipschitz_target)
    losses, start = [], time.perf_counter()

    def step_loss(step):
        idx = torch.randint(0, x.shape[0], (batch,), generator=gen).to(device)
        err = (graph(x[idx])[:, 0] - y[idx]).abs().mean()
        loss = err
        if lipschitz_weight > 0:
            lip = lipschitz_bound(graph, differentiable=True)
            loss = loss + lipschitz_weight * torch.relu(torch.log(lip) - log_target)
        return loss, err

    def after(step, returned, bar):
        if step % 100 == 0 or step == steps - 1:
            err = float(returned[1].detach())
            losses.append((step, err))
            bar.set_postfix(l1=f"{err:.2e}", L=f"{lipschitz_bound(graph):.2f}")

    fit_steps(opt, step_loss, steps, lr_factor=cosine(steps, 0.02), after_step=after, desc=desc, progress=progress)
    return {"seconds": time.perf_counter() - start, "losses": losses}


def evaluate(module: NetworkSdfModule, mesh, data: dict, radius: float, mc_resolution: int = 64) -> dict:
    """Held-out quality numbers (world units; ``*_rel`` divided by the radius)."""
    out = {}
    with torch.no_grad():
        pred = {k: module(torch.from_numpy(data[k].astype(np.float32))).double().numpy()
                for k in ("surface", "near", "uniform")}
    out["surface_abs_mean"] = float(np.abs(pred["surface"]).mean())
    out["near_abs_err_mean"] = float(np.abs(pred["near"] - data["near_sdf"]).mean())
    out["uniform_abs_err_mean"] = float(np.abs(pred["uniform"] - data["uniform_sdf"]).mean())
    inside_t, inside_p = data["uniform_sdf"] < 0, pred["uniform"] < 0
    out["iou_uniform"] = float((inside_t & inside_p).sum() / max(1, (inside_t | inside_p).sum()))
    out.update({k + "_rel": v / radius for k, v in list(out.items()) if k != "iou_uniform"})
    out.update(_chamfer(module, mesh, radius, mc_resolution))
    # empirical Lipschitz: max |grad| over the held-out samples (a lower bound on L)
    p = torch.from_numpy(np.concatenate([data["near"], data["uniform"]]).astype(np.float32)).requires_grad_(True)
    (g,) = torch.autograd.grad(module(p).sum(), p)
    out["grad_norm_max"] = float(g.norm(dim=1).max())
    out["grad_norm_mean_near"] = float(g[: len(data["near"])].norm(dim=1).mean())
    return out


def _chamfer(module: NetworkSdfModule, mesh, radius: float, res: int) -> dict:
    """Symmetric Chamfer (mean nearest-neighbour distance both ways, /2) between 20k samples of
    the network's marching-cubes surface and 20k samples of the mesh."""
    import trimesh
    from scipy.spatial import cKDTree
    from skimage.measure import marching_cubes

    c = np.asarray(module.scene.center, np.float64)
    axis = np.linspace(-radius, radius, res)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3) + c
    with torch.no_grad():
        field = module(torch.from_numpy(grid.astype(np.float32))).numpy().reshape(res, res, res)
    if not (field.min() < 0 < field.max()):
        return {"chamfer": math.inf, "chamfer_rel": math.inf}
    v, f, _, _ = marching_cubes(field, 0.0, spacing=(axis[1] - axis[0],) * 3)
    net_mesh = trimesh.Trimesh(v - radius + c, f, process=False)
    a, _ = trimesh.sample.sample_surface(net_mesh, 20000, seed=1)
    b, _ = trimesh.sample.sample_surface(mesh, 20000, seed=2)
    ch = 0.5 * (cKDTree(b).query(a)[0].mean() + cKDTree(a).query(b)[0].mean())
    return {"chamfer": float(ch), "chamfer_rel": float(ch / radius)}


# ---------------------------------------------------------------------------------------------
# all of it

@dataclass
class MeshSdfFit:
    module: NetworkSdfModule     # the folded network on the CPU, its trace settings from its bound
    metrics: dict                # held-out quality, the bound, sizes and timings
    mesh: object                 # the loaded trimesh


def fit_mesh(mesh, *, width=DEFAULTS["width"], layers=DEFAULTS["layers"], freqs=DEFAULTS["freqs"],
             activation=DEFAULTS["activation"], steps=DEFAULTS["steps"], batch=DEFAULTS["batch"], lr=DEFAULTS["lr"],
             samples=DEFAULTS["samples"], seed=DEFAULTS["seed"], lipschitz_target=DEFAULTS["lipschitz_target"],
             lipschitz_weight=DEFAULTS["lipschitz_weight"], hit_eps=DEFAULTS["hit_eps"], albedo=DEFAULT_ALBEDO,
             name: str = "", progress: bool | None = None, mc_resolution: int = 64, device="cpu") -> MeshSdfFit:
    """Fit an MLP SDF to the watertight mesh file ``mesh`` on ``device`` (a torch.device or its
    name; the signed distances come from the mesh on the CPU), fold it, bound it, evaluate it on
    held-out points on the CPU. ``name`` is the module's (and the progress bar's)."""
    device = torch.device(device)
    torch.manual_seed(seed)
    tri = load_mesh(Path(mesh), require_watertight=True)
    center, radius = bounding_sphere(tri, BOUND_MARGIN)
    center, radius = tuple(f32(c) for c in center), f32(radius)
    t0 = time.perf_counter()
    data = sample_points(tri, center, radius, samples, seed, progress)
    held = sample_points(tri, center, radius, max(4000, samples // 10), seed + 1, progress)
    data_seconds = time.perf_counter() - t0
    # initialised on the CPU generator, then moved: the same start on every device
    graph = build(width, layers, freqs, activation).to(device)
    log = fit(graph, data, center, radius, steps=steps, batch=batch, lr=lr, seed=seed,
              lipschitz_target=lipschitz_target, lipschitz_weight=lipschitz_weight, progress=progress,
              desc=name or "mlp sdf")
    graph = fold_beta(graph.cpu())     # evaluation and export on the CPU
    lip = float(lipschitz_bound(graph))
    module = NetworkSdfModule(graph, trace_settings(lip, radius, hit_eps), center, radius, albedo, name)
    t1 = time.perf_counter()
    metrics = evaluate(module, tri, held, radius, mc_resolution)
    metrics.update({
        "lipschitz_bound": lip, "step_scale": module.scene.trace["step_scale"],
        "params": int(sum(p.numel() for p in graph.parameters())),
        "data_seconds": round(data_seconds, 2), "train_seconds": round(log["seconds"], 2),
        "eval_seconds": round(time.perf_counter() - t1, 2),
        "samples_per_second_sdf": round(1.1 * samples / max(data_seconds, 1e-9)),
        "final_l1_normalised": log["losses"][-1][1] if log["losses"] else None,
        "device": str(device),
    })
    return MeshSdfFit(module, metrics, tri)
