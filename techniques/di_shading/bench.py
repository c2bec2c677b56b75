"""`inshade bench di_shading`: the end-to-end optimised DI shading pipeline against independent
training, rendered through the GL driver (Differentiable Indirection, Datta et al. 2023 §4.3.3).

One asset (default trained/di_shading_bricks: the lambda sweep's samplers lambda_000 .. lambda_050,
the frozen DI Disney decoder brdf/, the uncompressed set set0/set1.png), one grazing view of the
plane (the scene camera), all through ``passes/shading_plane.frag``:

- for each lambda of the sweep: the sampler of that lambda + the DI Disney decoder (SHADING_VIEW
  end_to_end with that sampler bound as e2e; lambda = 0 is the independently trained sampler);
- the reference: SHADING_VIEW reference, 16 samples over each pixel's footprint of the
  uncompressed set (GL trilinear, RGBA8 + GL mips) shaded with the analytic Disney BRDF, averaged;
- context (not part of the sweep): the uncompressed set + GL mips, one trilinear sample per pixel,
  shaded with the DI Disney decoder (SHADING_VIEW trilinear) or the analytic BRDF (analytic).

The reference is computed in torch on the pass's own G-buffer (uv, duv/dx, duv/dy, hit point), with
the emulated trilinear sampler the samplers are trained against (box-filtered mips rounded to 8
bits): the GLSL reference view uses the driver's glGenerateMipmap, which on llvmpipe is biased by
up to 3-4 8-bit steps at the coarse levels -- enough to tip grazing normals below the horizon --
so it is reported beside it, not used as the ground truth.

Quality: PSNR (8-bit sRGB of the linear render clamped to [0, 1]) and mean FLIP (LDR) against the
reference, over the rows of the view where every pixel lies on the plane with valid derivatives.
Also: the torch held-out numbers the trainer recorded (metrics.json), the GLSL-vs-torch parity of
the end-to-end view on this view (the pass's G-buffer fed to model.py's twin), and the frame time
of the pass (end-to-end, independent, reference) at --time-size^2 (512^2) with GL_RENDERER; the paper's number
(< 1.5 ms at 4K, sampler + shading, RTX 3090) is quoted, not measured.

Writes ``di_shading.json``, ``.md``, ``.png`` (PSNR and FLIP per lambda) and
``di_shading_views.png`` (reference, then each lambda; below, |difference to the reference| x 4)
into ``--out``. ``--quick``: a tiny asset trained here (32^2 set, 30
steps per lambda), a 96x48 view (tests / smoke runs).
"""
from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bench.contract import Bench, option, sized
from inshade.bench.entry import Claim, claim_row
from inshade.bench.harness import (BenchError, clock_for, clock_record, interleave, machine, machine_markdown,
                                   markdown_table, matplotlib_pyplot, portable_path, write_report)
from inshade.metrics import flip, flip_unavailable, psnr, srgb_oetf

DEFAULT_OUT = "bench-out/di_shading"
DEFAULT_ASSET = "trained/di_shading_bricks"
PAPER = {"claim": "< 1.5 ms at 4K (3840x2160) for learned texture sampling + shading on an Nvidia RTX 3090; "
                  "+5% to +8% PSNR over independent training (Fig. 13 / Fig. 1)", "source": "paper §6.0.7, Fig. 1"}


@dataclass
class Settings:
    out: str = option(DEFAULT_OUT, f"output folder (default {DEFAULT_OUT})")
    asset: str = option(DEFAULT_ASSET, "a di_shading asset folder (default %(default)s)")
    width: int = option(512)
    height: int = option(256)
    repeats: int = option(5, "timed frames per variant (default 5)")
    time_size: int = option(512, "frame time measured at SIZE x SIZE (default 512)")
    quick: bool = option(False, "tiny run: a 32^2 set trained here, a 96x48 view")


def _errors() -> tuple:
    from inshade.techniques.di_shading.model import ShadingError

    return BenchError, ShadingError


# ---------------------------------------------------------------------------------------------

class ShadingRenderer:
    """The asset's scene with a chosen e2e sampler bundle: ``render(view, camera, w, h)`` ->
    (linear RGBA, inputs, derivatives, positions), each [H, W, 4] in image orientation."""

    def __init__(self, ctx, folder: Path, e2e: str, view: str, lut_filter: str = "exact"):
        from inshade.bundle import load
        from inshade.runtime.renderer import SceneRenderer
        from inshade.scene.description import load_scene
        from inshade.techniques.di_shading import VIEWS

        self.scene = load_scene(folder)
        bundles = [load(folder / e2e), load(folder / self.scene.networks[1].bundle.name),
                   load(folder / "brdf")]
        self.renderer = SceneRenderer(self.scene, ctx, bundles=bundles,
                                      settings={"view": VIEWS[view], "lut_filter": lut_filter})

    def render(self, camera, width: int, height: int, force: bool = False):
        r = self.renderer
        r.render_network(camera, width, height, force=force)
        return tuple(r.read("network", i) for i in range(4))

    def release(self):
        self.renderer.release()
        self.renderer.cache.release()


def plane_rows(inputs: np.ndarray) -> np.ndarray:
    """Mask of the rows whose every pixel and its 8 neighbours hit the plane (valid derivatives)."""
    hit = np.pad(inputs[..., 3] > 0.5, 1, mode="edge")
    h, w = inputs.shape[:2]
    ok = np.ones((h, w), bool)
    for dy in range(3):
        for dx in range(3):
            ok &= hit[dy:dy + h, dx:dx + w]
    return ok.all(1)


def display(linear: np.ndarray) -> np.ndarray:
    return srgb_oetf(np.clip(linear[..., :3], 0.0, 1.0))


def torch_twin(folder: Path, e2e: str, inputs, positions, eye) -> np.ndarray:
    """model.py's torch twin of the learned view on the pass's own G-buffer: linear [H, W, 3]."""
    import torch

    from inshade.bundle import load
    from inshade.models.graph import GraphModule
    from inshade.techniques.di_shading import model as ds

    sampler = GraphModule.from_bundle(load(folder / e2e))
    decoder = GraphModule.from_bundle(load(folder / "brdf"))
    x = torch.from_numpy(np.ascontiguousarray(inputs[..., :3].reshape(-1, 3), np.float32))
    p = torch.from_numpy(np.ascontiguousarray(positions[..., :3].reshape(-1, 3), np.float32))
    with torch.no_grad():
        geo = ds.plane_geometry(p, torch.tensor(eye, dtype=torch.float32))
        y = ds.shade_di(sampler(x), geo, decoder)
    return y.numpy().reshape(*inputs.shape[:2], 3)


def emulated_views(folder: Path, inputs, derivs, positions, eye):
    """The reference and the 1-sample views from the pass's own G-buffer, in torch on the emulated
    trilinear sampler (model.py `reference`: box-filtered mips rounded to 8 bits, the proxy the
    samplers are trained against): (reference, 1 sample + DI Disney, 1 sample + analytic), linear
    [H, W, 3], 0 off the plane."""
    import torch
    from PIL import Image

    from inshade.bundle import load
    from inshade.models.graph import GraphModule
    from inshade.models import footprint_sampler as fp
    from inshade.techniques.di_shading import model as ds

    lanes = np.concatenate([np.asarray(Image.open(folder / f"set{i}.png").convert("RGBA"), np.float32) / 255.0
                            for i in range(2)], -1)
    chain = fp.mip_chain(fp.texture_tensor(lanes))
    decoder = GraphModule.from_bundle(load(folder / "brdf"))
    hit = inputs[..., 3] > 0.5
    f = lambda a: torch.from_numpy(np.ascontiguousarray(a[hit], np.float32))  # noqa: E731
    x, d, p = f(inputs), f(derivs), f(positions)
    outs = [np.zeros(inputs.shape[:2] + (3,), np.float32) for _ in range(3)]
    eye = torch.tensor(eye, dtype=torch.float32)
    parts = [[], [], []]
    with torch.no_grad():
        for s in range(0, len(x), 16384):
            sl = slice(s, s + 16384)
            geo = ds.plane_geometry(p[sl, :3], eye)
            one = fp.emulated_trilinear(chain, x[sl, :2], x[sl, 2])
            parts[0].append(ds.reference(chain, x[sl, :2], d[sl, :2], d[sl, 2:], x[sl, 2], geo))
            parts[1].append(ds.shade_di(one, geo, decoder))
            parts[2].append(ds.shade_analytic(one, geo))
    for o, part in zip(outs, parts):
        if part:
            o[hit] = torch.cat(part).numpy()
    return tuple(outs)


def frame_times(ctx, folder: Path, camera, size: int, rounds: int, clock, best: str) -> dict:
    """Frame time of each pass at size x size, interleaved rounds (harness.interleave: every variant
    once per round, the order reversed every other round), so machine noise hits all alike."""
    from inshade.techniques.di_shading.train import lambda_folder

    variants = {"reference": (lambda_folder(0.0), "reference"), "independent": (lambda_folder(0.0), "end_to_end"),
                "end_to_end": (best, "end_to_end"), "trilinear": (lambda_folder(0.0), "trilinear"),
                "analytic": (lambda_folder(0.0), "analytic")}
    renderers = {}
    try:
        for key, (sampler, view) in variants.items():
            renderers[key] = ShadingRenderer(ctx, folder, sampler, view)
        calls = {k: (lambda r=r: r.render(camera, size, size, force=True)) for k, r in renderers.items()}
        return interleave(calls, rounds=rounds, clock=clock)
    finally:
        for r in renderers.values():
            r.release()


def _quick_asset(out: Path) -> Path:
    from inshade.techniques.di_shading import train as ds

    folder = out / "di_shading_quick"
    if ds.main(["-o", str(folder), "--size", "32", "--ratio", "2", "--steps", "30", "--samples", "4096",
                "--views", "2", "--batch", "1024"]) != 0:
        raise BenchError("training the --quick asset failed (see the error above)")
    return folder


def run(args) -> int:
    from inshade.runtime.context import gl_info, shared_context

    if args.width < 8 or args.height < 8 or args.repeats < 1 or args.time_size < 8:
        raise BenchError("--width, --height and --time-size must be >= 8 and --repeats >= 1")
    ctx = shared_context()
    gl = gl_info(ctx)
    print(f"GL_RENDERER: {gl['renderer']}", file=sys.stderr)
    out = Path(args.out)
    folder = _quick_asset(out) if args.quick else Path(args.asset)
    if not (folder / "scene.json").is_file() or not (folder / "metrics.json").is_file():
        raise BenchError(f"{folder}: no di_shading asset here (scene.json, metrics.json); build one with "
                         f"`inshade train di_shading -o {folder} --preset ship`")
    trained = json.loads((folder / "metrics.json").read_text())
    from inshade.scene.description import load_scene
    from inshade.techniques.di_shading.train import lambda_folder

    scene = load_scene(folder)
    camera = scene.make_camera()
    w, h, ts = args.width, args.height, args.time_size
    lambdas = [float(s["lambda"]) for s in trained["sweep"]]
    clock = clock_for(ctx)

    gl_ref, inputs, derivs, positions = _render(ctx, folder, lambda_folder(0.0), "reference", camera, w, h)
    rows_ok = plane_rows(inputs)
    if rows_ok.sum() < 2:
        raise BenchError("the view shows fewer than 2 rows of plane: change the camera")
    eye = camera.uniforms(w, h)["u_eye"]
    t0 = time.perf_counter()
    ref, one_di, one_analytic = emulated_views(folder, inputs, derivs, positions, eye)
    ref_seconds = time.perf_counter() - t0
    flip_why = flip_unavailable()
    scores = _scorer(ref, gl_ref, rows_ok, flip_why)
    rows, renders, parity, parity_db = _lambda_sweep(ctx, folder, camera, w, h, trained, lambdas, inputs, eye,
                                                     scores)
    context = _context_views(ctx, folder, camera, w, h, scores, gl_ref, one_di, one_analytic)
    timings = frame_times(ctx, folder, camera, ts, args.repeats, clock, lambda_folder(trained["lambda_best"]))
    best = _psnr_gains(rows)
    view = {"width": w, "height": h, "camera": camera.to_dict(), "rows_scored": int(rows_ok.sum()),
            "pixels_scored": int(rows_ok.sum()) * w, "reference_seconds": round(ref_seconds, 2)}
    result = _result(folder, gl, clock, view, trained, best, flip_why, parity, parity_db, rows, context, timings, ts)
    write_report(out, "di_shading", result, markdown, plot)
    _views(renders, ref, rows_ok, out / "di_shading_views.png")
    print(f"wrote {out / 'di_shading.json'}, di_shading.md, di_shading.png, di_shading_views.png", file=sys.stderr)
    return 0


def _render(ctx, folder: Path, sampler: str, view: str, camera, width: int, height: int):
    """One render of the asset's scene with `sampler` bound as e2e, through `view` (see ShadingRenderer)."""
    r = ShadingRenderer(ctx, folder, sampler, view)
    try:
        return r.render(camera, width, height)
    finally:
        r.release()


def _scorer(ref, gl_ref, rows_ok: np.ndarray, flip_why):
    """scores(linear image) -> its PSNR and FLIP against the reference, and its PSNR against the GLSL
    reference view, over the plane rows (8-bit sRGB)."""
    crop = lambda img: display(img)[rows_ok]  # noqa: E731
    ref_d, gl_ref_d = crop(ref), crop(gl_ref)

    def scores(img):
        d = crop(img)
        return {"psnr": round(psnr(np.rint(d * 255), np.rint(ref_d * 255), peak=255.0), 4),
                "flip": None if flip_why else round(flip(ref_d, d), 5),
                "psnr_vs_gl_reference": round(psnr(np.rint(d * 255), np.rint(gl_ref_d * 255), peak=255.0), 4)}

    return scores


def _lambda_sweep(ctx, folder: Path, camera, w: int, h: int, trained: dict, lambdas: list, inputs, eye, scores):
    """One row per lambda of the sweep (its end-to-end view scored, beside the trainer's held-out PSNR),
    the renders by lambda, and the GLSL-vs-torch parity of the trainer's best lambda (max scaled error,
    display-domain PSNR; None when it is not in the sweep)."""
    from inshade.techniques.di_shading.train import lambda_folder

    rows, renders = [], {}
    parity = parity_db = None
    for lam in lambdas:
        name = lambda_folder(lam)
        img, ins, _, pos = _render(ctx, folder, name, "end_to_end", camera, w, h)
        if not np.array_equal(ins, inputs):
            raise BenchError("the views disagree on the G-buffer (same camera and plane expected)")
        renders[lam] = img
        row = {"lambda": lam, "sampler": name, "role": "independent (baseline)" if lam == 0.0 else "end-to-end",
               **scores(img)}
        torch_row = next(s for s in trained["sweep"] if float(s["lambda"]) == lam)
        row["torch_heldout_psnr"] = torch_row["psnr_shaded_vs_reference"]
        rows.append(row)
        if lam == trained["lambda_best"]:
            hit = ins[..., 3] > 0.5
            twin = torch_twin(folder, name, ins, pos, eye)
            parity = float(np.max(np.abs(img[..., :3][hit] - twin[hit]) / np.maximum(1.0, np.abs(twin[hit]))))
            parity_db = psnr(display(img)[hit], display(twin)[hit], peak=1.0)
    return rows, renders, parity, parity_db


def _context_views(ctx, folder: Path, camera, w: int, h: int, scores, gl_ref, one_di, one_analytic) -> list[dict]:
    """The context rows (not part of the sweep): the GLSL reference view, the emulated 1-sample views
    and the GLSL 1-sample views of the uncompressed set, each scored."""
    from inshade.techniques.di_shading.train import lambda_folder

    context = [{"view": "gl_reference", "label": "the reference view in GLSL (16 samples, GL-built mips)",
                **scores(gl_ref), "psnr_vs_gl_reference": None},
               {"view": "trilinear_emulated", "label": "1 trilinear sample (box mips), DI Disney decoder (torch)",
                **scores(one_di)},
               {"view": "analytic_emulated", "label": "1 trilinear sample (box mips), analytic Disney (torch)",
                **scores(one_analytic)}]
    labels = {"trilinear": "1 trilinear sample (GL-built mips), DI Disney decoder (GLSL)",
              "analytic": "1 trilinear sample (GL-built mips), analytic Disney (GLSL)"}
    for view, label in labels.items():
        img = _render(ctx, folder, lambda_folder(0.0), view, camera, w, h)[0]
        context.append({"view": view, "label": label, **scores(img)})
    return context


def _psnr_gains(rows: list[dict]) -> dict:
    """Adds each row's PSNR gain over lambda 0 (dB, %); returns the best row with lambda > 0 (else lambda 0's)."""
    base = next(x for x in rows if x["lambda"] == 0.0)
    for x in rows:
        x["psnr_gain_db"] = round(x["psnr"] - base["psnr"], 4)
        x["psnr_gain_percent"] = round(100.0 * (x["psnr"] / base["psnr"] - 1.0), 3)
    return max((x for x in rows if x["lambda"] > 0), key=lambda x: x["psnr"], default=base)


def _result(folder: Path, gl: dict, clock, view: dict, trained: dict, best: dict, flip_why, parity, parity_db,
            rows: list, context: list, timings: dict, ts: int) -> dict:
    """The report dict (di_shading.json)."""
    px = ts * ts
    return {
        "benchmark": "di_shading", "asset": portable_path(folder),
        "machine": machine(gl), "clock": clock_record(clock),
        "view": view,
        "reference": "torch: train.py reference() on the pass's own G-buffer (uv, duv/dx, duv/dy, hit point): "
                     "16 samples over the pixel footprint, emulated trilinear (box mips rounded to 8 bits), "
                     "analytic Disney, averaged; psnr_vs_gl_reference: against the GLSL reference view, whose "
                     "mips are the driver's glGenerateMipmap (llvmpipe: biased up to 3-4 8-bit steps at the "
                     "coarse levels, enough to tip grazing normals below the horizon)",
        "settings": trained.get("settings"), "lambda_best_torch": trained["lambda_best"],
        "lambda_best_glsl": best["lambda"],
        "psnr_gain_best_glsl_db": best["psnr_gain_db"], "psnr_gain_best_glsl_percent": best["psnr_gain_percent"],
        "flip_unavailable": flip_why,
        "parity_end_to_end_scaled_max_err": parity,
        "parity_end_to_end_psnr_db": None if parity_db is None else round(min(float(parity_db), 999.0), 2),
        "rows": rows,
        "context": context,
        "timing_size": [ts, ts],
        "timing": {k: {**t.to_dict(), "ms_per_frame": round(1e3 * t.median, 3),
                       "ns_per_pixel": round(1e9 * t.median / px, 2)} for k, t in timings.items()},
        "paper": PAPER,
        "bytes": {"sampler": trained.get("bytes"), "ratio_vs_base": trained.get("ratio_vs_base")},
    }


def markdown(res: dict) -> str:
    v = res["view"]
    lines = ["# DI end-to-end shading pipeline (lambda sweep)", "",
             machine_markdown(res["machine"]),
             f"- asset `{res['asset']}`; view {v['width']}x{v['height']}, {v['rows_scored']} plane rows scored "
             f"({v['pixels_scored']} px); settings `{json.dumps(res['settings'])}`",
             "- reference: 16 samples over each pixel's footprint of the uncompressed set, each the proxy "
             "trilinear sampler (box mips rounded to 8 bits, as in training), shaded with the analytic Disney BRDF "
             "and averaged (torch, on the pass's own G-buffer); each lambda: that DI sampler + the frozen DI Disney "
             "decoder, rendered in GLSL. Last column: against the GLSL reference view instead (the driver's "
             "glGenerateMipmap; llvmpipe's is biased by up to 3-4 8-bit steps at coarse levels)",
             f"- parity, end-to-end view GLSL vs torch twin: max |d| / max(1, |torch|) = "
             f"{res['parity_end_to_end_scaled_max_err']:.3g}, display-domain PSNR "
             f"{res['parity_end_to_end_psnr_db']:.1f} dB (images are held to >= 50 dB)", ""]
    lines += markdown_table(
        ["lambda", "role", "PSNR (dB)", "gain vs lambda 0", "FLIP", "torch held-out PSNR (dB)",
         "PSNR vs GLSL reference (dB)"],
        [[f"{x['lambda']:g}", x["role"], f"{x['psnr']:.2f}",
          f"{x['psnr_gain_db']:+.2f} dB ({x['psnr_gain_percent']:+.1f}%)",
          "n/a" if x["flip"] is None else f"{x['flip']:.4f}", f"{x['torch_heldout_psnr']:.2f}",
          f"{x['psnr_vs_gl_reference']:.2f}"] for x in res["rows"]])
    lines += ["", "For context, against the same reference: the GLSL reference view, and the uncompressed set "
                  "with its mip chain (what the samplers replace), one sample per pixel:", ""]
    lines += markdown_table(["pass", "PSNR (dB)", "FLIP", "PSNR vs GLSL reference (dB)"],
                            [[x["label"], f"{x['psnr']:.2f}", "n/a" if x["flip"] is None else f"{x['flip']:.4f}",
                              "-" if x["psnr_vs_gl_reference"] is None else f"{x['psnr_vs_gl_reference']:.2f}"]
                             for x in res["context"]])
    lines += ["", f"Best lambda on this view (GLSL): {res['lambda_best_glsl']:g} "
                  f"({res['psnr_gain_best_glsl_db']:+.2f} dB, {res['psnr_gain_best_glsl_percent']:+.1f}%); the trainer "
                  f"picked {res['lambda_best_torch']:g} for the asset (torch held-out pixels).", ""]
    lines += [f"Frame time of the pass at {res['timing_size'][0]}x{res['timing_size'][1]} (the whole fullscreen pass, "
              "sky pixels included; median of interleaved rounds; end_to_end and independent are one program with "
              "different weights):", ""]
    lines += markdown_table(["pass", "ms / frame", "ns / pixel"],
                            [[k, f"{t['ms_per_frame']:.2f}", f"{t['ns_per_pixel']:.1f}"]
                             for k, t in res["timing"].items()])
    lines += ["", f"Timing clock: {res['clock']['clock_note'] or res['clock']['clock']}. "
                  f"Paper: {res['paper']['claim']} ({res['paper']['source']}); "
                  "not comparable to a software rasteriser."]
    if res["flip_unavailable"]:
        lines += ["", f"FLIP: {res['flip_unavailable']}"]
    return "\n".join(lines) + "\n"


def plot(res: dict, path: Path):
    plt = matplotlib_pyplot()
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.4))
    lam = [x["lambda"] for x in res["rows"]]
    ax[0].plot(lam, [x["psnr"] for x in res["rows"]], "o-", label="GLSL view")
    ax[0].plot(lam, [x["torch_heldout_psnr"] for x in res["rows"]], "s--", label="torch held-out pixels")
    ax[0].set_xlabel("lambda")
    ax[0].set_ylabel("PSNR vs 16-sample reference (dB)")
    ax[0].legend(fontsize=8)
    if all(x["flip"] is not None for x in res["rows"]):
        ax[1].plot(lam, [x["flip"] for x in res["rows"]], "o-", color="C3")
    ax[1].set_xlabel("lambda")
    ax[1].set_ylabel("mean FLIP (lower is better)")
    fig.suptitle(f"DI end-to-end shading, {res['machine']['gl_renderer']}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=110)
    plt.close(fig)


def _views(renders: dict, ref: np.ndarray, rows_ok: np.ndarray, path: Path):
    """Reference | lambda 0 | best lambda, stacked (sRGB), with |difference| x 4 rows."""
    from inshade.files import atomic_files
    from PIL import Image

    lams = sorted(k for k in renders if not isinstance(k, str))
    tiles = [display(ref)] + [display(renders[k]) for k in lams]
    diffs = [np.zeros_like(tiles[0])] + [np.clip(4 * np.abs(display(renders[k]) - display(ref)), 0, 1) for k in lams]
    img = np.concatenate([np.concatenate(tiles, 1), np.concatenate(diffs, 1)], 0)
    with atomic_files(path) as tmp:
        Image.fromarray(np.rint(img * 255).astype(np.uint8), "RGB").save(tmp, format="PNG")


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper

CLAIMS = {"gain": Claim("Differentiable Indirection (Datta et al. 2023), Fig. 1 / 13",
                        "end-to-end (best lambda) PSNR gain over independent training vs the 16-sample reference (%)",
                        "+5% (Fig. 13) to +8% (Fig. 1)", 8.0)}


def headlines(r: dict) -> list[dict]:
    base = next(x for x in r["rows"] if x["lambda"] == 0.0)
    best = max((x for x in r["rows"] if x["lambda"] > 0), key=lambda x: x["psnr"])
    return [claim_row(CLAIMS, "di_shading", "gain", f"{best['psnr_gain_percent']:+.1f}%: lambda {best['lambda']:g} "
                      f"{best['psnr']:.2f} dB vs independent {base['psnr']:.2f} dB", best["psnr_gain_percent"])]


BENCH = Bench("di_shading", __doc__, Settings, run, errors=_errors, claims=CLAIMS, headlines=headlines,
              quick={"width": 96, "height": 48, "repeats": 2, "time_size": 64},
              sizes={"cpu": sized(30, time_size=256, repeats=3), "device": sized(15, time_size=2048, repeats=10)})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite
