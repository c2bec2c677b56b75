"""`inshade bench appearance_prefilter`: prefiltered voxels against the full geometry and a mesh LoD.

For each asset (``--assets``, default every ``trained/appearance_prefilter_*`` folder) the scene the
asset was baked from is rebuilt (scene.py, from metrics.json's settings) and, per scale s of
``--scales`` (default: the asset's range), one image is made by each method at the scene's camera,
its sun and its SH environment. The image is square, sized so that the box spans about 2^(s-1)
pixels (the paper's convention: voxels of scale s, the next finer than the footprint's, are about
half a pixel), at least ``--min-size``:

- **prefiltered**: the GL pass (passes/appearance_prefilter.frag, one beam per pixel), scale forced
  to s (setting ``force_scale``), sun shadows on;
- **reference**: full-geometry ray tracing (reference.py, embree, direct light), ``--spp`` (64)
  stratified samples per pixel: the ground truth every other method is measured against;
- **1 spp**: the same ray tracer at the pixel centre only: the aliasing a plain render shows;
- **decimated LoD**: the mesh decimated (quadric error, fast-simplification) to the prefiltered
  representation's bytes at scale s (see below), the
  material averaged onto the kept faces (baseline.py), ray traced at ``--spp``. The bytes are the
  paper's per-voxel accounting: that scale's latents and spheres; the decoders and the index
  are fixed costs, reported beside.

Quality: MSE (linear RGB, whole image) and FLIP (LDR, sRGB of the radiance clipped to [0, 1]).
Memory: the bytes of each representation, per voxel and per covered pixel (bytes / pixels the
reference covers), against the full scene (positions, indices, an 8-bit material per face).
Speed, in the same run: the prefiltered frame (GL, median of ``--rounds``) against the
equal-quality ray-traced render: the fewest spp of 1, 2, 4, ... 32 whose MSE against the
reference is at most the prefiltered MSE, timed at that spp (embree on the CPU here). The
crossover is the finest scale at which the prefiltered frame is the faster. Bake seconds (data,
training) come from the asset's metrics.json. A scene of the hidden-occlusion case alone (``slabs``)
adds the masks-vs-mean-alpha measurement of hidden_occlusion.py. Writes ``appearance_prefilter.{json,md,png}`` into ``--out``.
"""
from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bench.contract import Bench, option, sized
from inshade.bench.entry import Claim, claim_row
from inshade.bench.harness import (BenchError, machine, machine_markdown, markdown_table, matplotlib_pyplot,
                                   portable_path, write_report)
from inshade.files import atomic_write

from . import KIND, PREFIX, environment_sh, sun

STEM = KIND
DEFAULT_OUT = f"bench-out/{KIND}"
EQ_SPP = (1, 2, 4, 8, 16, 32)
METHODS = ("prefiltered", "decimated", "1spp")


@dataclass
class Settings:
    assets: str | None = option(None, f"comma-separated asset folders (default: every trained/{KIND}_* folder)")
    scales: tuple[int, ...] | None = option(None, "scales to measure (default: the asset's)", nargs="*")
    spp: int = option(64, "reference samples per pixel (default %(default)s)")
    min_size: int = option(8, "smallest image side (default %(default)s)")
    rounds: int = option(3, "timed rounds per frame (default %(default)s)")
    out: str = option(DEFAULT_OUT, f"output folder (default {DEFAULT_OUT})")


def asset_folders(text: str | None) -> list[Path]:
    if text:
        folders = [Path(t) for t in text.split(",") if t]
    else:
        folders = sorted(p for p in Path("trained").glob(f"{KIND}_*") if (p / "scene.json").is_file())
    if not folders:
        raise BenchError(f"--assets: no {KIND} asset found (train one: inshade train {KIND} --preset quick)")
    return folders


def load_asset(folder: Path):
    """(scene, bundle, metrics) of an asset folder; BenchError naming the folder otherwise."""
    from inshade.bundle import BundleError, load
    from inshade.scene.description import SceneError, load_scene

    if not (folder / "scene.json").is_file() or not (folder / "metrics.json").is_file():
        raise BenchError(f"{folder}: not a {KIND} asset (scene.json and metrics.json needed)")
    try:
        scene = load_scene(folder)
        nets = [n for n in scene.networks if n.prefix == PREFIX]
        bundle = load(nets[0].bundle)
    except (SceneError, BundleError, ValueError, IndexError) as exc:
        raise BenchError(f"{folder}: {exc}") from None
    if bundle.kind != KIND:
        raise BenchError(f"{folder}: bundle kind is {bundle.kind!r}, expected {KIND!r}")
    return scene, bundle, json.loads((folder / "metrics.json").read_text())


def image_side(camera, scale: int, min_size: int) -> int:
    """The square image side at which the box (unit, centred at 0.5) spans ~2^(scale-1) pixels."""
    d = float(np.linalg.norm(camera.eye() - 0.5))
    return max(min_size, int(round(2.0 ** (scale - 1) * 2.0 * d * math.tan(math.radians(camera.fov_y) / 2.0))))


def _display(img: np.ndarray) -> np.ndarray:
    from inshade.metrics import srgb_oetf

    return srgb_oetf(np.clip(img[..., :3], 0.0, 1.0)).astype(np.float32)


def quality(test: np.ndarray, ref: np.ndarray) -> dict:
    from inshade.metrics import flip, flip_unavailable, mse

    out = {"mse": float(mse(test[..., :3].astype(np.float64), ref.astype(np.float64)))}
    out["flip"] = None if flip_unavailable() else round(float(flip(_display(ref), _display(test))), 5)
    return out


def scale_bytes(mem: dict, cells: np.ndarray, scale: int) -> int:
    """The prefiltered representation at one scale, counted as the paper counts it: that scale's
    voxels (latent + sphere). The decoders and the index grid are fixed costs reported beside it
    (the paper calls them "relatively small and negligible"; the memory table shows both, and the
    dense grid's bytes beside the index the bundle uses)."""
    n = int((cells[:, 0] == scale).sum())
    return n * (mem["latent_bytes_per_voxel"] + mem["sphere_bytes_per_voxel"])


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def bench_scale(s: int, ctx: dict, args, log) -> dict:
    from .baseline import decimate
    from .reference import render_reference

    scene, renderer, geo, camera = ctx["scene"], ctx["renderer"], ctx["geometry"], ctx["camera"]
    drawn_from = ctx["gl_camera"]
    side = image_side(camera, s, args.min_size)
    light = ctx["light"]
    trace = dict(camera=camera.to_dict(), size=(side, side), sun_dir=light["direction"],
                 sun_radiance=light["radiance"], env_sh=ctx["sh"], shadows=True, seed=s)
    ref, ref_s = _timed(lambda: render_reference(geo, spp=args.spp, **trace))
    renderer.set_setting("force_scale", s)
    renderer.render_network(drawn_from, side, side, force=True)   # first draw at this size (JIT), untimed
    times = []
    for _ in range(args.rounds):
        t = time.perf_counter()
        renderer.render_network(drawn_from, side, side, force=True)
        renderer.ctx.finish()
        times.append(time.perf_counter() - t)
    dap = renderer.read("network")[..., :3].copy()
    one = render_reference(geo, spp=1, **trace)
    budget = scale_bytes(ctx["memory"], ctx["cells"], s)
    lod, lod_bytes = decimate(geo, budget)
    lod_trace = dict(trace, seed=trace["seed"] + 500)   # its own noise: the full mesh may fit the budget
    lod_img = (render_reference(lod, spp=args.spp, **lod_trace) if len(lod.mesh.faces)
               else render_reference(lod_background(geo), spp=1, **lod_trace))
    covered = max(1, int(ctx["coverage_of"](ref)))
    row = {"scale": s, "size": side, "covered_pixels": covered, "reference_seconds": round(ref_s, 3),
           "prefiltered": quality(dap, ref), "1spp": quality(one, ref), "decimated": quality(lod_img, ref),
           "decimated_faces": int(len(lod.mesh.faces)), "decimated_bytes": int(lod_bytes),
           "decimated_is_full_mesh": lod is geo,
           "prefiltered_bytes": int(budget), "voxels": int((ctx["cells"][:, 0] == s).sum()),
           "prefiltered_ms": round(1e3 * float(np.median(times)), 3)}
    row["bytes_per_pixel"] = {"prefiltered": round(budget / covered, 1), "scene": round(ctx["scene_bytes"] / covered, 1)}
    row["equal_quality"] = equal_quality(geo, trace, ref, row["prefiltered"]["mse"])
    eq = row["equal_quality"]
    log(f"  scale {s} ({side}x{side}): MSE prefiltered {row['prefiltered']['mse']:.3g}, decimated "
        f"{row['decimated']['mse']:.3g} ({row['decimated_faces']} faces), 1 spp {row['1spp']['mse']:.3g}; "
        f"{row['prefiltered_ms']:.1f} ms vs ray tracing {eq['spp']} spp {eq['ms']:.1f} ms")
    row["images"] = {"reference": ref, "prefiltered": dap, "decimated": lod_img, "1spp": one}
    return row


def lod_background(geo):
    """A scene the LoD has vanished from: one degenerate face far outside the view (the tracer needs
    a mesh), so the render is the environment alone."""
    import dataclasses

    import trimesh

    mesh = trimesh.Trimesh([[50.0, 50.0, 50.0], [50.0, 50.0, 50.001], [50.0, 50.001, 50.0]], [[0, 1, 2]],
                           process=False)
    return dataclasses.replace(geo, mesh=mesh, parts=[], base_colour=np.zeros((1, 3), np.float32),
                               roughness=np.ones(1, np.float32), metallic=np.zeros(1, np.float32),
                               two_sided=np.ones(1, bool))


def equal_quality(geo, trace: dict, ref: np.ndarray, target_mse: float) -> dict:
    """The fewest ray-traced spp (EQ_SPP) reaching ``target_mse`` against ``ref``, and its time."""
    from inshade.metrics import mse

    from .reference import render_reference

    last = None
    for spp in EQ_SPP:
        img, secs = _timed(lambda: render_reference(geo, spp=spp, **dict(trace, seed=trace["seed"] + 1000)))
        last = {"spp": spp, "ms": round(1e3 * secs, 2), "mse": float(mse(img.astype(np.float64), ref)),
                "reached": False}
        if last["mse"] <= target_mse:
            last["reached"] = True
            break
    return last


# how the memory table names each cell -> slot index layout (codegen/voxel_index.py)
INDEX_LABELS = {"dense": "dense R32UI grid, every scale",
                "bricks": "R32UI bricks of {brick}^3 where voxels are + a brick table per scale"}


def index_label(m: dict) -> str:
    """The index's layout, and the dense grid's bytes beside another layout's."""
    kind = m.get("index", "dense")
    label = INDEX_LABELS[kind].format(brick=m.get("brick"))
    if kind == "dense":
        return label
    return (f"{label}; a dense R32UI grid of every scale: {m['dense_index_bytes']} B, "
            f"{m['dense_index_bytes_per_voxel']} B per voxel")


# scenes made of the hidden-occlusion case alone: their report adds masks against mean alpha
HIDDEN_OCCLUSION_SCENES = ("slabs",)


def bench_asset(folder: Path, args, cache, log) -> dict:
    from inshade.runtime.renderer import SceneRenderer

    from .baseline import lod_bytes
    from .memory import memory_report
    from .user_asset import asset_geometry

    scene, bundle, metrics = load_asset(folder)
    settings = metrics["settings"]
    # the traced methods see the unit box; a glTF file's pass is drawn from the camera in its coordinates
    try:
        geo, camera = asset_geometry(folder, settings, scene.make_camera())
    except ValueError as exc:     # a file asset's copy that cannot be read, a camera with no box twin
        raise BenchError(str(exc)) from None
    node = next(n for n in bundle.nodes if n.type == "sparse_voxels")
    cells = np.asarray(bundle.tensor(node, "cells"))
    mem = memory_report(bundle)
    scales = args.scales or list(range(int(node.params["scale_min"]), int(node.params["scale_max"]) + 1))
    bad = [s for s in scales if not node.params["scale_min"] <= s <= node.params["scale_max"]]
    if bad:
        raise BenchError(f"--scales: {bad[0]} is outside {folder.name}'s scales "
                         f"{node.params['scale_min']}..{node.params['scale_max']}")
    renderer = SceneRenderer(scene, cache=cache, settings={"shadows": True, "view": "prefiltered"}, bundles=[bundle])
    values = dict(renderer.values)
    light = sun(scene)
    sh = np.asarray(environment_sh(scene, values), np.float32)
    ctx = {"scene": scene, "renderer": renderer, "geometry": geo, "camera": camera, "gl_camera": scene.make_camera(),
           "cells": cells,
           "memory": mem, "sh": sh, "scene_bytes": lod_bytes(len(geo.mesh.vertices), len(geo.mesh.faces)),
           "light": {"direction": [float(v) for v in light.direction], "radiance": float(np.mean(light.intensity))}}
    env_only = None

    def coverage_of(ref):   # pixels whose reference differs from the bare environment
        nonlocal env_only
        if env_only is None or env_only.shape != ref.shape:
            from .reference import render_reference

            env_only = render_reference(lod_background(geo), camera=ctx["camera"].to_dict(),
                                        size=ref.shape[1::-1], spp=1, sun_dir=ctx["light"]["direction"],
                                        sun_radiance=ctx["light"]["radiance"], env_sh=sh)
        return int((np.abs(ref - env_only).max(-1) > 1e-4).sum())

    ctx["coverage_of"] = coverage_of
    log(f"{folder.name}: {geo.name} ({len(geo.mesh.faces)} faces), {len(cells)} voxels, scales {scales}")
    try:
        rows = [bench_scale(s, ctx, args, log) for s in scales]
    finally:
        renderer.release()
    crossover = max((r["scale"] for r in rows if r["prefiltered_ms"] < r["equal_quality"]["ms"]), default=None)
    hidden = None
    if settings["scene"] in HIDDEN_OCCLUSION_SCENES:
        from .hidden_occlusion import measure

        log(f"{folder.name}: hidden occlusion, coverage masks vs mean alpha")
        hidden = measure(bundle, geo, camera, scales, spp=args.spp, sun_dir=ctx["light"]["direction"],
                         sun_radiance=ctx["light"]["radiance"], sh=sh,
                         image_side=lambda cam, s: image_side(cam, s, args.min_size))
    return {"hidden_occlusion": hidden, "folder": portable_path(folder), "scene": settings["scene"], "faces": int(len(geo.mesh.faces)),
            "scene_bytes": ctx["scene_bytes"], "memory": mem, "rows": rows, "crossover_scale": crossover,
            "bake": {"data_seconds": metrics.get("bake_seconds"), "train_seconds": metrics.get("train_seconds"),
                     "rays": metrics.get("bake_rays"), "preset": metrics.get("preset")},
            "lower_than_decimated_at_every_scale": all(r["prefiltered"]["mse"] < r["decimated"]["mse"] for r in rows)}


def run(args: Settings) -> int:
    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    if args.spp < 1 or args.rounds < 1 or args.min_size < 1:
        raise BenchError("--spp, --rounds and --min-size must be >= 1")
    folders = asset_folders(args.assets)
    from inshade.runtime.context import gl_info, shared_context
    from inshade.runtime.programs import ProgramCache

    gl = gl_info(shared_context())
    log(f"GL_RENDERER: {gl['renderer']}")
    cache = ProgramCache(shared_context())
    out = Path(args.out)
    results = {"assets": {}}
    images = {}
    for folder in folders:
        a = bench_asset(folder, args, cache, log)
        images[folder.name] = {r["scale"]: r.pop("images") for r in a["rows"]}
        results["assets"][folder.name] = a
        out.mkdir(parents=True, exist_ok=True)
        atomic_write(out / f"{STEM}.partial.json", json.dumps(results, indent=2))
    results["machine"] = machine(gl)
    results["settings"] = {"spp": args.spp, "min_size": args.min_size, "rounds": args.rounds, "eq_spp": list(EQ_SPP)}
    write_report(out, STEM, results, markdown, lambda r, p: plot(r, p, images))
    (out / f"{STEM}.partial.json").unlink(missing_ok=True)
    return 0


# ---------------------------------------------------------------------------------------------
# report

def _g(v) -> str:
    return "—" if v is None else f"{v:.3g}"


def markdown(r: dict) -> str:
    lines = [f"# {KIND}: prefiltered voxels vs full geometry and a decimated LoD", "", machine_markdown(r["machine"]), "",
             f"Reference: full-geometry ray tracing at {r['settings']['spp']} spp (embree, direct light: sun + SH "
             "environment, shadows). MSE on linear RGB over the whole image, FLIP on the sRGB display values.", ""]
    for name, a in r["assets"].items():
        m = a["memory"]
        lines += [f"## {name} ({a['scene']}, {a['faces']} faces, {m['voxels']} voxels)", "",
                  "### Quality", ""]
        lines += markdown_table(
            ["scale", "image", "MSE prefiltered", "MSE decimated (faces)", "MSE 1 spp", "FLIP prefiltered",
             "FLIP decimated", "FLIP 1 spp"],
            [[r_["scale"], f"{r_['size']}²", _g(r_["prefiltered"]["mse"]),
              f"{_g(r_['decimated']['mse'])} ({'full mesh fits' if r_['decimated_is_full_mesh'] else r_['decimated_faces']})",
              _g(r_["1spp"]["mse"]),
              _g(r_["prefiltered"]["flip"]), _g(r_["decimated"]["flip"]), _g(r_["1spp"]["flip"])] for r_ in a["rows"]])
        lines += ["", f"Lower MSE than the decimated LoD at every scale: **{'yes' if a['lower_than_decimated_at_every_scale'] else 'no'}** "
                      "(where the full mesh fits the budget, the 'LoD' is the full geometry at the reference's spp, "
                      "other noise: only sampling noise separates it from the reference).",
                  "", "### Memory", ""]
        lines += [f"Per voxel: {m['bytes_per_voxel']} B (latents {m['latent_bytes_per_voxel']} B {m['precision']}, sphere "
                  f"{m['sphere_bytes_per_voxel']} B, index share {m['index_bytes_per_voxel']} B; the paper: "
                  f"{m['paper_bytes_per_voxel']} B). Fixed costs: decoders {m['decoder_bytes']} B, index {m['index_bytes']} B "
                  f"({index_label(m)}). "
                  f"Full scene {a['scene_bytes']} B (float32 positions, uint32 indices, 8-bit material per face). "
                  "Per-scale bytes (and the LoD's budget) count that scale's latents and spheres.", ""]
        lines += markdown_table(
            ["scale", "voxels", "prefiltered B", "decimated B", "prefiltered B/pixel", "scene B/pixel", "scene / prefiltered"],
            [[r_["scale"], r_["voxels"], r_["prefiltered_bytes"], r_["decimated_bytes"],
              r_["bytes_per_pixel"]["prefiltered"], r_["bytes_per_pixel"]["scene"],
              f"{a['scene_bytes'] / r_['prefiltered_bytes']:.1f}×"] for r_ in a["rows"]])
        lines += ["", "### Speed (same run)", ""]
        lines += markdown_table(
            ["scale", "image", "prefiltered ms (GL)", "equal-quality ray tracing", "ray tracing ms (CPU)", "faster"],
            [[r_["scale"], f"{r_['size']}²", r_["prefiltered_ms"],
              f"{r_['equal_quality']['spp']} spp" + ("" if r_["equal_quality"]["reached"] else " (not reached)"),
              r_["equal_quality"]["ms"],
              "prefiltered" if r_["prefiltered_ms"] < r_["equal_quality"]["ms"] else "ray tracing"] for r_ in a["rows"]])
        lines += ["", f"Crossover (finest scale where the prefiltered frame is faster): {a['crossover_scale']} "
                      "(the paper: around scale 5).", "", "### Bake", ""]
        b = a["bake"]
        lines += [f"Preset {b['preset']}: data {b['data_seconds']} s ({b['rays']}), training {b['train_seconds']} s.", ""]
        if a.get("hidden_occlusion"):
            lines += ["### Hidden occlusion: coverage masks vs mean alpha", "",
                      "The torch twin of the march with the decoded coverage masks (correlated transmittance) and "
                      "with each mask replaced by its mean (uncorrelated alpha, a statistical aggregate's "
                      "assumption), against the reference; sun shadows off on both sides "
                      "(hidden_occlusion.py).", ""]
            lines += markdown_table(
                ["view", "scale", "image", "MSE coverage masks", "MSE mean alpha", "mean alpha / masks"],
                [[h["view"], h["scale"], f"{h['size']}²", _g(h["mse_masks"]), _g(h["mse_mean_alpha"]),
                  f"{h['ratio']:.2f}×"] for h in a["hidden_occlusion"]])
            lines += [""]
    return "\n".join(lines)


def plot(r: dict, path: Path, images: dict) -> None:
    plt = matplotlib_pyplot()
    names = list(r["assets"])
    fig, axes = plt.subplots(len(names), 2, figsize=(11, 4 * len(names)), squeeze=False)
    for row, name in enumerate(names):
        a = r["assets"][name]
        ax = axes[row][0]
        scales = [x["scale"] for x in a["rows"]]
        for method, style in (("prefiltered", "o-"), ("decimated", "s--"), ("1spp", "^:")):
            ax.semilogy(scales, [max(x[method]["mse"], 1e-12) for x in a["rows"]], style, label=method)
        ax.set_xlabel("scale")
        ax.set_ylabel("MSE vs reference")
        ax.set_title(name)
        ax.legend()
        ax = axes[row][1]
        s = scales[-1]
        strip = np.concatenate([_display(images[name][s][k]) for k in ("reference", "prefiltered", "decimated", "1spp")], 1)
        ax.imshow(strip, interpolation="nearest")
        ax.set_title(f"scale {s}: reference | prefiltered | decimated | 1 spp")
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper

CLAIMS = {
    "crossover": Claim("Deep Appearance Prefiltering (Bako et al. 2022), Sec. 6.3", "finest scale at which the "
                       "prefiltered frame is faster than equal-quality ray tracing", "around scale 5 (GPU beam "
                       "tracer + TensorRT vs OptiX)", 5.0),
    "voxel": Claim("Deep Appearance Prefiltering, Sec. 5.4", "bytes per voxel", "just over 3 KB (797 fp32 floats)",
                   3188.0, higher_better=False),
}


def headlines(r: dict) -> list[dict]:
    rows = []
    for asset, a in r["assets"].items():
        name = asset.removeprefix("appearance_prefilter_")
        c = a["crossover_scale"]
        rows.append(claim_row(CLAIMS, "appearance_prefilter", "crossover", "none (ray tracing faster at every scale)"
                              if c is None else f"scale {c}", None if c is None else float(c), name))
        per = a["memory"]["bytes_per_voxel"]
        rows.append(claim_row(CLAIMS, "appearance_prefilter", "voxel", f"{per:.0f} B", float(per), name))
    return rows


BENCH = Bench(KIND, __doc__, Settings, run, claims=CLAIMS, headlines=headlines, sizes={
    "cpu": sized(60, assets="trained/appearance_prefilter_grove", scales=(3, 4), spp=16, rounds=2),
    "device": sized(10, scales=(3, 4, 5), rounds=5)})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite
