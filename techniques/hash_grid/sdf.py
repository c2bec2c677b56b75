"""The SDF application: a hash grid + MLP signed distance of a watertight mesh, sphere traced by the
sdf technique's pass (scene.json ``"sdf": {"network": "."}``) through the network-SDF contract
(models/network_sdf.py: the graph sees q = (p - center) / radius, its output times radius is the
world distance).

Frame: ``center`` is the centre of the mesh's bounding box and ``radius`` its farthest vertex from
it grown by 8% (geometry/mesh.py bounding_sphere, as neural_sdf). The grid's box is the cube
[center - radius, center + radius]^3, mapped onto the encoding's [0, 1]^3 by a frozen dense node
``to_unit`` (x = 0.5 q + 0.5): a power-of-two scale, exact in float32 on both sides, so the grid
reads the same cells in torch and GLSL. The traced bound sphere lies inside that cube.

Training (the torch twin): models/mlp_sdf_fit.py's samples (1/4 on the surface, 1/2 pushed off it
by Gaussian offsets, 1/4 uniform in the cube; exact signed distances), L1 on the normalised
distance plus an eikonal term ``eikonal * mean((|grad f| - 1)^2)`` on the off-surface points, the
gradient by forward differences a quarter of the finest cell long (the twin's encoding passes no
gradient to its input).

Safe step. A hash grid has no weight bound by construction: ``lipschitz.sound_bound`` gives one
from the table (per level: largest neighbouring-vertex difference x scale; a hashed level's range)
through the MLP's weights, sound but loose (its hashed levels' ranges). The shipped step is
``1 / (safety * L_measured)``, L_measured the largest slope measured over short segments at many
points (``lipschitz.measured_slope``): the eikonal term keeps the true slope near 1, so the step
stays near 1 where the sound bound would make rays crawl. ``max_steps`` is set on its own (1024 for the
shipped rabbit): with a hit distance of 2e-4 of the radius, rays grazing the ears ran out of the 216
steps ``mlp_sdf.trace_settings`` allows at that step and showed as holes. That choice is checked, not assumed:
tests/techniques/hash_grid/test_hash_grid_technique.py traces the shipped asset from its views in GLSL and finds no leak
pixel, and proves with the sound bound (lipschitz.certify_positive) that no ray of its view stepped
over a surface: the network is positive along every miss and up to every hit.
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import torch

from inshade.components.dense.torch_twin import Dense
from inshade.files import atomic_write
from inshade.geometry.mesh import DEFAULT_OUT as DEFAULT_MESH, bounding_sphere, load_mesh
from inshade.geometry.sdf import f32
from inshade.lit_settings import lit_settings
from inshade.models.graph import GraphModule
from inshade.models.mlp_sdf import trace_settings
from inshade.models.mlp_sdf_fit import BOUND_MARGIN, SIGMAS, sample_points, signed_distance
from inshade.models.network_sdf import NetworkSdfModule
from inshade.provenance import recorded_at
from inshade.scene.builder import display_modes, network_sdf, orbit_around, requires, scene_json, sky

from .lipschitz import measured_slope, sound_bound
from .network import add_frequency_mlp, add_hash_grid, add_mlp, grid_shape, network_bytes, optimizer

KIND = "hash_grid_sdf"
RENDER_PROGRAM = "passes/sdf_diffuse.frag"
ALBEDO = (0.8, 0.8, 0.8)
TO_UNIT = 0.5          # x = 0.5 q + 0.5: the cube around the bound sphere onto [0, 1]^3


def mesh_or_rabbit(mesh) -> Path:
    """``mesh``, or the procedural rabbit neural_sdf fits (generated into DEFAULT_MESH once)."""
    if mesh is None:
        from inshade.geometry.mesh import write_bunny

        mesh = DEFAULT_MESH if DEFAULT_MESH.is_file() else write_bunny(DEFAULT_MESH)
    return Path(mesh)


def to_unit_node() -> Dense:
    d = Dense(3, 3, bias=True)
    with torch.no_grad():
        d.linear.weight.copy_(torch.eye(3) * TO_UNIT)
        d.linear.bias.fill_(TO_UNIT)
    for p in d.parameters():
        p.requires_grad_(False)
    return d


def sdf_grid_shape(s):
    return grid_shape(3, levels=s.levels, features=s.features, base_resolution=s.base_resolution,
                      finest=s.finest, budget_bytes=int(s.budget_kb * 1024), width=s.width, depth=s.depth,
                      out_dim=1, log2_table_size=s.log2_table_size)


def build(s, seed: int = 0) -> GraphModule:
    """q[3] -> to_unit -> hash grid -> MLP -> distance / radius."""
    g = GraphModule([("q", 3, "position")])
    g.add("to_unit", to_unit_node(), "q")
    g.output("distance", add_mlp(g, add_hash_grid(g, "to_unit", sdf_grid_shape(s), seed), s.width, s.depth, 1), "sdf")
    return g


def build_baseline(s, budget_bytes: int) -> GraphModule:
    """The MLP-only SDF of ``budget_bytes``: frequency encoding of q + ReLU MLP."""
    g = GraphModule([("q", 3, "position")])
    g.output("distance", add_frequency_mlp(g, "q", s.n_freqs, s.baseline_depth, 1, budget_bytes), "sdf")
    return g


def training_tensors(data: dict, center, radius: float, device):
    parts = ("surface", "near", "uniform")
    c = np.asarray(center, np.float64)
    q = np.concatenate([(data[k] - c) / radius for k in parts]).astype(np.float32)
    d = np.concatenate([data[k + "_sdf"] / radius for k in parts]).astype(np.float32)
    off_surface = np.concatenate([np.zeros(len(data["surface"]), bool), np.ones(len(data["near"]), bool),
                                  np.ones(len(data["uniform"]), bool)])
    return (torch.from_numpy(q).to(device), torch.from_numpy(d).to(device), torch.from_numpy(off_surface).to(device))


def fit(g: GraphModule, q, d, off, *, steps: int, batch: int, seed: int, lrs: dict, eikonal: float, h: float,
        desc: str = "hash_grid sdf") -> dict:
    """Adam (network.optimizer), cosine decay: L1 on the normalised distance plus the eikonal term on a
    quarter of the batch's off-surface points (forward differences of length ``h`` in q units)."""
    from inshade.models.fit_loop import cosine, fit as fit_steps

    device = q.device
    opt = optimizer(g, **lrs)
    gen = torch.Generator().manual_seed(seed)
    eye = torch.eye(3, device=device) * h
    losses, start = [], time.perf_counter()

    def step_loss(step):
        idx = torch.randint(0, q.shape[0], (batch,), generator=gen).to(device)
        qb = q[idx]
        l1 = (g(qb)[:, 0] - d[idx]).abs().mean()
        loss = l1
        if eikonal > 0:
            pe = qb[off[idx]][: batch // 4]
            f0 = g(pe)
            grad = torch.cat([(g(pe + eye[k]) - f0) / h for k in range(3)], 1)
            loss = loss + eikonal * ((grad.norm(dim=1) - 1.0) ** 2).mean()
        return loss, l1

    def after(step, returned, bar):
        if step % 100 == 0 or step == steps - 1:
            l1 = float(returned[1].detach())
            losses.append((step, round(l1, 7)))
            bar.set_postfix(l1=f"{l1:.2e}")

    fit_steps(opt, step_loss, steps, lr_factor=cosine(steps, 0.02), after_step=after, desc=desc)
    return {"seconds": time.perf_counter() - start, "l1": losses}


def surface_metrics(f, mesh, center, radius: float, diagonal: float, held: dict, mc_resolution: int) -> dict:
    """Quality in world units and relative to the mesh's bounding-box diagonal: mean |f| on points of
    the true surface, mean |error| near it and in the cube, inside/outside IoU (uniform points), and
    the distance to the true mesh of the network's zero set (marching cubes vertices, mean and 95th
    percentile)."""
    with torch.no_grad():
        pred = {k: f(torch.from_numpy(held[k].astype(np.float32))).double().numpy()
                for k in ("surface", "near", "uniform")}
    out = {"surface_abs_mean": float(np.abs(pred["surface"]).mean()),
           "near_abs_err_mean": float(np.abs(pred["near"] - held["near_sdf"]).mean()),
           "uniform_abs_err_mean": float(np.abs(pred["uniform"] - held["uniform_sdf"]).mean())}
    inside_t, inside_p = held["uniform_sdf"] < 0, pred["uniform"] < 0
    out["iou_uniform"] = float((inside_t & inside_p).sum() / max(1, (inside_t | inside_p).sum()))
    zero = zero_set_points(f, center, radius, mc_resolution)
    if len(zero):
        dist = np.abs(signed_distance(mesh, zero))
        out["zero_set_to_mesh_mean"] = float(dist.mean())
        out["zero_set_to_mesh_p95"] = float(np.percentile(dist, 95))
    for k in [k for k in out if k != "iou_uniform"]:
        out[k + "_per_diagonal"] = out[k] / diagonal
    out["diagonal"] = diagonal
    out["mc_resolution"] = mc_resolution
    return out


def zero_set_points(f, center, radius: float, res: int) -> np.ndarray:
    """Marching-cubes vertices of f = 0 over the cube (world units)."""
    from skimage.measure import marching_cubes

    c = np.asarray(center, np.float64)
    axis = np.linspace(-radius, radius, res)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3) + c
    with torch.no_grad():
        pts = torch.from_numpy(grid.astype(np.float32))
        field = torch.cat([f(pts[i:i + 65536]) for i in range(0, len(pts), 65536)]).numpy().reshape(res, res, res)
    if not (field.min() < 0 < field.max()):
        return np.zeros((0, 3))
    v, _, _, _ = marching_cubes(field, 0.0, spacing=(axis[1] - axis[0],) * 3)
    return v - radius + c


def slope_points(center, radius: float, held: dict, n_lattice: int, seed: int) -> torch.Tensor:
    """Where the slope is measured: a lattice over the bound sphere's cube and the held-out points."""
    axis = np.linspace(-radius, radius, n_lattice)
    lattice = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3) + np.asarray(center)
    jitter = np.random.default_rng(seed).uniform(-0.5, 0.5, lattice.shape) * (axis[1] - axis[0])
    pts = np.concatenate([lattice + jitter, held["surface"], held["near"], held["uniform"]])
    inside = np.linalg.norm(pts - np.asarray(center), axis=1) <= radius
    return torch.from_numpy(pts[inside].astype(np.float32))


def train(run) -> int:
    s = run.settings
    torch.manual_seed(s.seed)
    mesh_path = mesh_or_rabbit(run.args.mesh)
    tri = load_mesh(mesh_path, require_watertight=True)
    center, radius = bounding_sphere(tri, BOUND_MARGIN)
    center, radius = tuple(f32(c) for c in center), f32(radius)
    lo, hi = tri.bounds
    diagonal = float(np.linalg.norm(hi - lo))
    t0 = time.perf_counter()
    data = sample_points(tri, center, radius, s.samples, s.seed)
    held = sample_points(tri, center, radius, max(4000, s.samples // 10), s.seed + 1)
    data_seconds = time.perf_counter() - t0
    shape = sdf_grid_shape(s)
    h = 0.25 * 2.0 / (shape.finest_resolution() - 1)      # a quarter of the finest cell, in q units
    q, d, off = training_tensors(data, center, radius, run.device)
    lrs = dict(grid_lr=s.grid_lr, mlp_lr=s.mlp_lr, grid_eps=s.grid_eps, mlp_eps=s.mlp_eps, mlp_l2=s.mlp_l2)
    g = build(s, s.seed).to(run.device)
    log = fit(g, q, d, off, steps=s.steps, batch=s.batch, seed=s.seed, lrs=lrs, eikonal=s.eikonal, h=h)
    g = g.cpu().eval()

    probe = NetworkSdfModule(g, None, center, radius, ALBEDO, run.out.name)
    world_h = h * radius
    points = slope_points(center, radius, held, s.slope_lattice, s.seed)
    measured = measured_slope(probe, points, world_h, s.seed)
    sound = sound_bound(g, input_scale=TO_UNIT)
    hit_eps = s.hit_eps
    trace = {**trace_settings(s.step_safety * measured, radius, hit_eps), "max_steps": s.max_steps}
    module = NetworkSdfModule(g, trace, center, radius, ALBEDO, run.out.name)
    quality = surface_metrics(module, tri, center, radius, diagonal, held, s.mc_resolution)
    box = {"min": [f32(c - radius) for c in center], "max": [f32(c + radius) for c in center],
           "mesh_bounds": [[float(v) for v in lo], [float(v) for v in hi]]}
    metrics = {**quality, "bytes": network_bytes(g), "params": int(sum(p.numel() for p in g.parameters())),
               "encoding": {"levels": shape.levels, "features": shape.features,
                            "log2_table_size": shape.log2_table_size, "base_resolution": shape.base_resolution,
                            "per_level_scale": shape.per_level_scale, "finest_resolution": shape.finest_resolution(),
                            "table_rows": shape.rows(), "table_bytes_fp16": shape.table_bytes()},
               "lipschitz_measured": measured, "lipschitz_sound": sound, "step_safety": s.step_safety,
               "step_scale": trace["step_scale"], "sound_step_scale": f32(1.0 / sound),
               "grid_box": box, "data_seconds": round(data_seconds, 1), "train_seconds": round(log["seconds"], 1),
               "final_l1_normalised": log["l1"][-1][1] if log["l1"] else None, "l1_batches": log["l1"],
               "train_threads": torch.get_num_threads(), "device": str(run.device)}
    if s.baseline_steps > 0:
        metrics["mlp_baseline"] = baseline(s, q, d, off, tri, center, radius, diagonal, held, network_bytes(g),
                                           lrs, h, run.device)
    metrics["neural_sdf_shipped"] = shipped_neural_sdf(tri, center, radius, diagonal, held, s.mc_resolution,
                                                       mesh_path)
    provenance = {
        "command": run.command, "preset": run.preset, "settings": run.record()["settings"],
        "mesh": str(mesh_path), "mesh_faces": int(len(tri.faces)),
        "grid_box": box,
        "contract": "q = (p - center) / radius; x = 0.5 q + 0.5 (to_unit, frozen) in [0, 1]^3 is the grid's "
                    "input: the cube grid_box; distance = radius * graph(q)",
        "sampling": f"{s.samples}: 1/4 on the surface, 1/2 surface + N(0, ({SIGMAS[0]}r, {SIGMAS[1]}r)), "
                    "1/4 uniform in the cube; exact signed distance",
        "loss": f"L1 on distance / radius + {s.eikonal} * eikonal (forward differences, {h:.3g} in q)",
        "step": f"step_scale = 1 / ({s.step_safety} * measured slope {measured:.4g}); sound bound {sound:.4g}",
        "device": str(run.device), "torch": torch.__version__,
        **recorded_at(),
    }
    bundle = module.export(KIND, run.out.name, provenance=provenance, metrics={
        k: v for k, v in metrics.items() if k not in ("mlp_baseline", "neural_sdf_shipped", "l1_batches")})
    from .image import bundle_file_bytes, save_fp16

    save_fp16(bundle, run.out)
    metrics["bytes_file"] = bundle_file_bytes(run.out)
    write_scene(run.out, center, radius, metrics)
    if run.args.preview:
        write_preview(run.out)
    run.write_metrics(metrics)
    base = metrics.get("mlp_baseline")
    print(f"wrote {run.out}: surface |f| {metrics['surface_abs_mean_per_diagonal']:.2e} of the diagonal, "
          f"zero set to mesh {metrics.get('zero_set_to_mesh_mean_per_diagonal', math.nan):.2e}, IoU "
          f"{metrics['iou_uniform']:.4f}, slope {measured:.3f} (sound bound {sound:.3g}) -> step "
          f"{trace['step_scale']:.3f}, {metrics['bytes']} bytes"
          + (f"; MLP-only at {base['bytes']} bytes: {base['surface_abs_mean_per_diagonal']:.2e}" if base else ""))
    return 0


def baseline(s, q, d, off, tri, center, radius, diagonal, held, budget_bytes, lrs, h, device) -> dict:
    """The MLP-only SDF of the hash grid's bytes, same samples, loss and optimiser settings."""
    torch.manual_seed(s.seed)
    g = build_baseline(s, budget_bytes).to(device)
    log = fit(g, q, d, off, steps=s.baseline_steps, batch=s.batch, seed=s.seed,
              lrs={**lrs, "mlp_lr": s.baseline_lr}, eikonal=s.eikonal, h=h, desc="mlp baseline")
    g = g.cpu().eval()
    module = NetworkSdfModule(g, None, center, radius, ALBEDO, "mlp")
    widths = [m.linear.out_features for m in g.nodes.values() if m.type == "dense"]
    return {**surface_metrics(module, tri, center, radius, diagonal, held, s.mc_resolution),
            "bytes": network_bytes(g), "network": f"frequency({s.n_freqs}) -> " + " -> ".join(
                f"dense {w}" for w in widths), "steps": s.baseline_steps, "batch": s.batch,
            "lr": s.baseline_lr, "train_seconds": round(log["seconds"], 1), "l1_batches": log["l1"]}


def shipped_neural_sdf(tri, center, radius, diagonal, held, mc_resolution, mesh_path) -> dict | None:
    """neural_sdf's shipped network (trained/prt_neural_bunny/sdf, the procedural rabbit) measured
    the same way, when the mesh is that rabbit."""
    from inshade.bundle import load

    folder = Path(__file__).resolve().parents[2] / "trained" / "prt_neural_bunny" / "sdf"
    if not folder.is_dir() or Path(mesh_path).resolve() != DEFAULT_MESH.resolve():
        return None
    module = NetworkSdfModule.from_bundle(load(folder))
    g = module.graph
    return {**surface_metrics(module, tri, center, radius, diagonal, held, mc_resolution),
            "bytes": network_bytes(g), "folder": "trained/prt_neural_bunny/sdf"}


def orbit_camera(center, radius: float, yaw: float = -30.0, pitch: float = -15.0) -> dict:
    return orbit_around(center, radius, yaw, pitch)


def write_scene(out: Path, center, radius: float, metrics: dict) -> None:
    scene = scene_json(
        out.name, f"Hash grid SDF: procedural rabbit, {metrics['bytes'] / 1024:.0f} KiB, surface error "
                  f"{metrics['surface_abs_mean_per_diagonal']:.1e} of the diagonal",
        RENDER_PROGRAM, (256, 256), networks=[],
        sdf=network_sdf(),
        notes={"grid_box": metrics["grid_box"],
               "contract": "the hash grid's [0, 1]^3 is the cube grid_box (min, max; world units) around "
                           "the bound sphere; mesh_bounds is the mesh's own bounding box"},
        camera=orbit_camera(center, radius),
        bookmarks={"front": orbit_camera(center, radius, 0.0, -10.0),
                   "ears": orbit_camera(center, radius * 0.6, 60.0, -35.0),
                   "top": orbit_camera(center, radius, -30.0, -80.0)},
        lights=[], environment=sky("noon"),
        display=display_modes("final", "network"),
        settings={**lit_settings()},
        requires=requires(),
    )
    atomic_write(out / "scene.json", json.dumps(scene, indent=1) + "\n")


def write_preview(out: Path, size: int = 256) -> None:
    """preview.png through the real shader path (inshade render)."""
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene
    from inshade.scene.image_io import write_png

    image, _ = render_scene(load_scene(out), width=size, height=size)
    write_png(out / "preview.png", np.asarray(image)[..., :3])
