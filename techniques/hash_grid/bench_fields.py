"""The hash_grid bench's marched applications: the SDF (sphere traced by passes/sdf_diffuse.frag) and
the radiance field (ray marched by passes/radiance_field_hash_grid.frag with its occupancy grid).

Each is drawn and timed from its scene's camera; how many network evaluations a pixel makes is
counted by the march's torch twin (step for step the shader's) at ``count_size``², so FLOPs and
fetches per pixel are the plan's per evaluation times that count. The radiance field's held-out
views are drawn by the shader here and compared with their ground truth; the SDF's surface error
is the trainer's (metrics.json: its held-out points on the mesh and the zero set's distance to it).

The MLP-only network of the same bytes (frequency encoding + ReLU MLP, the trainer's baseline) has
its quality quoted from the trainer (metrics.json ``mlp_baseline``, measured beside the ship run).
A march's frame time follows its field: an untrained network's distances or densities set how far
a ray goes and how many samples it evaluates. So the MLP-only network is timed per evaluation in
passes/evaluate.frag beside the hash grid (one point per pixel, a lattice over the field's box),
and its frame is projected as the hash grid's measured frame plus, for each of the hash grid's
evaluations, the difference of the two costs per evaluation (the same march with the other
network), and labelled so.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from inshade.bench.harness import portable_command, portable_path

from .bench_measure import (ScenePass, asset_record, evaluation_cost, folder_bytes, lattice, load_asset,
                            march_evaluations, plan_summary, sdf_evaluations)

SDF_QUALITY = ("surface_abs_mean_per_diagonal", "zero_set_to_mesh_mean_per_diagonal",
               "zero_set_to_mesh_p95_per_diagonal", "iou_uniform")


def _per_pixel(row: dict, plan: dict, evals: float) -> None:
    row.update(evaluations_per_pixel=evals, flops_per_pixel=round(plan["flops"] * evals),
               fetches_per_pixel=round(plan["fetches"] * evals))


def _ours(ctx, scene, opts) -> tuple[ScenePass, dict]:
    p = ScenePass(ctx, scene, opts.timing)
    return p, {"compile_s": p.compile_s, "first_draw_s": p.first_draw_s, "frames": p.frames()}


def projected(frames: dict, evals_per_pixel: float, extra_ns: float) -> dict:
    """The hash grid's measured frames (sizes it timed) with ``extra_ns`` more per evaluation: the
    same march making the same evaluations with another network."""
    return {size: {"ms_projected": round(f["ms_median"] + 1e-6 * extra_ns * evals_per_pixel * int(size) ** 2, 1)}
            for size, f in frames.items() if "ms_median" in f}


def mlp_row(ctx, graph, kind: str, inputs, opts, ours: dict, base: dict | None, quality_keys) -> dict:
    """The MLP-only network of the hash grid's bytes: cost per evaluation beside the hash grid's,
    projected frames and per-pixel work at the hash grid's evaluations, the trainer's quality."""
    from .bench_image import architecture
    from .network import network_bytes

    bundle = graph.export(kind, f"{kind}_mlp_only")
    cost = evaluation_cost(ctx, bundle, inputs, opts.timing)
    ours_ns = ours["evaluation"]["ns_per_evaluation"]
    row = {"key": "mlp", "name": "MLP-only", "bytes": network_bytes(graph), "architecture": architecture(bundle),
           "evaluation": cost, "plan": cost["plan"], "cost_ratio": round(cost["ns_per_evaluation"] / ours_ns, 2),
           "frames": projected(ours["frames"], ours["evaluations_per_pixel"], cost["ns_per_evaluation"] - ours_ns),
           "first_draw_s": cost["first_draw_s"],
           "frames_note": "MLP-only frames projected: the hash grid's measured frame plus its evaluations x the "
                          "difference of the two costs per evaluation (the same march with the other network; an "
                          "untrained network's own march would follow its untrained field); its first draw is the "
                          "evaluate pass's",
           "quality": {k: base[k] for k in quality_keys if k in base} if base else None,
           "quality_source": (f"the trainer's, beside the ship run ({base['steps']} steps, {base['network']}; "
                              "metrics.json mlp_baseline)") if base else
                             "not measured: the asset was trained without --baseline-steps"}
    _per_pixel(row, cost["plan"], ours["evaluations_per_pixel"])
    return row


# --- the SDF ---------------------------------------------------------------------------------------

def measure_sdf(folder: Path, opts, ctx, workdir: Path, log) -> dict:
    from inshade.models.network_sdf import NetworkSdfModule
    from inshade.scene.description import load_scene

    from . import sdf
    from .bench_image import architecture

    bundle, metrics, s = load_asset(folder, sdf.KIND)
    log(f"sdf: hash grid + MLP, {metrics['bytes']} bytes, timed from the scene's camera")
    p, ours = _ours(ctx, load_scene(folder), opts)
    try:
        plan = plan_summary(p.plans()[-1])      # the network SDF's Generated comes after the (no) networks'
        camera = p.camera
    finally:
        p.release()
    module = NetworkSdfModule.from_bundle(bundle).eval()
    count = sdf_evaluations(module, camera, opts.count_size)
    q = lattice(opts.eval_side, 3, -1.0, 1.0)           # q = (p - center) / radius over the traced cube
    ours.update(key="hash_grid", name="hash grid + MLP", bytes=int(metrics["bytes"]),
                architecture=architecture(bundle), plan=plan, evaluations=count,
                evaluation=evaluation_cost(ctx, bundle, q, opts.timing),
                quality={k: metrics[k] for k in SDF_QUALITY if k in metrics},
                quality_source="the trainer's (metrics.json), per bounding-box diagonal "
                               f"({metrics['diagonal']:.4g}): surface error = mean |f| at held-out points on the "
                               "mesh; zero set→mesh = distance to the mesh of the vertices of f = 0 (marching cubes, "
                               f"{metrics['mc_resolution']}³); IoU of inside on held-out points in the cube")
    _per_pixel(ours, plan, count["per_pixel"])
    log(f"sdf: MLP-only network of {metrics['bytes']} bytes, cost per evaluation")
    graph = sdf.build_baseline(s, int(metrics["bytes"]))
    mlp = mlp_row(ctx, graph, sdf.KIND, q, opts, ours, metrics.get("mlp_baseline"), SDF_QUALITY)
    neural = metrics.get("neural_sdf_shipped")
    if neural and "folder" in neural:   # as the trainer recorded it: relative paths are relative to where it ran
        neural = {**neural, "folder": portable_command(neural["folder"])}
    return {"app": "sdf", "asset": portable_path(folder), "trained": asset_record(bundle, metrics), "kind": sdf.KIND,
            "mesh": portable_command(bundle.meta["provenance"].get("mesh")),
            "bytes_file": folder_bytes(folder), "table_bytes": int(metrics["encoding"]["table_bytes_fp16"]),
            "lipschitz": {k: metrics.get(k) for k in ("lipschitz_measured", "lipschitz_sound", "step_scale")},
            "rows": [ours, mlp],
            "also": {"neural_sdf_shipped": {k: neural[k] for k in (*SDF_QUALITY, "bytes", "folder") if k in neural}}
            if neural else {},
            "not_compared": {"DI-SDF": "its trainer is techniques/di_sdf's (a technique imports no other) and the "
                             "shared layers hold none; `inshade bench di_sdf` measures it against an MLP SDF at "
                             "equal bytes (12.8 and 43 KB; docs/bench/di_sdf.md), not at this network's bytes"}}


# --- the radiance field ----------------------------------------------------------------------------

def measure_radiance_field(folder: Path, opts, ctx, workdir: Path, log) -> dict:
    from inshade.bundle import load
    from inshade.models.graph import GraphModule
    from inshade.scene.camera import camera_from_dict
    from inshade.scene.description import load_scene
    from inshade.scene.image_io import read_exr

    from . import radiance_field as rf
    from .bench_image import architecture
    from .radiance_field_render import KIND, march_settings
    from .radiance_field_train import HELDOUT_FOLDER, heldout_image, heldout_psnr

    bundle, metrics, s = load_asset(folder, KIND)
    cameras = json.loads((folder / HELDOUT_FOLDER / "cameras.json").read_text())[:opts.heldout_views]
    truths = [read_exr(folder / heldout_image(k))[..., :3] for k in range(len(cameras))]
    side = truths[0].shape[0]
    log(f"radiance field: hash grid + MLP, {metrics['bytes']} bytes, {len(cameras)} held-out views at {side}², timed")
    p, ours = _ours(ctx, load_scene(folder), opts)
    try:
        images = [p.image(side, camera_from_dict(c))[..., :3] for c in cameras]
        plans = {g.prefix: plan_summary(g.plan) for g in p.renderer.generated}
        camera = p.camera
    finally:
        p.release()
    m = march_settings(bundle.meta["render"], str(folder))
    occupancy = rf.occupancy_cells(load(folder / "occupancy"))
    count = march_evaluations(GraphModule.from_bundle(bundle), occupancy, m, camera, opts.count_size)
    n = len(cameras)
    shader = heldout_psnr(images, truths)
    points = lattice(opts.eval_side, 3, 0.0, 1.0)
    d = np.tile(np.asarray([[0.36, -0.48, 0.8]], np.float32), (len(points), 1))
    inputs = np.concatenate([points, d], 1)
    plan = plans["hgrf"]
    ours.update(key="hash_grid", name="hash grid + MLP", bytes=int(metrics["bytes"]),
                architecture=architecture(bundle), plan=plan, occupancy_plan=plans.get("hgocc"), evaluations=count,
                evaluation=evaluation_cost(ctx, bundle, inputs, opts.timing),
                quality={"heldout_psnr": shader["heldout_psnr"], "heldout_psnr_per_view": shader["heldout_psnr_per_view"],
                         "heldout_psnr_torch": metrics["heldout_psnr"]},
                quality_source=f"GL march of {n} held-out view{'s' * (n != 1)} at {side}² against their ground "
                               "truth (all pixels, linear RGB); heldout_psnr_torch: the trainer's torch march "
                               f"of its {len(metrics['heldout_psnr_per_view'])} views")
    _per_pixel(ours, plan, count["per_pixel"])
    log(f"radiance field: MLP-only network of {metrics['bytes']} bytes, cost per evaluation")
    graph = rf.baseline_graph(s.n_freqs, s.baseline_depth, s.width, s.depth, int(metrics["bytes"]), s.seed)
    mlp = mlp_row(ctx, graph, KIND, inputs, opts, ours, metrics.get("mlp_baseline"), ("heldout_psnr",))
    return {"app": "radiance_field", "asset": portable_path(folder), "trained": asset_record(bundle, metrics),
            "kind": KIND, "scene": s.scene,
            "march": {"step": m.step, "max_steps": m.max_steps, "occupancy_resolution": m.occupancy_resolution,
                      "occupied_fraction": metrics.get("occupied_fraction")},
            "bytes_file": folder_bytes(folder, ("occupancy",)), "occupancy_bytes": int(metrics["occupancy_bytes"]),
            "table_bytes": int(metrics["encoding"]["table_bytes_fp16"]), "rows": [ours, mlp],
            "not_compared": {"DI radiance field": "techniques/di_radiance_field compresses the baked grids of its own "
                             "procedural field (`inshade bench di_radiance_field`); its trainer is that technique's "
                             "(a technique imports no other), so it is not trained on this scene here"}}
