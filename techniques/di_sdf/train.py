"""DI-SDF: a truncated signed distance field learned from a mesh as a Differentiable Indirection
cascade (Differentiable Indirection, Datta et al. 2023 §4.1 and supp. §1.6).

The cascade, its bundle graph and the truncation band are techniques/di_sdf/model.py; the samples,
their signed distances and the metrics techniques/di_sdf/data.py. Training: L1 loss, Adam with a
cosine schedule, the primary's half-cell gradient clip (notes §4.3), 8-bit export; the byte budget
is solved by ``indirection.size_cascade``.

    from inshade.techniques.di_sdf.data import load_mesh
    from inshade.techniques.di_sdf.train import fit
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
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from inshade.files import atomic_write
from inshade.lit_settings import lit_settings
from inshade.geometry.mesh import DEFAULT_OUT as DEFAULT_MESH

from inshade.models import indirection as di
from inshade.models.fit_loop import history_rows
from inshade.models.graph import GraphModule
from inshade.models.network_sdf import NetworkSdfModule
from inshade.models.threads import torch_threads
from inshade.scene.builder import (display_modes, lut_filter_setting, network_sdf, orbit_around, requires,
                                    scene_json, sky)
from inshade.trainer import Run, Trainer, batch_setting, lr_setting, seed_setting, setting, steps_setting
from inshade.provenance import recorded_at

from .data import (MARGIN, NEAR_SIGMAS, UNIFORM_FRACTION, DiSdfError, DistanceQuery, Frame, check_mesh, eval_set,
                   load_mesh, make_samples, mesh_frame, nearest_init, sample_batches, sdf_metrics)
from .model import ALBEDO, RHO, export_graph, plan, sdf_module, trace_settings

KIND = "di_sdf"
RENDER_PROGRAM = "passes/sdf_diffuse.frag"
# Measured on the 2-core CPU with a ~40k-face mesh: lr 1e-2 + cosine reaches in ~1 min what the
# paper's 1e-3 does not in 5 (as for texture compression); rho 2 is the middle of the paper's
# [1.5, 2.5] for SDFs. monotonicity 0.2 (the paper's soft-monotonicity regulariser on the primary):
# without it the rabbit (inshade.geometry.mesh, 43.2 KB, 3000 steps) grows a floater between its ears -- a
# fold of the primary that maps free space onto the inside -- with it the floater is gone, at
# surface MAE 1.05e-3 vs 0.85e-3 of the radius, IoU 0.9918 vs 0.9928 (lr 3e-3 also removes it,
# at 1.30e-3 / 0.9887 in 1500 steps).
DEFAULTS = dict(budget_kb=64.0, rho=RHO, truncation=0.1, steps=1500, lr=1e-2, batch=16384, schedule="cosine",
                samples=400_000, uniform_fraction=UNIFORM_FRACTION, near_sigmas=NEAR_SIGMAS, margin=MARGIN, seed=0,
                clip_primary="auto", monotonicity=0.2)


@dataclass(frozen=True)
class Settings:
    """What a di_sdf run is built from (metrics.json records it; the mesh is an input beside it)."""
    budget_kb: float = setting(DEFAULTS["budget_kb"], "bytes of 8-bit cells, KiB")
    rho: float = setting(DEFAULTS["rho"], "N_p / N_c")
    truncation: float = setting(DEFAULTS["truncation"], "truncation band, fraction of the bound radius")
    steps: int = steps_setting(DEFAULTS["steps"])
    lr: float = lr_setting(DEFAULTS["lr"])
    batch: int = batch_setting(DEFAULTS["batch"])
    samples: int = setting(DEFAULTS["samples"], "training samples")
    schedule: str = setting(DEFAULTS["schedule"], "learning-rate schedule", choices=sorted(di.SCHEDULES))
    monotonicity: float = setting(DEFAULTS["monotonicity"], "soft-monotonicity weight on the primary (paper supp. §2)")
    seed: int = seed_setting(DEFAULTS["seed"])


# --preset: "ship" is what built trained/di_sdf; "quick" (the default) keeps the 1500-step default.
PRESETS = {"quick": dict(steps=1500), "ship": dict(steps=3000)}


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
        "history": history_rows(history.records, "loss", 6),
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
        **recorded_at(),
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
    return orbit_around(frame.center, frame.radius, yaw, pitch)


def scene_dict(name: str, title: str, frame: Frame, lut_filter: str = "exact", size: int = 256) -> dict:
    return scene_json(
        name, title, RENDER_PROGRAM, (size, size), networks=[],
        sdf=network_sdf(),
        camera=orbit_camera(frame),
        bookmarks={"front": orbit_camera(frame, 0.0, -10.0), "top": orbit_camera(frame, -30.0, -80.0)},
        lights=[], environment=sky("noon"),
        display=display_modes("final", "network"),
        settings={**lit_settings(), "lut_filter": lut_filter_setting(lut_filter)},
        requires=requires(),
    )


def render_torch(bundle, camera: dict, size: int, sky: str = "noon") -> dict:
    """The sdf_diffuse pass in torch (models/sdf.py render) for a DI-SDF bundle."""
    from inshade.codegen.sdf import environment_sh
    from inshade.scene.camera import camera_from_dict

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
    from inshade.scene.image_io import write_png

    out = Path(out)
    result.bundle.save(out)
    scene = scene_dict(out.name, title, result.frame, lut_filter)
    atomic_write(out / "scene.json", json.dumps(scene, indent=1) + "\n")
    img = render_torch(result.bundle, scene["camera"], preview_size)
    write_png(out / "preview.png", img["rgba"][..., :3])
    return out


# ---------------------------------------------------------------------------------------------
# command line

def extra_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--mesh", help="closed triangle mesh (PLY/OBJ/STL/GLB ...; default: the procedural rabbit, "
                   f"generated into {DEFAULT_MESH}, the shipped asset's)")
    p.add_argument("--lut-filter", choices=("exact", "fast"), default="exact", help="the scene's default LUT path")
    p.add_argument("--title", help="scene title")


def train(run: Run) -> int:
    s, args = run.settings, run.args
    mesh_path = args.mesh
    if mesh_path is None:     # the procedural rabbit (deterministic), as neural_sdf does
        from inshade.geometry.mesh import write_bunny

        mesh_path = str(DEFAULT_MESH if DEFAULT_MESH.is_file() else write_bunny(DEFAULT_MESH))
    mesh = load_mesh(mesh_path)
    result = fit(mesh, s.budget_kb * 1024, rho=s.rho, truncation=s.truncation, steps=s.steps, lr=s.lr,
                 batch=s.batch, samples=s.samples, schedule=s.schedule, seed=s.seed, name=run.out.name,
                 monotonicity=s.monotonicity, device=run.device,
                 provenance={"command": run.command, "mesh": str(mesh_path)})
    title = args.title or f"DI-SDF: {Path(mesh_path).name}, {result.metrics['bytes'] / 1024:.1f} KiB"
    out = write_asset(result, run.out, title, args.lut_filter)
    m = result.metrics
    return run.finish(out, m, f"{m['bytes']} bytes (N_p {m['n_primary']}, N_c {m['n_cascaded']}), surface MAE "
                              f"{m['surface_mae_per_radius']:.2e} radius, IoU {m['iou']:.4f}, normals "
                              f"{m['normal_deg_mean']:.2f} deg, samples {m['sample_seconds']:.1f} s, training "
                              f"{m['train_seconds']:.1f} s")


TRAINER = Trainer("di_sdf", __doc__, Settings, PRESETS, train,
                  folder=lambda s, args: f"di_sdf_{Path(args.mesh or DEFAULT_MESH).stem}",
                  folder_hint="di_sdf_<mesh>",
                  ship_assets={KIND: {}}, extra_arguments=extra_arguments, errors=(DiSdfError,))
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
