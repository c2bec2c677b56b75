"""`inshade bench di_sdf`: the DI-SDF (techniques/di_sdf/train.py) against the MLP SDF (models/mlp_sdf.py, fitted as neural_sdf fits it)
at equal bytes, on one mesh, rendered by the same sphere-tracing pass.

For each ``--budgets-kb`` value: a DI-SDF is fitted within the budget (8-bit arrays; its actual
bytes are the cells, N_p³·3 + N_c³), and an MLP SDF (``--mlp-layers`` hidden layers, float32
weights as the bundle stores them) whose width is the largest with 4 · params <= the DI's bytes.
Both are measured the same way:

- surface error: mean and 95th percentile |d| at 20k mesh surface points (world units and per
  mesh bound radius);
- IoU of inside (d < 0) against the mesh's inside on 100k uniform points in the bound cube;
- normal angle error (degrees) at the surface points, central differences with the bundle's own
  ``normal_eps`` (the shader's estimator);
- the sdf_diffuse pass (lib/sdf sphere tracing, SH environment "noon") rendered by the GL driver
  through the runtime's SceneRenderer, on the scene ``inshade train di_sdf`` writes (``"sdf":
  {"network": bundle folder}``), at ``--size``² (DI on both LUT paths: exact = texelFetch + fp32
  mix, fast = hardware filtering): PSNR (linear, peak 1) against a ground truth ray-traced from the mesh (trimesh +
  embree first hits, barycentric-interpolated vertex normals, the same shading); and ms/frame
  (median and min of ``--frames`` draws after a warm-up draw, timed by ``--clock`` of
  ``inshade.bench.harness``: GL timer query on a hardware driver, draw + ``glFinish`` wall time
  on llvmpipe; the first draw, where llvmpipe JIT-compiles, reported apart -- seconds only on a
  cold Mesa shader cache).

Writes ``di_sdf.json``, ``di_sdf.md``, ``di_sdf.png`` (renders + bars) and the renders as PNGs
into ``--out``; GL_RENDERER is logged in all of them. ``--quick``: one tiny budget, few steps,
64² (smoke runs and tests).
"""
from __future__ import annotations

import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bench.contract import Bench, clock_option, option, sized
from inshade.bench.entry import Claim, claim_row
from inshade.bench.harness import (BenchError, WallClock, clock_for, clock_record, label_axes, machine,
                                   machine_markdown, matplotlib_pyplot, measure, portable_path, save_figure,
                                   write_report)
from inshade.metrics import psnr

DEFAULT_OUT = "bench-out/di_sdf"
DEFAULT_MESH = "trained/prt_mesh/mesh.ply"
SKY = "noon"
PROGRAM = "passes/sdf_diffuse.frag"


@dataclass
class Settings:
    out: str = option(DEFAULT_OUT, f"output folder (default {DEFAULT_OUT})")
    mesh: str = option(DEFAULT_MESH, "closed mesh (default: the procedural rabbit of inshade.geometry.mesh, generated "
                                     "if missing)")
    budgets_kb: str = option("13", "DI-SDFs to fit here, byte budgets in KiB, comma-separated ( = none; default "
                                   "%(default)s)")
    di_steps: int = option(1500, "DI training steps (default %(default)s)")
    di_bundles: str = option("", "also compare these trained DI-SDF bundle folders (comma-separated; their bytes set "
                                 "the MLP's), e.g. trained/di_sdf")
    mlp_steps: int = option(3000, "MLP training steps (default %(default)s)")
    mlp_layers: int = option(3, "MLP hidden layers (default %(default)s)")
    mlp_samples: int = option(300_000, "MLP training samples (default %(default)s)")
    mlp_max_width: int = option(48, "skip (and say so) MLPs wider than this: sdf_diffuse inlines scene_sdf 7 times and "
                                    "llvmpipe's first-draw JIT of a 38-wide MLP took 147 s here (default %(default)s)")
    mlp_storage: str = option("auto", "MLP weight placement in the shader (default %(default)s: as the renderer picks)",
                              choices=("auto", "inline", "ubo", "texture"))
    size: int = option(256, "render size (default %(default)s)")
    frames: int = option(5, "timed frames per method (default %(default)s)")
    quick: bool = option(False, "tiny run: 13 KiB, 40/100 steps, 64x64, 1 frame")
    clock: str = clock_option()


# ---------------------------------------------------------------------------------------------
# equal bytes

def mlp_params(width: int, layers: int) -> int:
    """Parameters of models/mlp_sdf.py build(width, layers): 3 -> width (x layers) -> 1, with biases."""
    return 4 * width + (layers - 1) * (width * width + width) + width + 1


def mlp_width_for_bytes(nbytes: int, layers: int) -> int:
    """The widest MLP whose float32 weights fit ``nbytes`` (at least 1)."""
    w = 1
    while 4 * mlp_params(w + 1, layers) <= nbytes:
        w += 1
    return w


# ---------------------------------------------------------------------------------------------
# ground truth and GL renders

def camera(frame) -> dict:
    from inshade.techniques.di_sdf.train import orbit_camera

    return orbit_camera(frame)


def mesh_ground_truth(mesh, uniforms: dict, size: int, sh: np.ndarray) -> dict:
    """The sdf_diffuse shading of the mesh itself: first hits by embree, barycentric-interpolated
    vertex normals, albedo 0.8; misses show max(L(rd), 0) as the pass does. Linear RGBA [H, W, 4]."""
    import torch
    import trimesh

    from inshade.techniques.di_sdf.model import ALBEDO
    from inshade.models.sdf import INV_PI, camera_rays, sh_background_t, sh_irradiance_t

    ro, rd = camera_rays(uniforms, size, size)
    coeffs = torch.from_numpy(np.asarray(sh, np.float32))
    out = sh_background_t(coeffs, rd).numpy()
    loc, ray, tri = mesh.ray.intersects_location(ro.numpy().astype(np.float64), rd.numpy().astype(np.float64),
                                                 multiple_hits=False)
    hit = np.zeros(size * size, bool)
    if len(ray):
        bary = trimesh.triangles.points_to_barycentric(mesh.triangles[tri], loc)
        n = (mesh.vertex_normals[mesh.faces[tri]] * bary[:, :, None]).sum(1)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        shade = sh_irradiance_t(coeffs, torch.from_numpy(n.astype(np.float32))).numpy()
        out[ray] = np.asarray(ALBEDO, np.float32) * shade * np.float32(INV_PI)
        hit[ray] = True
    rgba = np.concatenate([out, np.ones((size * size, 1), np.float32)], -1)
    return {"rgba": rgba.reshape(size, size, 4), "hit": hit.reshape(size, size)}


def sdf_scene(bundle_folder, frame, size: int, workdir: Path):
    """The scene ``inshade train di_sdf`` writes for an asset (train.py ``scene_dict``: sdf_diffuse,
    the orbit camera framing ``frame``, sky SKY), tracing the network SDF bundle in
    ``bundle_folder`` (a DI-SDF or an MLP SDF: both are ``"sdf": {"network": ...}``)."""
    import json

    from inshade.techniques.di_sdf.train import scene_dict
    from inshade.scene.description import load_scene

    data = scene_dict("di_sdf_bench", "DI-SDF bench", frame, size=size)
    data["program"] = PROGRAM
    data["sdf"] = {"network": str(Path(bundle_folder).resolve())}
    data["environment"] = {**data["environment"], "sky": SKY, "rotation": 0.0}
    folder = Path(tempfile.mkdtemp(prefix="scene-", dir=workdir))
    (folder / "scene.json").write_text(json.dumps(data))
    return load_scene(folder)


def glsl_render(ctx, scene, size: int, frames: int, clock=None, **settings) -> dict:
    """The scene's pass (sdf_diffuse on its network SDF) drawn by the runtime's SceneRenderer at
    ``size``² from the scene's camera, ``settings`` overriding the scene's (``lut_filter``,
    ``storage``): the image and the frame times (``clock``: a harness clock, default draw +
    glFinish wall time; every timed frame is redrawn, ``render_network(force=True)``)."""
    from inshade.runtime.renderer import SceneRenderer

    cam = scene.make_camera()
    r = SceneRenderer(scene, ctx, settings=settings)
    try:
        link = r.compile_seconds
        first = WallClock(ctx.finish).time(lambda: r.render_network(cam, size, size))   # llvmpipe JIT
        timing = measure(lambda: r.render_network(cam, size, size, force=True), repeats=frames, warmup=0,
                         clock=clock or WallClock(ctx.finish))
        image = r.read("network")
        plan = r.generated[-1].plan   # the network SDF's Generated comes after the (no) networks'
    finally:
        r.release()
        r.cache.release()
    return {"image": image, "first_draw_s": round(first, 3), "compile_s": round(link, 3),
            "ms_median": round(1e3 * timing.median, 2), "ms_min": round(1e3 * timing.min, 2),
            "ms_max": round(1e3 * timing.max, 2), "clock": timing.clock,
            "plan": plan.report() if hasattr(plan, "report") else ""}


# ---------------------------------------------------------------------------------------------
# the models

def di_bundles(mesh, args) -> list[tuple[object, str]]:
    """A DI-SDF fitted here for each ``--budgets-kb`` value, then each ``--di-bundles`` folder."""
    from inshade import bundle as bundle_mod
    from inshade.techniques.di_sdf import train as di_sdf

    out = []
    for kb in args.budget_list:
        r = di_sdf.fit(mesh, kb * 1024, steps=args.di_steps, evaluate=False, name=f"di_sdf_{kb:g}k",
                       **({"samples": 60000, "batch": 8192} if args.quick else {}))
        out.append((r.bundle, f"trained in this run ({args.di_steps} steps)"))
    for p in (p.strip() for p in args.di_bundles.split(",")):
        if p:
            b = bundle_mod.load(p)
            out.append((b, f"{portable_path(p)} ({b.meta.get('metrics', {}).get('steps')} steps)"))
    return out


def mlp_bundle(mesh_path: str, nbytes: int, args, workdir: Path):
    """The MLP SDF baseline of ``nbytes`` float32 weights, fitted to the mesh and saved in ``workdir``."""
    from inshade.models.mlp_sdf_fit import fit_mesh
    from inshade.models.threads import torch_threads

    kind = "neural_sdf"   # the kind MLP SDF bundles carry; the report's rows and headlines find the MLP by it
    width = mlp_width_for_bytes(nbytes, args.mlp_layers)
    with torch_threads(1):   # 18x faster per step than 2 threads on the shared, busy 2 cores (measured)
        fit = fit_mesh(mesh_path, width=width, layers=args.mlp_layers, steps=args.mlp_steps, samples=args.mlp_samples,
                       name=kind, mc_resolution=32 if args.quick else 64)
    b = fit.module.export(kind, kind, metrics=fit.metrics)
    b.save(workdir / f"mlp_{width}x{args.mlp_layers}")
    return b, width


def on_disk(bundle, workdir: Path) -> Path:
    """The bundle's folder, saved into ``workdir`` first if it lives only in memory (a scene names
    its network SDF by folder)."""
    if bundle.path is None:
        bundle.save(Path(tempfile.mkdtemp(prefix=f"{bundle.name}-", dir=workdir)))
    return Path(bundle.path)


def model_entry(name, bundle, nbytes, mesh_radius, ev, gt, ctx, view, args, workdir: Path, **settings) -> dict:
    import torch

    from inshade.techniques.di_sdf.data import sdf_metrics
    from inshade.models.network_sdf import NetworkSdfModule

    module = NetworkSdfModule.from_bundle(bundle)
    trace = module.scene.trace
    with torch.no_grad():
        m = sdf_metrics(module, ev, trace["normal_eps"], mesh_radius)
    scene = sdf_scene(on_disk(bundle, workdir), view, args.size, workdir)
    r = glsl_render(ctx, scene, args.size, args.frames, clock=args.timer, **settings)
    bm = bundle.meta.get("metrics", {})
    return {"method": name, "bytes": int(nbytes), "kind": bundle.kind,
            "surface_mae": m["surface_mae"], "surface_p95": m["surface_p95"],
            "surface_mae_per_radius": m["surface_mae"] / mesh_radius, "iou": m["iou"],
            "normal_deg_mean": m["normal_deg_mean"], "normal_deg_median": m["normal_deg_median"],
            "psnr": round(psnr(r["image"][..., :3], gt["rgba"][..., :3]), 3),
            "ms_median": r["ms_median"], "ms_min": r["ms_min"], "ms_max": r["ms_max"], "clock": r["clock"],
            "first_draw_s": r["first_draw_s"],
            "train_seconds": bm.get("train_seconds"), "trace": dict(trace), "_image": r["image"]}


# ---------------------------------------------------------------------------------------------
# run

def run(args) -> int:
    from inshade.codegen.sdf import environment_sh
    from inshade.geometry.mesh import bounding_sphere, write_bunny
    from inshade.techniques.di_sdf.data import Frame, eval_set, load_mesh
    from inshade.techniques.di_sdf.model import fast_path_bound
    from inshade.scene.camera import camera_from_dict
    from inshade.runtime.context import gl_info, shared_context
    from inshade.scene.image_io import write_png

    if args.quick:
        args.mlp_samples = min(args.mlp_samples, 20000)
    try:
        args.budget_list = [float(v) for v in args.budgets_kb.split(",") if v.strip()]
    except ValueError:
        raise BenchError(f"--budgets-kb: expected numbers, got {args.budgets_kb!r}") from None
    if args.mesh == DEFAULT_MESH and not Path(DEFAULT_MESH).is_file():   # not run from the repository root
        from inshade.geometry.mesh import DEFAULT_OUT as generated
        args.mesh = str(write_bunny(generated))
    mesh = load_mesh(args.mesh)
    ctx = shared_context()
    info = gl_info(ctx)
    args.timer = clock_for(ctx, args.clock, software=info["software"])
    print(f"GL_RENDERER: {info['renderer']}", file=sys.stderr)
    center, mesh_radius = bounding_sphere(mesh)
    view = Frame(tuple(float(c) for c in center), float(mesh_radius) * 1.1)
    cam = camera(view)
    uniforms = camera_from_dict(cam).uniforms(args.size, args.size)
    sh = environment_sh(SKY, 0.0)
    ev = eval_set(mesh, view)
    gt = mesh_ground_truth(mesh, uniforms, args.size, sh)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_png(out / "ground_truth.png", gt["rgba"][..., :3])
    result = {
        "benchmark": "di_sdf", "quick": bool(args.quick),
        "machine": machine(info), **clock_record(args.timer),
        "mesh": {"path": portable_path(args.mesh), "faces": int(len(mesh.faces)), "radius": float(mesh_radius)},
        "render": {"size": args.size, "sky": SKY, "camera": cam, "frames": args.frames,
                   "ground_truth": "embree first hits of the mesh, interpolated vertex normals, same shading"},
        "budgets": [],
    }
    with tempfile.TemporaryDirectory() as tmp:
        for bundle, origin in di_bundles(mesh, args):
            nbytes = int(bundle.meta["metrics"]["bytes"])
            rows = []
            for f in ("exact", "fast"):
                e = model_entry(f"DI-SDF ({f})", bundle, nbytes, mesh_radius, ev, gt, ctx, view, args, Path(tmp),
                                lut_filter=f)
                m = bundle.meta["metrics"]
                e.update(n_primary=m["n_primary"], n_cascaded=m["n_cascaded"], origin=origin,
                         fast_path_bound=fast_path_bound(bundle))
                rows.append(e)
            width = mlp_width_for_bytes(nbytes, args.mlp_layers)
            if width > args.mlp_max_width:
                rows.append({"method": f"MLP {width}x{args.mlp_layers} (fp32)", "skipped":
                             f"width {width} > --mlp-max-width {args.mlp_max_width} (llvmpipe JIT time)",
                             "bytes": 4 * mlp_params(width, args.mlp_layers)})
                result["budgets"].append({"di_bytes": nbytes, "rows": _write_images(rows, out, nbytes)})
                continue
            mlp, width = mlp_bundle(str(args.mesh), nbytes, args, Path(tmp))
            e = model_entry(f"MLP {width}x{args.mlp_layers} (fp32)", mlp, 4 * mlp_params(width, args.mlp_layers),
                            mesh_radius, ev, gt, ctx, view, args, Path(tmp), storage=args.mlp_storage)
            e.update(width=width, layers=args.mlp_layers, step_scale=e["trace"]["step_scale"], storage=args.mlp_storage)
            rows.append(e)
            result["budgets"].append({"di_bytes": nbytes, "rows": _write_images(rows, out, nbytes)})
            print(f"budget {nbytes} bytes done", file=sys.stderr)
    write_report(out, "di_sdf", result, markdown, plot)
    print(f"wrote {out / 'di_sdf.json'}, {out / 'di_sdf.md'}, {out / 'di_sdf.png'}", file=sys.stderr)
    return 0


def _write_images(rows, out: Path, nbytes: int) -> list:
    from inshade.scene.image_io import write_png

    for r in rows:
        if "_image" in r:
            tag = r["method"].split(" ")[0].lower() + ("_fast" if "fast" in r["method"] else "")
            write_png(out / f"{tag}_{nbytes}.png", r.pop("_image")[..., :3])
            r["image"] = f"{tag}_{nbytes}.png"
    return rows


def markdown(result: dict) -> str:
    m = result["machine"]
    lines = ["# DI-SDF vs MLP SDF at equal bytes", "",
             machine_markdown(m),
             f"- mesh: `{result['mesh']['path']}` ({result['mesh']['faces']} faces, bound radius "
             f"{result['mesh']['radius']:.4f}); render {result['render']['size']}² sdf_diffuse, sky "
             f"{result['render']['sky']}; PSNR vs {result['render']['ground_truth']}",
             "- surface |d| at mesh surface points (per bound radius); IoU on uniform points in the bound cube; "
             "normal error at surface points (central differences, each bundle's normal_eps); ms/frame: median "
             f"of {result['render']['frames']} draws after a warm-up ({result.get('clock_note') or 'wall clock'}); "
             "first draw includes llvmpipe's JIT unless Mesa's on-disk shader cache already holds the program "
             "(a repeated run)", ""]
    for b in result["budgets"]:
        lines += [f"## DI budget {b['di_bytes']} bytes", "",
                  "| method | bytes | surface MAE / r | p95 / r | IoU | normal err ° | PSNR dB | ms/frame | "
                  "first draw s | train s |", "|---|---|---|---|---|---|---|---|---|---|"]
        r_mesh = result["mesh"]["radius"]
        for e in b["rows"]:
            if "skipped" in e:
                lines.append(f"| {e['method']} | {e['bytes']} | skipped: {e['skipped']} |||||||| ")
                continue
            lines.append(f"| {e['method']} | {e['bytes']} | {e['surface_mae_per_radius']:.2e} | "
                         f"{e['surface_p95'] / r_mesh:.2e} | {e['iou']:.4f} | {e['normal_deg_mean']:.2f} | "
                         f"{e['psnr']:.2f} | {e['ms_median']:.1f} | {e['first_draw_s']:.2f} | "
                         f"{'—' if e['train_seconds'] is None else format(e['train_seconds'], '.0f')} |")
        lines.append("")
    return "\n".join(lines)


def plot(result: dict, path: Path) -> None:
    """Renders (read from ``path``'s folder) and PSNR vs ms/frame, into ``path``."""
    from PIL import Image

    plt = matplotlib_pyplot()
    out = path.parent

    b = max(result["budgets"], key=lambda x: sum("image" in e for e in x["rows"]))
    rows = [e for e in b["rows"] if "image" in e]
    fig, axes = plt.subplots(1, len(rows) + 2, figsize=(3.0 * (len(rows) + 2), 3.2))
    axes[0].imshow(Image.open(out / "ground_truth.png"))
    axes[0].set_title("mesh (ray traced)", fontsize=8)
    for ax, e in zip(axes[1:], rows):
        ax.imshow(Image.open(out / e["image"]))
        ax.set_title(f"{e['method']}\n{e['psnr']:.1f} dB, {e['ms_median']:.0f} ms", fontsize=8)
    for ax in axes[:-1]:
        ax.axis("off")
    ax = axes[-1]
    for bud in result["budgets"]:
        for e in (e for e in bud["rows"] if "image" in e):
            ax.scatter(e["ms_median"], e["psnr"], marker="o" if "DI" in e["method"] else "s")
            ax.annotate(f"{e['method'].split(' (')[0]} {'fast' if 'fast' in e['method'] else ''} {e['bytes'] // 1024}K",
                        (e["ms_median"], e["psnr"]), fontsize=6)
    ax.set_xscale("log")
    label_axes(ax, "ms / frame", "PSNR dB")
    save_figure(fig, path, "DI-SDF vs MLP SDF, equal bytes", result)


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper


CLAIMS = {"mlp": Claim("Differentiable Indirection (Datta et al. 2023), Fig. 8 / 14c",
                       "surface error of the MLP SDF / the DI-SDF's at equal bytes (> 1: DI better)",
                       "'compares favourably with MRHE at equal parameter count' (MRHE, not an MLP; no number in "
                       "the text)")}


def headlines(r: dict) -> list[dict]:
    rows = []
    for budget in r["budgets"]:
        di = next(x for x in budget["rows"] if x["method"] == "DI-SDF (exact)")
        mlp = next((x for x in budget["rows"] if x.get("kind") == "neural_sdf" and "surface_mae" in x), None)
        if mlp is None:
            rows.append(claim_row(CLAIMS, "di_sdf", "mlp", f"no MLP at {budget['di_bytes']} B (skipped); DI MAE/r "
                                  f"{di['surface_mae_per_radius']:.2e}, IoU {di['iou']:.3f}", None,
                                  f"{budget['di_bytes']} B"))
            continue
        ratio = mlp["surface_mae"] / di["surface_mae"]
        rows.append(claim_row(CLAIMS, "di_sdf", "mlp", f"{ratio:.1f}x: MAE/r DI {di['surface_mae_per_radius']:.2e} vs "
                              f"{mlp['method']} {mlp['surface_mae_per_radius']:.2e}; IoU {di['iou']:.3f} vs "
                              f"{mlp['iou']:.3f}", ratio, f"{budget['di_bytes']} B"))
    return rows


BENCH = Bench("di_sdf", __doc__, Settings, run, claims=CLAIMS, headlines=headlines,
              quick={"budgets_kb": "13", "di_steps": 40, "mlp_steps": 100, "size": 64, "frames": 1},
              sizes={"cpu": sized(150, di_steps=500, mlp_steps=600, mlp_samples=50000, size=128, frames=3),
                     # 2000 MLP steps: seconds on a GPU
                     "device": sized(60, mlp_steps=2000, size=512, frames=10)})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite
