"""`inshade bench di_radiance_field`: DI-compressed radiance fields against the uncompressed grids.

The procedural field (field.py) is baked at ``--grid``^3 (float32: the reference, as the paper's
DVGO grids are); one density head per ``--density-ratios`` value and one colour head per
``--colour-ratios`` value are trained (model.py; cached under ``--cache`` by their settings, so a
re-run only renders), and every (density, colour) pair is one DI bundle. For each pair:

- quality: the GL march (passes/di_radiance_field.frag, exact lookups) of the DI network against the
  same march through the float32 grids, over ``--views`` orbit views at ``--size``^2: PSNR (linear RGB,
  peak 1, all pixels: the background included) and FLIP (LDR, sRGB of the colour clipped to [0, 1]),
  mean over the views;
- memory: MB per field (density, colour) for the DI heads (8-bit primaries + fp32 cascaded, cells
  only) and the float32 grids, and the achieved ratios (the paper's sizing rounds N_p to 8 and N_c
  to 4 under the budget, so a head lands at or above its nominal ratio).

Speed, in the same run: one frame at ``--time-size``^2 through the float32 grids, the DI network
(exact path) and the DI network (hardware-filtered "fast" lookups), at the ``--time-pair`` pair
(default 10x/10x), ``--rounds`` interleaved rounds (draw + glFinish wall time on llvmpipe).
Writes ``di_radiance_field.{json,md,png}`` into ``--out``.
"""
from __future__ import annotations

import hashlib
import json
import math
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bench.contract import Bench, option, sized
from inshade.bench.entry import Claim, claim_row
from inshade.bench.harness import (BenchError, WallClock, atomic_write, interleave, label_axes, machine,
                                   machine_markdown, markdown_table, matplotlib_pyplot, save_figure, write_report)

STEM = "di_radiance_field"


@dataclass
class Settings:
    out: str = option("docs/bench", "report folder (default %(default)s)")
    cache: str = option("build/di_radiance_field", "trained heads cache (default %(default)s)")
    grid: int = option(128, "field grid side (default %(default)s)")
    colour_ratios: str = option("5,10,25,50,100", "colour compression ratios (default %(default)s)")
    density_ratios: str = option("5,10", "density compression ratios (default %(default)s)")
    steps: int = option(800, "training steps per head (default %(default)s)")
    batch: int = option(8192, "samples per step (default %(default)s)")
    views: int = option(30, "orbit views for quality (default %(default)s)")
    size: int = option(128, "quality image side (default %(default)s)")
    time_size: int = option(512, "timed frame side (default %(default)s)")
    time_pair: str = option("10,10", "density,colour ratios of the timed DI (default %(default)s)")
    rounds: int = option(3, "interleaved timing rounds (default %(default)s)")
    quick: bool = option(False, "a smoke run: 32^3, 2 ratios, 4 views, 64^2, 50 steps, timed at 128^2 (options "
                                "given explicitly override it)")


# the smoke run's sizes, for every option still at its default
QUICK = dict(grid=32, colour_ratios="10,25", density_ratios="10", views=4, size=64, steps=50, time_size=128, rounds=1,
             time_pair="10,10")


def _ratios(text: str, what: str) -> list[float]:
    try:
        v = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise BenchError(f"{what}: expected comma-separated numbers, got {text!r}") from None
    if not v or any(x <= 1 for x in v):
        raise BenchError(f"{what}: ratios must be > 1, got {text!r}")
    return v


def orbit_views(n: int) -> list[dict]:
    """n cameras around the scene: yaw every 360/n degrees, pitch swinging between -45 and +15."""
    from .train import orbit_camera

    return [orbit_camera(yaw=360.0 * i / n, pitch=-15.0 - 30.0 * math.sin(2.0 * math.pi * 3 * i / n), distance=2.3)
            for i in range(n)]


# ---------------------------------------------------------------------------------------------
# heads (cached)

def head_settings(args, head: str, ratio: float) -> dict:
    from .train import Settings

    d = Settings()      # the trainer's quick preset
    return {"head": head, "ratio": ratio, "grid": args.grid, "steps": args.steps, "batch": args.batch,
            "lr": getattr(d, f"lr_{head}"), "shell_fraction": d.shell_fraction, "seed": d.seed, "scene": d.scene}


def cached_head(args, head: str, ratio: float, grids, log):
    """(primary, cascaded, metrics) of one head: from the cache, else trained here and cached."""
    import torch

    from inshade.bundle import load
    from inshade.models.graph import GraphModule

    from . import KIND, model

    s = head_settings(args, head, ratio)
    key = hashlib.sha1(json.dumps(s, sort_keys=True).encode()).hexdigest()[:12]
    folder = Path(args.cache) / f"{head}_{ratio:g}x_{key}"
    plan = model.plan(args.grid, head, ratio)
    if (folder / "bundle.json").is_file():
        b = load(folder)
        g = GraphModule.from_bundle(b)
        sizes = (g.nodes["primary"].resolution[0], g.nodes["cascaded"].resolution[0])
        if sizes == (plan.n_primary, plan.n_cascaded):   # else the sizing changed since: train again
            log(f"{head} {ratio:g}x: cached ({folder})")
            return g.nodes["primary"], g.nodes["cascaded"], b.meta["metrics"]
    log(f"{head} {ratio:g}x: training {args.steps} steps")
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        h = model.train_head(head, ratio, *grids, steps=args.steps, batch=args.batch, lr=s["lr"],
                             shell_fraction=s["shell_fraction"], seed=s["seed"], progress=False)
    finally:
        torch.set_num_threads(old)
    g = GraphModule([("x", 3, "position")])
    g.add("primary", h.primary, "x")
    g.add("cascaded", h.cascaded, "primary")
    g.output("y", "cascaded")
    metrics = {**h.metrics(), "settings": s}
    b = g.export(f"{KIND}_head", f"{head}_{ratio:g}x", metrics=metrics)
    if folder.exists():
        import shutil

        shutil.rmtree(folder)
    b.save(folder)
    g2 = GraphModule.from_bundle(load(folder))    # what the cache returns next time (8-bit primary)
    return g2.nodes["primary"], g2.nodes["cascaded"], metrics


# ---------------------------------------------------------------------------------------------
# renders

class Scene:
    """A scene folder with the float32 grids (rfg) and one DI bundle (rfd), and its renderer."""

    def __init__(self, root: Path, grid_folder: Path, di_bundle, cache, lut_filter: str = "exact"):
        from inshade.runtime.renderer import SceneRenderer
        from inshade.scene.description import load_scene

        from .train import scene_dict

        self.folder = Path(tempfile.mkdtemp(prefix="rf-", dir=root))
        di_bundle.save(self.folder)
        data = scene_dict("rf_bench", "bench", grid_folder=str(grid_folder.resolve()), lut_filter=lut_filter)
        atomic_write(self.folder / "scene.json", json.dumps(data))
        self.renderer = SceneRenderer(load_scene(self.folder), cache=cache)

    def draw(self, camera: dict, size: int, view: str, force: bool = False) -> np.ndarray:
        from inshade.scene.camera import camera_from_dict

        self.renderer.set_setting("view", view)
        self.renderer.render_network(camera_from_dict(camera), size, size, force=force)
        return self.renderer.read("network")

    def release(self):
        self.renderer.release()


def _display(img: np.ndarray) -> np.ndarray:
    from inshade.metrics import srgb_oetf

    return srgb_oetf(np.clip(img[..., :3], 0.0, 1.0)).astype(np.float32)


def quality(test: np.ndarray, ref: np.ndarray, use_flip: bool) -> tuple[float, float | None]:
    from inshade.metrics import flip, psnr

    p = float(psnr(test[..., :3], ref[..., :3]))
    return p, (float(flip(_display(ref), _display(test))) if use_flip else None)


# ---------------------------------------------------------------------------------------------
# run

def _log(msg):
    print(msg, file=sys.stderr, flush=True)


def run(args) -> int:
    from inshade.metrics import flip_unavailable
    from inshade.runtime.context import gl_info, shared_context
    from inshade.runtime.programs import ProgramCache

    from . import field, model
    from .train import march_render

    density_ratios, colour_ratios, time_pair = _checked_ratios(args)
    ctx = shared_context()
    gl = gl_info(ctx)
    _log(f"GL_RENDERER: {gl['renderer']}")
    use_flip = flip_unavailable() is None
    t0 = time.perf_counter()
    grids = field.bake(args.grid)
    bake_s = time.perf_counter() - t0
    heads = {}
    t0 = time.perf_counter()
    for r in density_ratios:
        heads[("density", r)] = cached_head(args, "density", r, grids, _log)
    for r in colour_ratios:
        heads[("colour", r)] = cached_head(args, "colour", r, grids, _log)
    heads_s = time.perf_counter() - t0
    render = march_render(args.grid, 1.0)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cache = ProgramCache(ctx)
    field_mb = {h: model.uncompressed_bytes(args.grid, h) / 1e6 for h in model.HEADS}
    rows, images, timing = _bench_pairs(ctx, cache, args, grids, heads, density_ratios, colour_ratios, time_pair,
                                        render, field_mb, use_flip, out)
    cache.release()
    nominal10 = [r for r in rows if r["density_ratio"] == 10 and r["colour_ratio"] == 10]
    result = {
        "benchmark": STEM, "quick": bool(args.quick), "machine": machine(gl),
        "field": {"grid": args.grid, "scene": "trinket", "density_mb": field_mb["density"], "colour_mb": field_mb["colour"],
                  "bake_seconds": round(bake_s, 2), "precision": "float32 (the reference)"},
        "render": {"views": args.views, "size": args.size, **render, "lut_filter": "exact"},
        "training": {"steps": args.steps, "batch": args.batch, "seconds_this_run": round(heads_s, 1),
                     "note": "per-head train_seconds are from the run that trained them (cached heads are reused)"},
        "rows": rows, "timing": timing,
        "target": {"psnr_at_10x_overall": 35.0,
                   "met": bool(nominal10) and nominal10[0]["psnr_mean"] >= 35.0},
    }
    write_report(out, STEM, result, markdown, lambda r, p: plot(r, p, images))
    (out / f"{STEM}.partial.json").unlink(missing_ok=True)
    _log(f"wrote {out / (STEM + '.json')}, .md, .png")
    return 0


def _checked_ratios(args) -> tuple[list[float], list[float], list[float]]:
    """(density ratios, colour ratios, the timed pair) once every option is checked, each head's sizing
    included: a BenchError names the option at fault."""
    from . import field, model

    colour_ratios, density_ratios = _ratios(args.colour_ratios, "--colour-ratios"), _ratios(args.density_ratios, "--density-ratios")
    time_pair = _ratios(args.time_pair, "--time-pair")
    if len(time_pair) != 2 or time_pair[0] not in density_ratios or time_pair[1] not in colour_ratios:
        raise BenchError(f"--time-pair: density,colour ratios among the benched ones, got {args.time_pair!r}")
    if args.views < 1 or args.size < 8 or args.time_size < 8 or args.rounds < 1:
        raise BenchError("--views and --rounds must be >= 1, --size and --time-size >= 8")
    try:
        field.check_resolution(args.grid, "--grid")
        for r in density_ratios:
            model.plan(args.grid, "density", r)
        for r in colour_ratios:
            model.plan(args.grid, "colour", r)
    except ValueError as e:
        raise BenchError(str(e)) from None
    return density_ratios, colour_ratios, time_pair


def _bench_pairs(ctx, cache, args, grids, heads: dict, density_ratios, colour_ratios, time_pair, render: dict,
                 field_mb: dict, use_flip: bool, out: Path) -> tuple[list, dict, dict]:
    """Every (density, colour) pair as one DI bundle, rendered beside the float32 grids over the orbit
    views: (rows, first-view images by pair and "uncompressed", the timed pair's frame times). The rows
    so far are kept in ``STEM.partial.json`` as the pairs finish."""
    from . import model

    views = orbit_views(args.views)
    rows, images, timing = [], {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        grid_folder = root / "grid"
        model.grid_graph(*grids).export(model.KIND, "grid_fp32").save(grid_folder)
        refs = None
        for dr in density_ratios:
            for cr in colour_ratios:
                graph = model.di_graph({"colour": heads[("colour", cr)][:2], "density": heads[("density", dr)][:2]})
                bundle = graph.export(model.KIND, f"di_{dr:g}x_{cr:g}x", render=render)
                t1 = time.perf_counter()
                sc = Scene(root, grid_folder, bundle, cache)
                try:
                    if refs is None:
                        refs = [sc.draw(v, args.size, "uncompressed") for v in views]
                        images["uncompressed"] = refs[0]
                    q = [quality(sc.draw(v, args.size, "di"), ref, use_flip) for v, ref in zip(views, refs)]
                    images[(dr, cr)] = sc.draw(views[0], args.size, "di")
                    if [dr, cr] == time_pair:
                        timing = time_frames(ctx, sc, root, grid_folder, bundle, cache, views[0], args, _log)
                finally:
                    sc.release()
                row = _pair_row(dr, cr, heads, field_mb, q, use_flip, time.perf_counter() - t1)
                rows.append(row)
                _log(f"density {dr:g}x colour {cr:g}x ({row['overall_ratio']:.1f}x overall): PSNR {row['psnr_mean']:.2f} dB "
                     f"(min {row['psnr_min']:.2f}), FLIP {row['flip_mean']}, {row['seconds']} s")
                atomic_write(out / f"{STEM}.partial.json", json.dumps(rows, indent=1))
    return rows, images, timing


def _pair_row(dr: float, cr: float, heads: dict, field_mb: dict, q: list, use_flip: bool, seconds: float) -> dict:
    """One pair's report row: each head's sizing and memory, the overall ratio, PSNR / FLIP over the views."""
    dm, cm = heads[("density", dr)][2], heads[("colour", cr)][2]
    di_b = dm["bytes"] + cm["bytes"]
    return {"density_ratio": dr, "colour_ratio": cr,
            "density": {"n_primary": dm["n_primary"], "n_cascaded": dm["n_cascaded"], "rho": dm["rho"],
                        "mb": dm["bytes"] / 1e6, "achieved_ratio": round(field_mb["density"] * 1e6 / dm["bytes"], 3),
                        "train_seconds": dm["train_seconds"]},
            "colour": {"n_primary": cm["n_primary"], "n_cascaded": cm["n_cascaded"], "rho": cm["rho"],
                       "mb": cm["bytes"] / 1e6, "achieved_ratio": round(field_mb["colour"] * 1e6 / cm["bytes"], 3),
                       "train_seconds": cm["train_seconds"]},
            "di_mb": di_b / 1e6, "overall_ratio": round(sum(field_mb.values()) * 1e6 / di_b, 3),
            "psnr_mean": round(float(np.mean([p for p, _ in q])), 3),
            "psnr_min": round(float(np.min([p for p, _ in q])), 3),
            "flip_mean": None if not use_flip else round(float(np.mean([f for _, f in q])), 5),
            "seconds": round(seconds, 1)}


def time_frames(ctx, sc: Scene, root: Path, grid_folder: Path, bundle, cache, camera: dict, args, log) -> dict:
    """Frame time at time_size^2: float32 grids vs DI (exact) in one renderer (a uniform switches the
    view), interleaved; DI (fast lookups) from a second renderer, interleaved with them."""
    from inshade.scene.camera import camera_from_dict

    cam = camera_from_dict(camera)
    size = args.time_size
    fast = Scene(root, grid_folder, bundle, cache, lut_filter="fast")
    try:
        clock = WallClock(ctx.finish)
        first = {}
        for name, (s, view) in {"uncompressed": (sc, "uncompressed"), "di_exact": (sc, "di"), "di_fast": (fast, "di")}.items():
            first[name] = round(clock.time(lambda: s.draw(camera, size, view, force=True)), 3)

        def frame(s, view):
            def fn():
                s.renderer.set_setting("view", view)
                s.renderer.render_network(cam, size, size, force=True)
            return fn

        t = interleave({"uncompressed": frame(sc, "uncompressed"), "di_exact": frame(sc, "di"),
                        "di_fast": frame(fast, "di")}, rounds=args.rounds, warmup=0, clock=clock)
    finally:
        fast.release()
    out = {"size": size, "rounds": args.rounds, "clock": "draw + glFinish wall time", "first_draw_s": first}
    for name, timing in t.items():
        out[name] = {"ms_median": round(1e3 * timing.median, 1), "ms_min": round(1e3 * timing.min, 1),
                     "ms_max": round(1e3 * timing.max, 1)}
    log(f"frame {size}^2: " + ", ".join(f"{k} {v['ms_median']} ms" for k, v in out.items() if isinstance(v, dict) and "ms_median" in v))
    return out


# ---------------------------------------------------------------------------------------------
# report

def markdown(r: dict) -> str:
    f = r["field"]
    lines = [f"# {STEM}: DI-compressed radiance field vs the uncompressed grids", "", machine_markdown(r["machine"]), "",
             f"Field: procedural `{f['scene']}` at {f['grid']}³, float32: density {f['density_mb']:.2f} MB, colour "
             f"(12-channel degree-1 SH) {f['colour_mb']:.2f} MB. Quality: the GL march of the DI network vs the same "
             f"march through the float32 grids, {r['render']['views']} orbit views at {r['render']['size']}², step "
             f"{r['render']['step']:.5f} (one voxel), exact lookups; PSNR on linear RGB (peak 1, background included), "
             "FLIP (LDR) on sRGB. MB count cells (8-bit primaries, fp32 cascaded arrays).", "",
             f"Target: >= 35 dB at 10x overall (the 10x density / 10x colour pair): "
             f"**{'met' if r['target']['met'] else 'not met'}**.", ""]
    lines += markdown_table(
        ["density x", "colour x", "overall x", "density MB (Np/Nc)", "colour MB (Np/Nc)", "PSNR dB (min)", "FLIP"],
        [[f"{x['density_ratio']:g} ({x['density']['achieved_ratio']:.1f})", f"{x['colour_ratio']:g} ({x['colour']['achieved_ratio']:.1f})",
          f"{x['overall_ratio']:.1f}", f"{x['density']['mb']:.3f} ({x['density']['n_primary']}/{x['density']['n_cascaded']})",
          f"{x['colour']['mb']:.3f} ({x['colour']['n_primary']}/{x['colour']['n_cascaded']})",
          f"{x['psnr_mean']:.2f} ({x['psnr_min']:.2f})", "—" if x["flip_mean"] is None else f"{x['flip_mean']:.4f}"]
         for x in r["rows"]])
    lines += ["", "Ratios: nominal (achieved, cells only). Sizing (model.py plan): N_c a multiple of 4, N_p the largest "
              "multiple of 8 that fits the budget with N_p / N_c within 15% of the paper's rho (supp. Table 6).", ""]
    t = r.get("timing") or {}
    if t:
        lines += [f"## Frame time at {t['size']}² ({t['clock']}, median of {t['rounds']} interleaved rounds)", ""]
        lines += markdown_table(["variant", "ms median", "min", "max", "first draw s"],
                                [[k, t[k]["ms_median"], t[k]["ms_min"], t[k]["ms_max"], t["first_draw_s"][k]]
                                 for k in ("uncompressed", "di_exact", "di_fast") if k in t])
    tr = r["training"]
    lines += ["", f"Training: {tr['steps']} steps per head, batch {tr['batch']}; per-head seconds: "
              + ", ".join(f"density {x['density_ratio']:g}x {x['density']['train_seconds']} s" for x in r["rows"] if x["colour_ratio"] == r["rows"][0]["colour_ratio"])
              + "; " + ", ".join(f"colour {x['colour_ratio']:g}x {x['colour']['train_seconds']} s" for x in r["rows"] if x["density_ratio"] == r["rows"][0]["density_ratio"])
              + f" ({tr['note']}).", ""]
    return "\n".join(lines)


def plot(r: dict, path: Path, images: dict) -> None:
    plt = matplotlib_pyplot()
    keys = [k for k in images if k != "uncompressed"]
    n = 1 + len(keys)
    cols = 2 * n
    fig = plt.figure(figsize=(max(12, 2.2 * n), 7))
    gs = fig.add_gridspec(2, cols)
    ax = fig.add_subplot(gs[0, : cols // 2])
    bx = fig.add_subplot(gs[0, cols // 2:])
    for dr in sorted({x["density_ratio"] for x in r["rows"]}):
        xs = [x for x in r["rows"] if x["density_ratio"] == dr]
        ax.plot([x["colour_ratio"] for x in xs], [x["psnr_mean"] for x in xs], "o-", label=f"density {dr:g}x")
        if xs[0]["flip_mean"] is not None:
            bx.plot([x["colour_ratio"] for x in xs], [x["flip_mean"] for x in xs], "o-", label=f"density {dr:g}x")
    for a, label in ((ax, "PSNR dB (mean of views)"), (bx, "FLIP (mean of views)")):
        a.set_xscale("log")
        label_axes(a, "colour compression (nominal)", label)
        a.legend()
    ax.axhline(35.0, color="grey", ls=":", lw=1)
    strip = [images["uncompressed"]] + [images[k] for k in keys]
    titles = ["fp32 grids"] + [f"DI d{k[0]:g}x c{k[1]:g}x" for k in keys]
    for i, (img, title) in enumerate(zip(strip, titles)):
        a = fig.add_subplot(gs[1, 2 * i: 2 * i + 2])
        a.imshow(_display(img), interpolation="nearest")
        a.set_title(title, fontsize=7)
        a.axis("off")
    save_figure(fig, path, f"DI radiance field, {r['field']['grid']}³", r, dpi=100)


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper

CLAIMS = {"10x": Claim("Differentiable Indirection (Datta et al. 2023), Sec. 6.0.3 / Fig. 7",
                       "PSNR of DI renders vs the uncompressed-grid renders at ~10x overall (dB)",
                       "density to 10x, RGB to 100x 'without losing significant details' (no number in the text)")}


def headlines(r: dict) -> list[dict]:
    rows = []
    for x in r["rows"]:
        if x["density_ratio"] == 10 and x["colour_ratio"] == 10:
            flip = "" if x["flip_mean"] is None else f", FLIP {x['flip_mean']:.4f}"
            rows.append(claim_row(CLAIMS, "di_radiance_field", "10x", f"{x['psnr_mean']:.2f} dB (min "
                                  f"{x['psnr_min']:.2f}){flip} at {x['overall_ratio']:.1f}x overall, "
                                  f"{r['field']['grid']}³", x["psnr_mean"]))
    return rows


BENCH = Bench(STEM, __doc__, Settings, run, quick=QUICK, quick_keeps_given=True, claims=CLAIMS, headlines=headlines,
              sizes={"cpu": sized(60, quick=True), "device": sized(15, quick=True, time_size=2048, rounds=7)})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite
