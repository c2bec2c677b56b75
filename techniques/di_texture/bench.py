"""`inshade bench di_texture`: Differentiable Indirection texture compression vs ASTC and BC, same images.

For each image (a ``skimage.data`` photograph, centre-cropped and resized to ``--size``):

- DI: the compressed textures (the shipped ``trained/di_<image>`` and ``trained/di_<image>_*``
  assets that match the size, and one trained here at each ``--ratios`` value), decoded by its generated GLSL through the GL driver
  on both LUT paths (``exact``: texelFetch + fp32 mix; ``fast``: hardware filtering), plus the
  torch decode of the same quantised bundle; training seconds from the bundle.
- ASTC (``inshade.bench.codecs``: ``astc-encoder-py``, ARM astcenc, LDR profile on the sRGB bytes,
  quality 60): every square block from 4x4 to 12x12 (``--astc``; 128 bits a block).
- BC1 and BC7 (``inshade.bench.codecs``: ``etcpak`` to encode; Pillow's ``bcn`` decoder to decode,
  because etcpak 0.9.15's ``decompress_bc*`` crash here).

Quality: PSNR in sRGB 8-bit space against the 8-bit original, and mean FLIP (LDR, default 67
PPD) with ``flip-evaluator``, at the texel centres; and PSNR *between texels*, where a renderer's
filtering reads: at the pixel centres of a grid twice as fine (a quarter texel from the centres),
against the bilinear filtering of the original -- the block codecs' decoded texels filtered the
same way, DI decoded there by its GLSL (exact path). A decoder fitted to the texel centres alone
scores well on the first and poorly on the second. Size: bits per pixel and the ratio to RGB8 (24 bpp). A baseline
whose package is missing or fails is listed as unavailable with the reason, never estimated.

Writes ``di_texture.json``, ``di_texture.md`` and ``di_texture.png`` (the rate-distortion curves: PSNR and FLIP
against bits per pixel, one line per codec and image) into ``--out``.
``--quick``: one 32x32 image, DI trained 60 steps at 3x (for tests / smoke runs).
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bench.contract import Bench, option, sized
from inshade.bench import codecs
from inshade.bench.entry import Claim, claim_row
from inshade.bench.harness import (BenchError, label_axes, machine, machine_markdown, matplotlib_pyplot,
                                   portable_command, portable_path, save_figure, write_report)
from inshade.bench.codecs import ASTC_BLOCKS, ASTC_QUALITY, RGB8_BPP
from inshade.metrics import flip as flip_mean
from inshade.metrics import flip_unavailable, psnr, srgb_oetf
from inshade.models.texture_cascade import DEFAULTS, INITS

DEFAULT_OUT = "bench-out/di"
RD_ASTC_BLOCKS = (4, 5, 6, 8, 10, 12)    # astcenc's square footprints: 8 down to 0.89 bpp


@dataclass
class Settings:
    out: str = option(DEFAULT_OUT, f"output folder (default {DEFAULT_OUT})")
    images: str = option("astronaut,chelsea,coffee", "skimage.data names (default %(default)s)")
    size: int = option(256, "square size the images are cropped/resized to")
    assets: str = option("trained", "folder with di_<image> assets to reuse ('' = none)")
    ratios: str = option("", "extra DI ratios to train here, comma-separated (e.g. 12)")
    steps: int = option(1500, "training steps for DI trained here")
    init: str = option(DEFAULTS["init"], "starting point of DI trained here (default %(default)s)", choices=INITS)
    astc: str = option(",".join(map(str, RD_ASTC_BLOCKS)), "ASTC block sizes, comma-separated (default %(default)s)")
    quick: bool = option(False, "tiny run: 32x32 astronaut, DI 150 steps at 3x")


# ---------------------------------------------------------------------------------------------
# metrics (inshade.metrics)

def psnr8(a8, b8) -> float:
    """PSNR of two 8-bit images (peak 255)."""
    return psnr(a8, b8, peak=255.0)


def upsample2(img: np.ndarray) -> np.ndarray:
    """Bilinear filtering (GL convention, clamp to edge) of [H, W, C] at the pixel centres of a
    2H x 2W grid: each output sits a quarter texel from a texel centre (weights 3/4, 1/4)."""
    x = np.asarray(img, np.float64)
    for axis in (0, 1):
        prev = np.concatenate([x.take([0], axis), x.take(range(x.shape[axis] - 1), axis)], axis)
        nxt = np.concatenate([x.take(range(1, x.shape[axis]), axis), x.take([-1], axis)], axis)
        both = np.stack([0.75 * x + 0.25 * prev, 0.75 * x + 0.25 * nxt], axis + 1)
        x = both.reshape(x.shape[:axis] + (2 * x.shape[axis],) + x.shape[axis + 1:])
    return x


def psnr_between(ref8: np.ndarray, filtered: np.ndarray) -> float:
    """PSNR (sRGB-encoded values in [0, 1], peak 1) of values on the 2x grid against the
    original's bilinear filtering there."""
    return round(psnr(np.asarray(filtered, np.float64), upsample2(ref8) / 255.0, peak=1.0), 4)


def quality(ref8: np.ndarray, test8: np.ndarray, flip: bool) -> dict:
    out = {"psnr": round(psnr8(test8, ref8), 4), "psnr_between": psnr_between(ref8, upsample2(test8) / 255.0)}
    if flip:
        out["flip"] = round(flip_mean(np.asarray(ref8, np.uint8), np.asarray(test8, np.uint8)), 5)
    return out


# ---------------------------------------------------------------------------------------------
# baselines (inshade.bench.codecs)

def astc_entries(img8: np.ndarray, flip: bool, blocks=ASTC_BLOCKS) -> list[dict]:
    out = []
    for b in blocks:
        name = f"ASTC {b}x{b}"
        t = time.perf_counter()
        try:
            decoded, nbytes = codecs.astc_roundtrip(img8, b)
        except codecs.CodecError as e:
            out.append({"codec": name, "available": False, "reason": str(e)})
            continue
        secs = time.perf_counter() - t
        out.append(_baseline_entry(name, "ASTC", nbytes, secs, f"astcenc LDR profile, quality {ASTC_QUALITY:g}",
                                   img8, decoded[..., :3], flip))
    return out


def _baseline_entry(codec, family, nbytes, secs, settings, img8, test, flip) -> dict:
    """One table row for a fixed-rate codec: size, rate and quality of its decoded image
    (``secs``: encode + decode time)."""
    h, w = img8.shape[:2]
    bpp = 8.0 * nbytes / (h * w)
    return {"codec": codec, "family": family, "available": True, "bytes": nbytes, "bpp": round(bpp, 4),
            "ratio": round(RGB8_BPP / bpp, 4), "codec_seconds": round(secs, 3), "settings": settings,
            **quality(img8, test, flip)}


def bc_entries(img8: np.ndarray, flip: bool) -> list[dict]:
    out = []
    for name in codecs.BC_CODECS:
        try:
            t = time.perf_counter()
            test, nbytes = codecs.bc_roundtrip(img8, name)
            secs = time.perf_counter() - t
        except codecs.CodecError as e:
            out.append({"codec": name, "available": False, "reason": str(e)})
            continue
        out.append(_baseline_entry(name, "BC", nbytes, secs, "etcpak encoder, Pillow bcn decoder",
                                   img8, test[..., :3], flip))
    return out


# ---------------------------------------------------------------------------------------------
# DI

def di_bundles(name: str, image: np.ndarray, args) -> list[tuple[object, str]]:
    """(bundle, origin) for each DI texture of this image: the shipped assets (``di_texture_<image>`` and
    ``di_texture_<image>_*``, e.g. ``di_texture_astronaut_12x``) that match the size, and one trained here for
    each extra ratio."""
    from inshade import bundle as bundle_mod
    from inshade.models import texture_cascade as tc

    found = []
    root = Path(args.assets) if args.assets else None
    folders = sorted([root / f"di_texture_{name}", *root.glob(f"di_texture_{name}_*")]) if root is not None else []
    for folder in folders:
        if not (folder / "bundle.json").is_file():
            continue
        b = bundle_mod.load(folder)
        m = b.meta.get("metrics", {})
        if b.kind == tc.KIND and (m.get("width"), m.get("height")) == image.shape[1::-1]:
            command = b.meta.get("provenance", {}).get("command")
            found.append((b, f"`{portable_command(command) if command else portable_path(folder)}`"))
    for r in args.ratio_list:
        res = tc.compress(image, r, steps=args.steps, init=args.init, name=f"di_{name}_{r:g}x",
                          provenance={"command": f"inshade bench di_texture (ratio {r:g}, {args.steps} steps, "
                                                 f"init {args.init})"})
        found.append((res.bundle, f"trained in this run ({args.steps} steps)"))
    return found


def di_entries(name, image, img8, flip, args) -> list[dict]:
    from inshade.models import texture_cascade as tc
    from inshade.runtime.network import evaluate_on_pixels

    out = []
    for b, origin in di_bundles(name, image, args):
        m = b.meta["metrics"]
        linear = bool(b.meta.get("render"))
        torch_out = tc.torch_decode(b, image.shape[0])
        for f in ("exact", "fast"):
            dec = evaluate_on_pixels(b, image.shape[0], f)
            test = tc.to_srgb8(dec, linear)
            if test.shape[-1] == 1:
                test = np.repeat(test, 3, -1)
            between = evaluate_on_pixels(b, 2 * image.shape[0], f)
            between = (srgb_oetf(between) if linear else between)[..., :3]
            if between.shape[-1] == 1:
                between = np.repeat(between, 3, -1)
            entry = {"codec": f"DI ({f})", "family": f"DI {f}", "available": True, "bytes": m["bytes"],
                     "bpp": round(8.0 * m["bytes"] / (image.shape[0] * image.shape[1]), 4),
                     "ratio": round(RGB8_BPP / (8.0 * m["bytes"] / (image.shape[0] * image.shape[1])), 4),
                     "train_seconds": m.get("train_seconds"), "steps": m.get("steps"), "origin": origin,
                     "n_primary": m.get("n_primary"), "n_cascaded": m.get("n_cascaded"),
                     "max_abs_diff_vs_torch": float(np.max(np.abs(dec.astype(np.float64) - torch_out))),
                     "psnr_torch": round(psnr8(tc.to_srgb8(torch_out, linear)[..., :3], img8[..., :torch_out.shape[-1]]), 4)
                     if torch_out.shape[-1] == img8.shape[-1] else None,
                     **quality(img8, test, flip), "psnr_between": psnr_between(img8, between)}
            out.append(entry)
    return out


# ---------------------------------------------------------------------------------------------
# run

def run(args) -> int:
    from inshade.models import texture_cascade as tc
    from inshade.runtime.context import gl_info, shared_context

    try:
        args.ratio_list = [float(v) for v in args.ratios.split(",") if v.strip()]
    except ValueError:
        raise BenchError(f"--ratios: expected numbers, got {args.ratios!r}") from None
    try:
        blocks = [int(v) for v in args.astc.split(",") if v.strip()]
    except ValueError:
        raise BenchError(f"--astc: expected block sizes, got {args.astc!r}") from None
    info = gl_info(shared_context())
    flip_reason = flip_unavailable()
    flip = flip_reason is None
    result = {
        "benchmark": "di", "quick": bool(args.quick),
        "machine": machine(info),
        "metric": "PSNR in sRGB 8-bit space vs the 8-bit original; FLIP mean (LDR, 67 PPD); PSNR between texels: "
                  "sRGB-encoded values a quarter texel from the centres (a 2x grid) vs the original's bilinear "
                  "filtering there, block codecs filtered bilinearly from their decoded texels",
        "flip": "available" if flip else f"unavailable: {flip_reason}",
        "images": [],
    }
    for name in [v.strip() for v in args.images.split(",") if v.strip()]:
        image, notes, source = tc.load_image(f"skimage:{name}", args.size)
        img8 = tc.to_srgb8(image, False)
        if img8.shape[-1] == 1:
            img8 = np.repeat(img8, 3, -1)
            image = np.repeat(image, 3, -1)
        entries = di_entries(name, image, img8, flip, args) + astc_entries(img8, flip, blocks) + bc_entries(img8, flip)
        result["images"].append({"image": source, "size": args.size, "notes": notes, "entries": entries})
        print(f"{name}: {len(entries)} entries", file=sys.stderr)
    out = Path(args.out)
    write_report(out, "di_texture", result, markdown, plot)
    print(f"wrote {out / 'di_texture.json'}, {out / 'di_texture.md'}, {out / 'di_texture.png'}", file=sys.stderr)
    return 0


def _fmt(v, spec):
    return "—" if v is None else format(v, spec)


def markdown(result: dict) -> str:
    m = result["machine"]
    lines = ["# DI texture compression vs ASTC / BC", "",
             machine_markdown(m),
             f"- quality: {result['metric']}; FLIP: {result['flip']}",
             "- DI rows: decoded by the generated GLSL through the GL driver (exact = texelFetch + fp32 "
             "mix, fast = hardware filtering); ratio vs RGB8 (24 bpp)", ""]
    for img in result["images"]:
        lines += [f"## {img['image']} ({img['size']}x{img['size']})", ""]
        if img.get("notes"):
            lines += ["Prepared: " + "; ".join(img["notes"]) + ".", ""]
        lines += [
                  "| codec | bpp | ratio | PSNR dB | FLIP | PSNR between texels dB | train s | notes |",
                  "|---|---|---|---|---|---|---|---|"]
        for e in img["entries"]:
            if not e["available"]:
                lines.append(f"| {e['codec']} | — | — | — | — | — | — | unavailable: {e['reason']} |")
                continue
            note = e.get("settings") or (f"N_p {e['n_primary']}, N_c {e['n_cascaded']}, {e['steps']} steps, "
                                         f"max diff vs torch {e['max_abs_diff_vs_torch']:.2g}; {e['origin']}")
            lines.append(f"| {e['codec']} | {e['bpp']:.3f} | {e['ratio']:.2f} | {e['psnr']:.2f} | "
                         f"{_fmt(e.get('flip'), '.4f')} | {_fmt(e.get('psnr_between'), '.2f')} | "
                         f"{_fmt(e.get('train_seconds'), '.1f')} | {note} |")
        lines.append("")
        for e in img["entries"]:
            equal = astc_at(img["entries"], e["bpp"]) if e.get("available") and e["family"].startswith("DI") else None
            if equal is not None:
                lines.append(f"- {e['codec']} at {e['bpp']:.3f} bpp: {e['psnr']:.2f} dB; ASTC at the same bpp "
                             f"(interpolated in log bpp): {equal:.2f} dB ({e['psnr'] - equal:+.2f} dB)")
        lines.append("")
    return "\n".join(lines)


def plot(result: dict, path: Path) -> None:
    """Rate-distortion: PSNR at and between texel centres and FLIP against bits per pixel, a
    line per codec family and image (DI at each trained ratio, ASTC at each block size)."""
    plt = matplotlib_pyplot()
    from matplotlib import ticker

    metrics = [("psnr", "PSNR at texel centres (sRGB 8-bit), dB"), ("psnr_between", "PSNR between texels, dB")]
    if any("flip" in e for img in result["images"] for e in img["entries"]):
        metrics.append(("flip", "FLIP (mean, lower is better)"))
    fig, axes = plt.subplots(1, len(metrics), figsize=(5.5 * len(metrics), 4.5), squeeze=False)
    markers = "osD^v<>"
    styles = {"ASTC": "-", "BC": "none", "DI exact": ":", "DI fast": "-."}   # BC1 / BC7: two codecs, no curve
    for ax, (key, label) in zip(axes[0], metrics):
        for i, img in enumerate(result["images"]):
            fams = {}
            for e in img["entries"]:
                if e["available"] and key in e:
                    fams.setdefault(e["family"], []).append((e["bpp"], e[key]))
            for fam, pts in sorted(fams.items()):
                pts.sort()
                ax.plot([p[0] for p in pts], [p[1] for p in pts], linestyle=styles.get(fam, "-"), marker=markers[i % 7],
                        label=f"{fam} — {img['image'].split('.')[-1]} {img['size']}²")
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(ticker.FormatStrFormatter("%g"))
        ax.xaxis.set_minor_formatter(ticker.NullFormatter())
        ax.set_xticks([1, 2, 4, 8])
        label_axes(ax, "bits per pixel (RGB8 = 24)", label)
    axes[0][0].legend(fontsize=6)
    save_figure(fig, path, "DI vs ASTC/BC", result)


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper

CLAIMS = {"astc": Claim("Differentiable Indirection (Datta et al. 2023), Fig. 14a",
                        "DI (exact) PSNR minus ASTC's at the nearest ratio (dB)",
                        "'comparable in quality with ASTC' at 1K (no number in the text)", 0.0)}


def astc_at(entries: list[dict], bpp: float) -> float | None:
    """ASTC's PSNR at `bpp`, interpolated linearly in log(bpp) between the two block sizes
    around it (None outside the measured range): the comparison at equal bytes."""
    pts = sorted((e["bpp"], e["psnr"]) for e in entries if e.get("available") and e["family"] == "ASTC")
    for (b0, p0), (b1, p1) in zip(pts, pts[1:]):
        if b0 <= bpp <= b1:
            t = math.log(bpp / b0) / math.log(b1 / b0) if b1 > b0 else 0.0
            return p0 + t * (p1 - p0)
    return None


def headlines(r: dict) -> list[dict]:
    rows = []
    for image in r["images"]:
        entries = [e for e in image["entries"] if e.get("available")]
        astc = [e for e in entries if e["family"] == "ASTC"]
        for di in (e for e in entries if e["codec"] == "DI (exact)"):
            near = min(astc, key=lambda e: abs(math.log(e["ratio"] / di["ratio"])))
            gap = di["psnr"] - near["psnr"]
            equal = astc_at(entries, di["bpp"])
            at_equal = "" if equal is None else f"; ASTC at DI's bpp (interpolated) {equal:.2f} dB"
            rows.append(claim_row(CLAIMS, "di_texture", "astc", f"{gap:+.2f} dB: DI {di['psnr']:.2f} dB at "
                                  f"{di['ratio']:.1f}x, {near['codec']} {near['psnr']:.2f} dB at {near['ratio']:.1f}x "
                                  f"({image['size']}²){at_equal}", gap, image["image"].rsplit(".", 1)[-1]))
    return rows


BENCH = Bench("di_texture", __doc__, Settings, run, claims=CLAIMS, headlines=headlines,
              quick={"images": "astronaut", "size": 32, "assets": "", "ratios": "3", "steps": 60, "astc": "4,8"},
              # trains the DI textures here (the shipped ones are found only at their own size)
              sizes={"cpu": sized(60, images="astronaut", ratios="6"),
                     "device": sized(60, images="astronaut,chelsea", size=256, ratios="6", steps=2000)})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite
