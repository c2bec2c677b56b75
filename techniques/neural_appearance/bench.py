"""`inshade bench neural_appearance`: the neural materials against their layered reference.

For each asset (``--assets``, default both shipped materials), in one run:

- **quality**: the teapot views of the asset's scene (default camera and close-up), lit by the
  scene's lights, neural (each decoder: 2x16, 2x32, 3x64) against the reference shader, same
  lights, view and pixels; ``--quality-spp`` samples each (the stochastic level choice
  accumulates). PSNR (linear RGB, peak 1, covered pixels) and mean FLIP (LDR, after the same
  exposure and sRGB encoding).
- **filtering**: the ``far`` view: the 1-sample neural render and the reference sampled at 1 spp
  through its own mips, each against a 64-sample supersampled reference (8x8 pixels per pixel,
  box-filtered), PSNR.
- **speed**: the material pass full screen at ``--size`` (a plane filling the view, one light):
  reference layered shader against each decoder size, interleaved rounds (ABBA) of
  ``render_network`` with the renderer's clock; ratios per round, median and min..max.
- **sampler**: environment lighting, BRDF sampling alone (no MIS), the mean over covered pixels
  of the per-pixel standard deviation of the 4-spp estimate (from ``--sampler-frames`` independent
  1-spp frames), learned proxy vs isotropic proxy vs cosine sampling, at the close-up (fine
  levels) and with the level biased coarse (``+3``).
- **memory**: bytes of each decoder and sampler (fp32 as stored, fp16 as the paper counts),
  latents (fp16, all levels) and the reference textures (RGBA8, with mips).

Writes ``neural_appearance.json``, ``.md`` and ``.png`` into ``--out``; logs GL_RENDERER.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bench.contract import Bench, clock_option, option, rounds_option, sized, warmup_option
from inshade.files import atomic_write
from inshade.bench.entry import Claim, claim_row, ratio_verdict
from inshade.bench.harness import (BenchError, clock_for, clock_record, interleave, machine,
                                   machine_markdown, markdown_table, matplotlib_pyplot, paired_ratio, write_report)

DEFAULT_OUT = "bench-out/neural_appearance"
DECODERS = (16, 32, 64)
DECODER_NAMES = {16: "2x16", 32: "2x32", 64: "3x64"}
SAMPLERS = ("learned", "isotropic", "cosine")


@dataclass
class Settings:
    out: str = option(DEFAULT_OUT, f"output folder (default {DEFAULT_OUT})")
    assets: str = option("trained/neural_appearance_ceramic,trained/neural_appearance_brushed_metal",
                         "comma-separated asset folders (default %(default)s)")
    size: int = option(1024, "speed: full-screen pass side in pixels (default %(default)s)")
    quality_size: int = option(256, "quality/sampler renders' height (default %(default)s)")
    quality_spp: int = option(8, "samples per quality render (default %(default)s)")
    sampler_frames: int = option(32, "1-spp frames per sampler estimate (default %(default)s)")
    rounds: int = rounds_option()
    warmup: int = warmup_option()
    clock: str = clock_option()


# ---------------------------------------------------------------------------------------------

def _renderer(scene, **settings):
    from inshade.runtime.renderer import SceneRenderer

    return SceneRenderer(scene, settings=settings)


def _image(r, camera, w, h, spp: int) -> tuple[np.ndarray, np.ndarray]:
    """(linear RGB [H, W, 3], covered mask) of the scene pass after ``spp`` samples."""
    r.accumulate(camera, w, h, spp)
    data = r.read("network")
    return data[..., :3].astype(np.float64), data[..., 3] > 0


def _psnr(a, b, mask) -> float:
    from inshade.metrics import psnr

    return round(float(psnr(np.clip(a, 0, 1), np.clip(b, 0, 1), mask=mask)), 3)


def _flip(a, b) -> float | None:
    from inshade.metrics import flip, flip_unavailable, srgb_oetf

    if flip_unavailable():
        return None
    return round(flip(srgb_oetf(np.clip(b, 0, 1)), srgb_oetf(np.clip(a, 0, 1))), 5)


def _supersampled(scene, camera, w, h, factor: int):
    """The reference at ``factor``² samples per pixel (rendered large, box-filtered) and its coverage."""
    ref = _renderer(scene, view="reference", lighting="lights")
    try:
        big, big_mask = _image(ref, camera, w * factor, h * factor, 1)
    finally:
        ref.release()
    truth = (big * big_mask[..., None]).reshape(h, factor, w, factor, 3).mean((1, 3))
    return truth, big_mask.reshape(h, factor, w, factor).mean((1, 3)) > 0.99


def quality(scene, height: int, spp: int, log) -> list[dict]:
    """Per view: each decoder (``spp`` samples: the level choice accumulates) against the reference
    shader at the same pixels (its parameters through their mips) and against the reference
    supersampled 4x4 (the filtered appearance the decoders are trained to); the reference through its
    mips against the supersampled one is the baseline row."""
    w = int(round(height * scene.size[0] / scene.size[1]))
    rows = []
    for view in (None, "close-up"):
        camera = scene.make_camera(view)
        ref = _renderer(scene, view="reference", lighting="lights")
        try:
            reference, mask = _image(ref, camera, w, height, spp)
        finally:
            ref.release()
        truth, truth_mask = _supersampled(scene, camera, w, height, 4)
        both = mask & truth_mask
        rows.append({"view": view or "default", "decoder": "reference (mips)", "psnr": None, "flip": None,
                     "psnr_supersampled": _psnr(reference, truth, both)})
        for d in DECODERS:
            r = _renderer(scene, view="neural", lighting="lights", decoder=d)
            try:
                neural, _ = _image(r, camera, w, height, spp)
            finally:
                r.release()
            rows.append({"view": view or "default", "decoder": DECODER_NAMES[d], "psnr": _psnr(neural, reference, mask),
                         "flip": _flip(neural * mask[..., None], reference * mask[..., None]),
                         "psnr_supersampled": _psnr(neural, truth, both)})
            log(f"  quality {rows[-1]}")
    return rows


def filtering(scene, height: int, log) -> dict:
    """Far view: neural 1 spp and reference-through-its-mips 1 spp vs a 64-sample supersampled reference."""
    w = int(round(height * scene.size[0] / scene.size[1]))
    camera = scene.make_camera("far") if "far" in scene.bookmarks else scene.make_camera()
    truth, truth_mask = _supersampled(scene, camera, w, height, 8)
    ref = _renderer(scene, view="reference", lighting="lights")
    try:
        mips, mask = _image(ref, camera, w, height, 1)
    finally:
        ref.release()
    r = _renderer(scene, view="neural", lighting="lights", decoder=64)
    try:
        neural, _ = _image(r, camera, w, height, 1)
    finally:
        r.release()
    cover = mask & truth_mask
    out = {"neural_1spp_psnr": _psnr(neural, truth, cover), "reference_mips_1spp_psnr": _psnr(mips, truth, cover),
           "pixels": int(cover.sum())}
    log(f"  filtering {out}")
    return out


def speed(scene, size: int, rounds: int, warmup: int, clock_name: str, log) -> dict:
    """The material pass full screen: a plane filling the view, one light."""
    from inshade.scene.description import parse_scene

    data = {**json.loads(Path(scene.path).read_text()), "mesh": {"shape": "plane", "size": 2.0},
            "camera": {"type": "orbit", "fov_y": 30.0, "target": [0.0, 0.0, 0.0], "distance": 3.0, "yaw": 0.0,
                       "pitch": -89.0}, "bookmarks": {}}
    plane = parse_scene(data, root=Path(scene.root), path=None)
    camera = plane.make_camera()
    variants, renderers = {}, []
    try:
        for name, settings in [("reference", {"view": "reference"})] + [
                (DECODER_NAMES[d], {"view": "neural", "decoder": d}) for d in DECODERS] + [
                (f"{DECODER_NAMES[d]} fast", {"view": "neural", "decoder": d, "latent_filter": "fast"}) for d in (16, 32)]:
            r = _renderer(plane, lighting="lights", lights=1, **settings)
            renderers.append(r)
            r.render_network(camera, size, size, force=True)
            r.ctx.finish()
            variants[name] = (lambda rr: lambda: rr.render_network(camera, size, size, force=True))(r)
        clock = clock_for(renderers[0].ctx, clock_name, software=renderers[0].gl["software"])
        timings = interleave(variants, rounds=rounds, warmup=warmup, clock=clock)
        coverage = float((renderers[0].read("network")[..., 3] > 0).mean())
    finally:
        for r in renderers:
            r.release()
    ref = timings["reference"].samples
    out = {"size": size, "coverage": round(coverage, 4), "clock": clock_record(clock),
           "ms": {k: t.to_dict() for k, t in timings.items()},
           "speedup_vs_reference": {k: paired_ratio(ref, timings[k].samples).to_dict()
                                    for k in timings if k != "reference"}}
    log(f"  speed {out['speedup_vs_reference']}")
    return out


def sampler_variance(scene, height: int, frames: int, log) -> list[dict]:
    w = int(round(height * scene.size[0] / scene.size[1]))
    rows = []
    for label, bias in (("fine (close-up)", 0.0), ("coarse (level +3)", 3.0)):
        camera = scene.make_camera("close-up")
        for sampling in SAMPLERS:
            r = _renderer(scene, view="neural", lighting="environment", sampling=sampling, mis=False,
                          level_bias=bias)
            try:
                means, mask = [], None
                for n in range(1, frames + 1):
                    m, mask = _image(r, camera, w, height, n)
                    means.append(m)
            finally:
                r.release()
            samples = [means[0]] + [n * means[n - 1] - (n - 1) * means[n - 2] for n in range(2, frames + 1)]
            x = np.stack(samples).mean(-1)                      # luminance-free mean of RGB per sample
            std4 = np.sqrt(x.var(0, ddof=1) / 4.0)
            rows.append({"level": label, "sampling": sampling, "mean_std_4spp": round(float(std4[mask].mean()), 5)})
            log(f"  sampler {rows[-1]}")
    return rows


def memory(folder: Path) -> dict:
    from inshade.bundle import load

    from . import NETWORKS

    out = {}
    for name, _prefix in NETWORKS:
        b = load(folder / name)
        fp32 = int(sum(np.asarray(t).size * 4 for t in b.tensors.values()))
        out[name] = {"fp32_bytes": fp32, "fp16_bytes": fp32 // 2}
    out["reference_textures"] = {"rgba8_bytes_with_mips": int(sum(
        _png_bytes(folder / f"param{k}.png") for k in range(3)))}
    return out


def _png_bytes(path: Path) -> int:
    from PIL import Image

    w, h = Image.open(path).size
    total, lw, lh = 0, w, h
    while True:
        total += lw * lh * 4
        if lw == 1 and lh == 1:
            return total
        lw, lh = max(1, lw // 2), max(1, lh // 2)


# ---------------------------------------------------------------------------------------------

def run(args: Settings) -> int:
    import sys

    from inshade.scene.description import load_scene

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    results = {"assets": {}}
    gl = None
    for folder in [Path(a) for a in args.assets.split(",") if a]:
        if not (folder / "scene.json").is_file():
            raise BenchError(f"{folder}: not a neural appearance asset (no scene.json)")
        scene = load_scene(folder)
        log(f"{folder.name}:")
        entry = {"quality": quality(scene, args.quality_size, args.quality_spp, log),
                 "filtering": filtering(scene, args.quality_size, log),
                 "speed": speed(scene, args.size, args.rounds, args.warmup, args.clock, log),
                 "sampler": sampler_variance(scene, args.quality_size, args.sampler_frames, log),
                 "memory": memory(folder)}
        results["assets"][folder.name] = entry
        Path(args.out).mkdir(parents=True, exist_ok=True)
        atomic_write(Path(args.out) / "neural_appearance.partial.json", json.dumps(results, indent=2))
        if gl is None:
            from inshade.runtime.context import gl_info, shared_context

            gl = gl_info(shared_context())
    results["machine"] = machine(gl)
    results["settings"] = {k: getattr(args, k) for k in ("size", "quality_size", "quality_spp", "sampler_frames",
                                                         "rounds", "warmup")}
    write_report(args.out, "neural_appearance", results, markdown, plot)
    (Path(args.out) / "neural_appearance.partial.json").unlink(missing_ok=True)
    return 0


def markdown(r: dict) -> str:
    lines = ["# neural_appearance: neural materials vs the layered reference", "", machine_markdown(r["machine"]), ""]
    for name, a in r["assets"].items():
        lines += [f"## {name}", "", "### Quality (scene lights; vs the reference shader at the same pixels, "
                  "and vs the reference supersampled 4x4)", ""]
        lines += markdown_table(["view", "decoder", "PSNR vs reference (dB)", "FLIP vs reference",
                                 "PSNR vs supersampled (dB)"],
                                [[q["view"], q["decoder"], _cell(q["psnr"]), _cell(q["flip"]),
                                  _cell(q.get("psnr_supersampled"))] for q in a["quality"]])
        f = a["filtering"]
        lines += ["", "### Filtering (far view, vs a 64-sample supersampled reference)", ""]
        lines += markdown_table(["render", "PSNR"], [["neural 3x64, 1 spp", f["neural_1spp_psnr"]],
                                                    ["reference through its mips, 1 spp",
                                                     f["reference_mips_1spp_psnr"]]])
        s = a["speed"]
        lines += ["", f"### Speed (full-screen material pass, {s['size']}², one light; clock: {s['clock']['clock']})",
                  "", "`fast`: latents fetched with hardware bilinear filtering (textureLod) instead of 4 texelFetch + fp32 mix.", ""]
        rows = [["reference", f"{1e3 * s['ms']['reference']['median_s']:.3f}", "1"]]
        for k, ratio in s["speedup_vs_reference"].items():
            rows.append([k, f"{1e3 * s['ms'][k]['median_s']:.3f}",
                         f"{ratio['median']:.2f} ({ratio['low']:.2f}..{ratio['high']:.2f}): {ratio['verdict']}"])
        lines += markdown_table(["shader", "median ms", "speed-up vs reference (min..max)"], rows)
        lines += ["", "### Sampler (environment light, BRDF sampling only, mean per-pixel std at 4 spp)", ""]
        lines += markdown_table(["level", "sampling", "mean std"],
                                [[x["level"], x["sampling"], x["mean_std_4spp"]] for x in a["sampler"]])
        lines += ["", "### Memory", ""]
        mem = a["memory"]
        lines += markdown_table(["part", "bytes as stored", "bytes at fp16 (the paper's count)"],
                                [[k, mem[k]["fp32_bytes"] if k != "latents" else mem[k]["fp16_bytes"],
                                  mem[k]["fp16_bytes"]] for k in mem if k != "reference_textures"]
                                + [["reference textures (3 RGBA8 + mips)",
                                    mem["reference_textures"]["rgba8_bytes_with_mips"], "—"]])
        lines.append("")
    return "\n".join(lines)


def _cell(v):
    return "—" if v is None else v


def plot(r: dict, path: Path) -> None:
    plt = matplotlib_pyplot()
    names = list(r["assets"])
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for name in names:
        q = [x for x in r["assets"][name]["quality"] if x["view"] == "default" and x["psnr"] is not None]
        axes[0].plot([x["decoder"] for x in q], [x["psnr"] for x in q], "o-", label=name)
        s = r["assets"][name]["speed"]
        keys = list(s["ms"])
        axes[1].bar([f"{name[-8:]}\n{k}" for k in keys], [1e3 * s["ms"][k]["median_s"] for k in keys])
    axes[0].set_title("PSNR vs reference (dB)")
    axes[0].legend()
    axes[1].set_title("material pass (ms)")
    axes[1].tick_params(axis="x", labelsize=6)
    fig.tight_layout()
    fig.savefig(path, format="png")
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper

CLAIMS = {
    "2x16": Claim("Real-Time Neural Appearance Models (2024), Figs. 15-16", "2x16 decoder vs the reference "
                  "material (speed-up)", "4.14x, full frame, RTX 4090", 4.14),
    "2x32": Claim("Real-Time Neural Appearance Models, Table 5", "2x32 decoder vs the reference material "
                  "shading (speed-up)", "9.06x, material shading, RTX 4090", 9.06),
    "3x64": Claim("Real-Time Neural Appearance Models, Table 5", "3x64 decoder vs the reference material "
                  "shading (speed-up)", "2.30x, material shading, RTX 4090", 2.30),
}


def headlines(r: dict) -> list[dict]:
    rows = []
    for asset, a in r["assets"].items():
        speed = a["speed"]["speedup_vs_reference"]
        for decoder in ("2x16", "2x32", "3x64"):
            if decoder in speed:
                rows.append(claim_row(CLAIMS, "neural_appearance", decoder, f"{ratio_verdict(speed[decoder])} at "
                                      f"{a['speed']['size']}²", speed[decoder]["median"],
                                      asset.removeprefix("neural_appearance_")))
    return rows


BENCH = Bench("neural_appearance", __doc__, Settings, run, claims=CLAIMS, headlines=headlines, sizes={
    # ~35 s with Mesa's shader cache warm; a cold cache adds minutes of llvmpipe JIT
    "cpu": sized(90, assets="trained/neural_appearance_ceramic", size=256, quality_size=64, quality_spp=2,
                 sampler_frames=4, rounds=3, warmup=1),
    "device": sized(50, size=2048, rounds=15)})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite
