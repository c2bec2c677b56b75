"""`inshade bench di_texture`: Differentiable Indirection texture compression vs ASTC and BC, same images.

For each image (a ``skimage.data`` photograph, centre-cropped and resized to ``--size``):

- DI: the compressed textures (the shipped ``trained/di_<image>`` and ``trained/di_<image>_*``
  assets that match the size, and one trained here at each ``--ratios`` value), decoded by its generated GLSL through the GL driver
  on both LUT paths (``exact``: texelFetch + fp32 mix; ``fast``: hardware filtering), plus the
  torch decode of the same quantised bundle; training seconds from the bundle.
- ASTC (``inshade.bench.codecs``: ``astc-encoder-py``, ARM astcenc, LDR profile on the sRGB bytes,
  quality 60): blocks 4x4, 6x6, 8x8, 12x12 (128 bits a block).
- BC1 and BC7 (``inshade.bench.codecs``: ``etcpak`` to encode; Pillow's ``bcn`` decoder to decode,
  because etcpak 0.9.15's ``decompress_bc*`` crash here).

Quality: PSNR in sRGB 8-bit space against the 8-bit original, and mean FLIP (LDR, default 67
PPD) with ``flip-evaluator``. Size: bits per pixel and the ratio to RGB8 (24 bpp). A baseline
whose package is missing or fails is listed as unavailable with the reason, never estimated.

Writes ``di_texture.json``, ``di_texture.md`` and ``di_texture.png`` (PSNR vs compression ratio) into ``--out``.
``--quick``: one 32x32 image, DI trained 60 steps at 3x (for tests / smoke runs).
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from inshade import command

from inshade.bench import codecs
from inshade.bench.entry import Claim, Sizing, SuiteEntry, claim_row
from inshade.bench.harness import BenchError, machine, machine_markdown, matplotlib_pyplot, write_report
from inshade.bench.codecs import ASTC_BLOCKS, ASTC_QUALITY, RGB8_BPP
from inshade.metrics import flip as flip_mean
from inshade.metrics import flip_unavailable, psnr

DEFAULT_OUT = "bench-out/di"


def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    p.add_argument("--out", default=DEFAULT_OUT, help=f"output folder (default {DEFAULT_OUT})")
    p.add_argument("--images", default="astronaut,chelsea,coffee", help="skimage.data names (default %(default)s)")
    p.add_argument("--size", type=int, default=256, help="square size the images are cropped/resized to")
    p.add_argument("--assets", default="trained", help="folder with di_<image> assets to reuse ('' = none)")
    p.add_argument("--ratios", default="", help="extra DI ratios to train here, comma-separated (e.g. 12)")
    p.add_argument("--steps", type=int, default=1500, help="training steps for DI trained here")
    p.add_argument("--quick", action="store_true", help="tiny run: 32x32 astronaut, DI 150 steps at 3x")
    return p


def main(argv=None) -> int:
    return command.main("inshade bench di_texture", __doc__, add_arguments, run, argv, errors=(BenchError,))


# ---------------------------------------------------------------------------------------------
# metrics (inshade.metrics)

def psnr8(a8, b8) -> float:
    """PSNR of two 8-bit images (peak 255)."""
    return psnr(a8, b8, peak=255.0)


def quality(ref8: np.ndarray, test8: np.ndarray, flip: bool) -> dict:
    out = {"psnr": round(psnr8(test8, ref8), 4)}
    if flip:
        out["flip"] = round(flip_mean(np.asarray(ref8, np.uint8), np.asarray(test8, np.uint8)), 5)
    return out


# ---------------------------------------------------------------------------------------------
# baselines (inshade.bench.codecs)

def astc_entries(img8: np.ndarray, flip: bool) -> list[dict]:
    out = []
    for b in ASTC_BLOCKS:
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
            found.append((b, str(folder)))
    for r in args.ratio_list:
        res = tc.compress(image, r, steps=args.steps, name=f"di_{name}_{r:g}x",
                          provenance={"command": f"inshade bench di_texture (ratio {r:g}, {args.steps} steps)"})
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
            entry = {"codec": f"DI ({f})", "family": f"DI {f}", "available": True, "bytes": m["bytes"],
                     "bpp": round(8.0 * m["bytes"] / (image.shape[0] * image.shape[1]), 4),
                     "ratio": round(RGB8_BPP / (8.0 * m["bytes"] / (image.shape[0] * image.shape[1])), 4),
                     "train_seconds": m.get("train_seconds"), "steps": m.get("steps"), "origin": origin,
                     "n_primary": m.get("n_primary"), "n_cascaded": m.get("n_cascaded"),
                     "max_abs_diff_vs_torch": float(np.max(np.abs(dec.astype(np.float64) - torch_out))),
                     "psnr_torch": round(psnr8(tc.to_srgb8(torch_out, linear)[..., :3], img8[..., :torch_out.shape[-1]]), 4)
                     if torch_out.shape[-1] == img8.shape[-1] else None,
                     **quality(img8, test, flip)}
            out.append(entry)
    return out


# ---------------------------------------------------------------------------------------------
# run

def run(args) -> int:
    from inshade.models import texture_cascade as tc
    from inshade.runtime.context import gl_info, shared_context

    if args.quick:
        args.images, args.size, args.assets, args.ratios, args.steps = "astronaut", 32, "", "3", 60
    try:
        args.ratio_list = [float(v) for v in args.ratios.split(",") if v.strip()]
    except ValueError:
        raise BenchError(f"--ratios: expected numbers, got {args.ratios!r}") from None
    info = gl_info(shared_context())
    flip_reason = flip_unavailable()
    flip = flip_reason is None
    result = {
        "benchmark": "di", "quick": bool(args.quick),
        "machine": machine(info),
        "metric": "PSNR in sRGB 8-bit space vs the 8-bit original; FLIP mean (LDR, 67 PPD)",
        "flip": "available" if flip else f"unavailable: {flip_reason}",
        "images": [],
    }
    for name in [v.strip() for v in args.images.split(",") if v.strip()]:
        image, notes, source = tc.load_image(f"skimage:{name}", args.size)
        img8 = tc.to_srgb8(image, False)
        if img8.shape[-1] == 1:
            img8 = np.repeat(img8, 3, -1)
            image = np.repeat(image, 3, -1)
        entries = di_entries(name, image, img8, flip, args) + astc_entries(img8, flip) + bc_entries(img8, flip)
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
        lines += [f"## {img['image']} ({img['size']}x{img['size']})", "",
                  "| codec | bpp | ratio | PSNR dB | FLIP | train s | notes |", "|---|---|---|---|---|---|---|"]
        for e in img["entries"]:
            if not e["available"]:
                lines.append(f"| {e['codec']} | — | — | — | — | — | unavailable: {e['reason']} |")
                continue
            note = e.get("settings") or (f"N_p {e['n_primary']}, N_c {e['n_cascaded']}, {e['steps']} steps, "
                                         f"max diff vs torch {e['max_abs_diff_vs_torch']:.2g}; {e['origin']}")
            lines.append(f"| {e['codec']} | {e['bpp']:.3f} | {e['ratio']:.2f} | {e['psnr']:.2f} | "
                         f"{_fmt(e.get('flip'), '.4f')} | {_fmt(e.get('train_seconds'), '.1f')} | {note} |")
        lines.append("")
    return "\n".join(lines)


def plot(result: dict, path: Path) -> None:
    plt = matplotlib_pyplot()

    fig, ax = plt.subplots(figsize=(7, 4.5))
    markers = "osD^v<>"
    styles = {"ASTC": "-", "BC": "--", "DI exact": ":", "DI fast": ":"}
    for i, img in enumerate(result["images"]):
        fams = {}
        for e in img["entries"]:
            if e["available"]:
                fams.setdefault(e["family"], []).append((e["ratio"], e["psnr"]))
        for fam, pts in sorted(fams.items()):
            pts.sort()
            ax.plot([p[0] for p in pts], [p[1] for p in pts], styles.get(fam, "-"), marker=markers[i % 7],
                    label=f"{fam} — {img['image'].split('.')[-1]}")
    ax.set_xscale("log")
    ax.set_xlabel("compression ratio vs RGB8")
    ax.set_ylabel("PSNR (sRGB 8-bit), dB")
    ax.set_title(f"DI vs ASTC/BC — {result['machine']['gl_renderer']}", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper

CLAIMS = {"astc": Claim("Differentiable Indirection (Datta et al. 2023), Fig. 14a",
                        "DI (exact) PSNR minus ASTC's at the nearest ratio (dB)",
                        "'comparable in quality with ASTC' at 1K (no number in the text)", 0.0)}


def headlines(r: dict) -> list[dict]:
    rows = []
    for image in r["images"]:
        entries = [e for e in image["entries"] if e.get("available")]
        astc = [e for e in entries if e["family"] == "ASTC"]
        for di in (e for e in entries if e["codec"] == "DI (exact)"):
            near = min(astc, key=lambda e: abs(math.log(e["ratio"] / di["ratio"])))
            gap = di["psnr"] - near["psnr"]
            rows.append(claim_row(CLAIMS, "di_texture", "astc", f"{gap:+.2f} dB: DI {di['psnr']:.2f} dB at "
                                  f"{di['ratio']:.1f}x, {near['codec']} {near['psnr']:.2f} dB at {near['ratio']:.1f}x "
                                  f"({image['size']}²)", gap, image["image"].rsplit(".", 1)[-1]))
    return rows


SUITE = SuiteEntry(sizes={
    # trains the DI textures here (the shipped ones are found only at their own size)
    "cpu": Sizing(("--images", "astronaut", "--ratios", "6"), 60),
    "device": Sizing(("--images", "astronaut,chelsea", "--size", "256", "--ratios", "6", "--steps", "2000"), 60),
}, claims=CLAIMS, headlines=headlines)
