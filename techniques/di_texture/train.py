"""Texture compression with Differentiable Indirection (Datta et al. 2023 §4.2.1).

A texture (k <= 8 channels, 8-bit) becomes a 2D primary array (4 channels, the (u, v, u, v)
repeated ramp, triangle F) looked up at uv, whose output indexes a 4D cascaded array holding the
k channels. Both arrays are exported at 8 bits; the byte budget is the uncompressed size
(W * H * k bytes) divided by the ratio, solved by `indirection.size_cascade` (N_p a multiple of
8, N_c a multiple of 4). Training (see DEFAULTS): the paper's stratified uv with bilinear targets
and L1 under Adam with a cosine schedule first; then, for the last `finish` fraction of the sample
budget, texel centres with the squared error -- the points and the error that PSNR (ours and the
block codecs') scores -- as full-batch L-BFGS on all texel centres (`finish_optimizer="lbfgs"`),
or as the same minibatch Adam and schedule on texel-centre batches ("adam"). Measured on
astronaut 256^2 at 6x, 6000 steps: 30.9 dB with the paper's recipe throughout, 32.6 dB with the
Adam finish at 0.5 (the L1 phase reached 30.9 dB at 3000 steps), 32.6-33.0 dB with L-BFGS (see
FINISH_OPTIMIZERS); `finish=0` is the paper's protocol.

Colour: the arrays hold the sRGB-*encoded* values (what an RGB8 texture, ASTC and BC compress),
so 8-bit cells lose no more than the source's own precision. The bundle then decodes to linear
light, as the renderer expects (passes/field2d.frag shows linear output; PNGs are sRGB-encoded
on write): for colour textures (k = 1 or 3) each channel is picked by a one-hot dense node and
passed through a fixed 256-entry float32 1D lookup of the sRGB EOTF (piecewise-linear; at most
6e-6 from the exact curve, far below one 8-bit step) -- the job an SRGB8 texture format does in
hardware. These decode tables are the same for every texture and are not counted in the
compressed bytes (reported as `decode_table_bytes`).

Orientation follows techniques/neural_image/train.py: uv (0, 0) is the bottom-left of the picture.

    from inshade.techniques.di_texture.train import compress, load_image
    image, notes = load_image("skimage:astronaut", size=256)
    result = compress(image, ratio=6)
    result.bundle.save("trained/di_texture_astronaut")

Command: ``inshade train di_texture IMAGE --ratio 6 [--preset quick|ship] --force -o trained/di_texture_<name>``
(IMAGE a file or ``skimage:NAME``; ``inshade compress`` is the same command). ``--preset ship`` with a
shipped asset's IMAGE, ``--size`` and ``--ratio`` (SHIP_ASSETS) is exactly what built it; OUT/metrics.json
records the preset and the resolved settings.
"""
from __future__ import annotations

import argparse
import datetime
import json
import math
import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from inshade.files import atomic_write
from inshade.progress import default_interval
from inshade import asset_folder, command
from inshade.devices import DeviceError, add_device_argument, resolve_device
from inshade.metrics import psnr, srgb_eotf, srgb_oetf
from inshade.models import indirection as di
from inshade.models.graph import GraphModule
from inshade.models.lookup_array import LookupArray
from inshade.models.mlp import Dense
from inshade.techniques.neural_image.train import pixel_uvs

KIND = "di_texture"
MAX_CHANNELS = 8
MIN_SIZE = 8
DECODE_TABLE_SIZE = 256
RENDER_PROGRAM = "passes/field2d.frag"
# Training lengths: "quick" runs in a couple of minutes on one CPU thread; "ship" is what the
# trained/ assets use (12000 steps, ~10 min a 256^2 texture on one thread of the 2-core machine).
PRESETS = {"quick": dict(steps=1500), "ship": dict(steps=12000)}
# The inputs of each shipped asset (IMAGE, --size, --ratio beside --preset ship): preset_settings() adds them.
SHIP_ASSETS = {"di_texture_astronaut": dict(image="skimage:astronaut", size=256, ratio=6.0),
               "di_texture_astronaut_12x": dict(image="skimage:astronaut", size=256, ratio=12.0),
               "di_texture_chelsea": dict(image="skimage:chelsea", size=256, ratio=6.0),
               "di_texture_coffee": dict(image="skimage:coffee", size=256, ratio=6.0)}
SETTINGS = ("image", "size", "ratio", "rho", "steps", "lr", "batch", "schedule", "finish", "finish_optimizer", "seed")
# Chosen by measurement on astronaut 256x256 at 6x on the shared 2-core CPU (see
# docs in the report of `inshade bench di_texture`): lr 1e-2 with cosine decay reaches in ~2 min what
# 1e-3 does not reach in 10; batch 16384 stratified samples (4 batches an epoch at 256^2).
DEFAULTS = dict(ratio=6.0, rho=None, steps=PRESETS["quick"]["steps"], lr=1e-2, batch=16384, schedule="cosine",
                seed=0,                 clip_primary=None, finish=0.5, finish_optimizer="lbfgs")
# The finish phase's optimiser. "adam": the same minibatch Adam and schedule on texel-centre
# batches. "lbfgs": the Adam phase (schedule over its own steps) is followed by full-batch L-BFGS
# on all texel centres, given the same number of samples as the Adam finish would see
# (finish steps * batch / texels evaluations of the whole texture), so it costs no more time.
# Measured on astronaut 256^2 / 6x, 6000 steps, 1 thread (8-bit PSNR, seeds 0 / 1): Adam finish
# 32.54 / 32.51 dB in 120 / 122 s, L-BFGS 32.62 / 33.02 dB in 110 / 116 s; 12000 steps, seed 0:
# Adam 32.97 dB in 232 s, L-BFGS 33.33 dB in 208 s; the shipped 12000-step RGB assets gained
# 0.25-0.72 dB. Hence the default; the gain follows the Adam phase's (seed-dependent) end point,
# and on the 8-lane PBR set (144^2 primary) L-BFGS was 0.17 dB *worse* (techniques/di_pbr_set/train.py keeps
# "adam"). (Full-batch Adam at lr 1e-2 matched L-BFGS: the gain is the full batch.)
FINISH_OPTIMIZERS = ("adam", "lbfgs")
# rho = N_p / N_c. None: the largest primary that fits with the smallest cascaded array
# (N_c = 4) -- at the small sizes trained here the primary is the one that carries detail
# (paper: rho in [40, 128] for 1K-4K textures; a 256^2 texture at 6x fits N_p = 88 only).
RHO_SMALLEST_CASCADE = None


class CompressionError(ValueError):
    """An image or a setting the compressor cannot use; the message says what to change."""


def preset_settings(preset: str, asset: str | None = None) -> dict:
    """The settings ``--preset PRESET`` resolves to (what metrics.json records as "settings") for the
    shipped asset folder name ``asset`` (its image, size and ratio; None: no image, the default ratio)."""
    inputs = SHIP_ASSETS[asset] if asset else dict(image=None, size=None)
    return {k: inputs.get(k, PRESETS[preset].get(k, DEFAULTS.get(k))) for k in SETTINGS}


def on_device(batches, device):
    """A sampler's (x, target) batches moved to ``device``: the samplers draw on their CPU
    generator (so a seed gives the same numbers on every device), the training runs where the
    cascade is; on the CPU this is the identity."""
    for batch in batches:
        yield tuple(t.to(device) for t in batch)


# ---------------------------------------------------------------------------------------------
# input

def _read_source(spec: str) -> tuple[np.ndarray, str]:
    if spec.startswith("skimage:"):
        import skimage.data

        name = spec.split(":", 1)[1]
        fn = getattr(skimage.data, name, None)
        if fn is None or not callable(fn) or name.startswith("_"):
            raise CompressionError(f"{spec}: skimage.data has no image {name!r} "
                                   "(e.g. skimage:astronaut, skimage:coffee, skimage:chelsea)")
        try:
            return np.asarray(fn()), f"skimage.data.{name}"
        except Exception as e:  # data download needed, etc.
            raise CompressionError(f"{spec}: could not load ({e})") from None
    path = Path(spec)
    if not path.is_file():
        raise CompressionError(f"{spec}: no such image file (or use skimage:NAME)")
    from PIL import Image

    try:
        with Image.open(path) as im:
            if im.mode == "P":
                im = im.convert("RGBA" if "transparency" in im.info else "RGB")
            if im.mode in ("I;16", "I;16B", "I;16L", "I"):
                arr = np.asarray(im).astype(np.uint16 if im.mode.startswith("I;16") else np.int32)
                if arr.dtype == np.int32:
                    arr = arr.clip(0, 65535).astype(np.uint16)
                return arr, str(path)
            if im.mode not in ("L", "LA", "RGB", "RGBA"):
                im = im.convert("RGB")
            return np.asarray(im), str(path)
    except OSError as e:
        raise CompressionError(f"{spec}: not a readable image ({e})") from None


def prepare_image(pixels: np.ndarray, size: int | None = None, where: str = "image"):
    """Checks and normalises an image to float32 [H, W, k] in [0, 1] (row 0 = top), returning
    (image, notes). Handled with a note: 16-bit input (reduced to 8-bit precision), grayscale
    (one channel), an opaque alpha channel (dropped), a non-square image when `size` is given
    (centre-cropped and resized). Rejected with one CompressionError: non-square without
    `size`, translucent alpha, more than 8 channels, smaller than 8x8, floats outside [0, 1]."""
    notes: list[str] = []
    a = np.asarray(pixels)
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] < 1:
        raise CompressionError(f"{where}: expected [H, W] or [H, W, C], got shape {a.shape}")
    if a.dtype == np.bool_:
        a = a.astype(np.uint8) * 255
    if np.issubdtype(a.dtype, np.integer):
        peak = np.iinfo(a.dtype).max
        if a.dtype.itemsize > 1:
            notes.append(f"{a.dtype} input ({8 * a.dtype.itemsize}-bit) reduced to 8-bit precision: "
                         "DI stores 8-bit cells and metrics are measured in sRGB 8-bit")
        a = a.astype(np.float64) / peak
    elif np.issubdtype(a.dtype, np.floating):
        if not np.all(np.isfinite(a)) or a.min() < 0.0 or a.max() > 1.0:
            raise CompressionError(f"{where}: float images must hold sRGB-encoded values in [0, 1] "
                                   f"(got range {np.nanmin(a):.3g}..{np.nanmax(a):.3g})")
        a = a.astype(np.float64)
    else:
        raise CompressionError(f"{where}: unsupported pixel type {a.dtype}")
    c = a.shape[2]
    if c in (2, 4):                                   # grey + alpha, RGB + alpha
        alpha = a[..., -1]
        if np.all(alpha >= 1.0 - 1e-6):
            notes.append("opaque alpha channel dropped")
            a = a[..., :-1]
        else:
            raise CompressionError(f"{where}: has a translucent alpha channel; compress its colour "
                                   "(drop or pre-multiply the alpha) or pass all channels as a "
                                   "generic k-channel array to compress()")
    if a.shape[2] == 1:
        notes.append("grayscale: compressed as one channel (shown grey)")
    if a.shape[2] > MAX_CHANNELS:
        raise CompressionError(f"{where}: {a.shape[2]} channels; at most {MAX_CHANNELS} are supported")
    h, w = a.shape[:2]
    if size is not None:
        if size < MIN_SIZE:
            raise CompressionError(f"size {size} is below the minimum of {MIN_SIZE}")
        s = min(h, w)
        top, left = (h - s) // 2, (w - s) // 2
        if (h, w) != (s, s):
            notes.append(f"centre-cropped {w}x{h} to {s}x{s}")
        a = a[top:top + s, left:left + s]
        if s != size:
            import skimage.transform

            a = skimage.transform.resize(a, (size, size), order=1, anti_aliasing=s > size, mode="edge")
            a = np.round(np.clip(a, 0, 1) * 255) / 255    # keep the reference an 8-bit image
            notes.append(f"resized {s}x{s} to {size}x{size}")
        h = w = size
    if h != w:
        raise CompressionError(f"{where}: {w}x{h} is not square; DI textures here use a square primary "
                               "array: pass --size N (centre-crop to a square, then resize to N)")
    if h < MIN_SIZE:
        raise CompressionError(f"{where}: {w}x{h} is smaller than {MIN_SIZE}x{MIN_SIZE}")
    if h % 2:
        notes.append(f"odd size {w}x{h}: fine for DI (uv space); block codecs need multiples of their block")
    return np.ascontiguousarray(a, dtype=np.float32), notes


def load_image(spec: str, size: int | None = None):
    """(image float32 [H, W, k] sRGB-encoded, notes, source) from a file or ``skimage:NAME``."""
    pixels, source = _read_source(spec)
    image, notes = prepare_image(pixels, size, where=spec)
    return image, notes, source


# ---------------------------------------------------------------------------------------------
# sizing and the graph

def uncompressed_bytes(image_shape) -> int:
    h, w, k = image_shape
    return int(h) * int(w) * int(k)


def plan(image_shape, ratio: float, rho: float | None = None):
    """The cascade for `ratio` (uncompressed 8-bit bytes / ratio). rho None: largest primary that
    fits next to an N_c = 4 cascaded array."""
    h, w, k = image_shape
    if not (isinstance(ratio, (int, float)) and math.isfinite(ratio) and ratio >= 1.0):
        raise CompressionError(f"ratio must be a number >= 1, got {ratio!r}")
    budget = uncompressed_bytes(image_shape) / float(ratio)
    common = dict(primary_dims=2, primary_channels=4, cascaded_dims=4, cascaded_channels=int(k))
    if rho is None:
        cascaded = di.array_bytes(4, 4, int(k), 8)
        side = int(math.floor(math.sqrt(max(budget - cascaded, 0) / 4.0) / 8)) * 8
        rho = max(side, 8) / 4.0
    try:
        return di.size_cascade(int(budget), float(rho), **common)
    except ValueError as e:
        smallest = di.array_bytes(8, 2, 4, 8) + di.array_bytes(4, 4, int(k), 8)
        raise CompressionError(
            f"ratio {ratio:g} cannot be met for a {w}x{h}x{k} texture: the budget is {int(budget)} bytes "
            f"and the smallest cascade (8x8x4 primary + 4^4x{k} cascaded) needs {smallest} bytes "
            f"(max ratio {uncompressed_bytes(image_shape) / smallest:.1f}); details: {e}") from None


def decode_nodes(g: GraphModule, src: str, channels: int) -> str:
    """Appends the sRGB-encoded -> linear decode: per channel a one-hot dense pick and a float32
    1D EOTF table, then an identity dense that gathers them. Returns the last node's id."""
    x = np.linspace(0.0, 1.0, DECODE_TABLE_SIZE)
    table = torch.from_numpy(srgb_eotf(x).astype(np.float32)).reshape(DECODE_TABLE_SIZE, 1)
    picked = []
    for c in range(channels):
        pick = Dense(channels, 1, bias=False)
        with torch.no_grad():
            pick.linear.weight.zero_()
            pick.linear.weight[0, c] = 1.0
        g.add(f"pick{c}", pick, src)
        g.add(f"eotf{c}", LookupArray([DECODE_TABLE_SIZE], 1, 32, "none", init=table.clone()), f"pick{c}")
        picked.append(f"eotf{c}")
    gather = Dense(channels, channels, bias=False)
    with torch.no_grad():
        gather.linear.weight.copy_(torch.eye(channels))
    return g.add("linear", gather, picked)


def export_graph(core: GraphModule, channels: int, decode: bool) -> GraphModule:
    """The bundle graph: the trained primary -> cascaded, then (colour) the sRGB decode."""
    g = GraphModule([("uv", 2, "uv")])
    g.add("primary", core.nodes["primary"], "uv")
    g.add("cascaded", core.nodes["cascaded"], "primary")
    if decode:
        name = "rgb" if channels == 3 else "grey"
        g.output(name, decode_nodes(g, "cascaded", channels), "linear_rgb" if channels == 3 else "linear")
    else:
        g.output("values", "cascaded", "generic")
    for p in g.parameters():
        p.requires_grad_(False)
    return g


# ---------------------------------------------------------------------------------------------
# quality

def to_srgb8(values: np.ndarray, linear: bool) -> np.ndarray:
    v = srgb_oetf(values) if linear else np.clip(values, 0.0, 1.0)
    return np.rint(np.asarray(v, np.float64) * 255.0).astype(np.uint8)


def torch_decode(bundle_or_graph, size: int) -> np.ndarray:
    """The bundle's output at the pixel centres [H, W, out] (image orientation)."""
    from inshade.bundle import Bundle

    g = GraphModule.from_bundle(bundle_or_graph) if isinstance(bundle_or_graph, Bundle) else bundle_or_graph
    uv = torch.from_numpy(pixel_uvs(size, size).reshape(-1, 2))
    with torch.no_grad():
        out = g(uv)
    return out.reshape(size, size, -1).numpy()


def glsl_decode(bundle, size: int, lut_filter: str = "exact", ctx=None) -> np.ndarray:
    """The bundle decoded by its generated GLSL through the GL driver (passes/evaluate.frag) at
    the pixel centres: [H, W, out] float32 (image orientation)."""
    from inshade.codegen import generate
    from inshade.runtime.context import shared_context
    from inshade.runtime.network import NetworkEvaluator

    ctx = shared_context() if ctx is None else ctx
    gen = generate(bundle, lut_filter=lut_filter)
    ev = NetworkEvaluator(ctx, gen, width=min(size, 1024))
    try:
        out = ev(pixel_uvs(size, size).reshape(-1, 2))
    finally:
        ev.release()
    return out.reshape(size, size, -1)


def decoded_metrics(bundle, image: np.ndarray, linear: bool, filters=("exact", "fast")) -> dict:
    """PSNR (sRGB 8-bit) of the GLSL-decoded texture per LUT path, and the exact path's max
    difference from torch on the same (quantised) bundle."""
    from inshade.runtime.context import gl_info, shared_context

    size = image.shape[0]
    ref8 = to_srgb8(image, False)
    ctx = shared_context()
    out = {"gl_renderer": gl_info(ctx)["renderer"]}
    ref_torch = torch_decode(bundle, size)
    out["psnr_srgb8_torch"] = round(psnr(to_srgb8(ref_torch, linear), ref8, 255.0), 4)
    for f in filters:
        dec = glsl_decode(bundle, size, f, ctx)
        out[f"psnr_srgb8_glsl_{f}"] = round(psnr(to_srgb8(dec, linear), ref8, 255.0), 4)
        out[f"max_abs_diff_glsl_{f}_vs_torch"] = float(np.max(np.abs(dec.astype(np.float64) - ref_torch)))
    return out


# ---------------------------------------------------------------------------------------------
# compress

@dataclass
class Result:
    graph: GraphModule          # bundle graph (float cells; the bundle holds them quantised)
    bundle: object              # inshade.bundle.Bundle
    history: di.History
    image: np.ndarray           # the target, [H, W, k] sRGB-encoded, row 0 = top
    metrics: dict = field(default_factory=dict)


def compress(image: np.ndarray, ratio: float = DEFAULTS["ratio"], *, rho: float | None = DEFAULTS["rho"],
             steps: int = DEFAULTS["steps"], lr: float = DEFAULTS["lr"], batch: int = DEFAULTS["batch"],
             schedule: str = DEFAULTS["schedule"], seed: int = DEFAULTS["seed"],
             clip_primary=DEFAULTS["clip_primary"], finish: float = DEFAULTS["finish"],
             finish_optimizer: str = DEFAULTS["finish_optimizer"],
             decode: bool | None = None, gl_metrics: bool = True,
             provenance: dict | None = None, name: str = KIND, progress: bool | None = None,
             device=None) -> Result:
    """Compress `image` (anything `prepare_image` accepts, e.g. uint8 [H, W, 3]) by `ratio`.
    Returns the Result with an exported 8-bit bundle whose metrics hold the sizes, the training
    time and PSNR (sRGB 8-bit) in torch and -- `gl_metrics` -- decoded by the GLSL (exact and
    fast LUT paths). `decode` (default: for 1 or 3 channels) appends the sRGB -> linear decode.
    `device` (a torch.device; default the CPU) is where the training runs; the exported result
    and its metrics are computed on the CPU."""
    if not 0.0 <= finish <= 1.0:
        raise CompressionError(f"finish must be a fraction of the steps in [0, 1], got {finish!r}")
    if finish_optimizer not in FINISH_OPTIMIZERS:
        raise CompressionError(f"unknown finish optimizer {finish_optimizer!r}; known: "
                               f"{', '.join(FINISH_OPTIMIZERS)}")
    image, notes = prepare_image(image)
    h, w, k = image.shape
    decode = k in (1, 3) if decode is None else bool(decode)
    sizing = plan(image.shape, ratio, rho)
    device = torch.device("cpu") if device is None else torch.device(device)
    torch.manual_seed(seed)
    flipped = np.ascontiguousarray(image[::-1])     # row 0 = v ~ 0 = bottom of the picture
    core = di.cascade(2, k, sizing.n_primary, sizing.n_cascaded, redundant=2,
                      cascaded_init="mean", cascaded_init_args={"target": image.reshape(-1, k)},
                      input_name="uv", input_semantic="uv", output_name="values").to(device)
    eval_set = di.image_eval_set(flipped)
    eval_on_device = tuple(t.to(device) for t in eval_set)
    finish_at = steps - int(round(finish * steps))
    lbfgs = finish_optimizer == "lbfgs" and finish_at < steps
    t0 = time.perf_counter()
    if progress is not False:
        print(f"{name}: training {steps} steps ({sizing.n_primary}^2 primary, {sizing.n_cascaded}^2 cascaded; "
              f"progress every {default_interval():g} s)", file=sys.stderr, flush=True)
    history = di.train_cascade(core, on_device(di.image_sampler(flipped, batch, seed=seed), device),
                               finish_at if lbfgs else steps,
                               lr=lr, schedule=schedule, seed=seed, eval_set=eval_on_device, clip_primary=clip_primary,
                               finish=(finish_at, on_device(di.texel_sampler(flipped, batch, seed=seed + 1), device),
                                       "mse") if finish_at < steps and not lbfgs else None,
                               progress=progress, desc=name)
    if lbfgs:   # the same sample budget as the Adam finish, as whole-texture evaluations
        evaluations = max(1, round((steps - finish_at) * batch / (h * w)))
        di.finish_lbfgs(core, eval_on_device, evaluations, history=history, first_step=finish_at)
    seconds = time.perf_counter() - t0
    core = core.to("cpu")       # export and metrics on the CPU
    graph = export_graph(core, k, decode)
    q = di.evaluate_quantised(core, 8, *eval_set)
    raw = uncompressed_bytes(image.shape)
    metrics = {
        "width": w, "height": h, "channels": k,
        "ratio_requested": float(ratio), "ratio": round(raw / sizing.bytes, 4),
        "bytes": sizing.bytes, "uncompressed_bytes": raw,
        "bytes_with_headers": sizing.bytes + 8 * (4 + k),   # + per-channel scale/offset (fp32 x 2)
        "bits_per_pixel": round(8.0 * sizing.bytes / (h * w), 4),
        "n_primary": sizing.n_primary, "n_cascaded": sizing.n_cascaded, "rho": round(sizing.rho, 4),
        "decode_table_bytes": (k * DECODE_TABLE_SIZE * 4 + k * 4 + k * k * 4) if decode else 0,
        "train_seconds": round(seconds, 2), "steps": steps, "finish_steps": steps - finish_at,
        "finish_optimizer": finish_optimizer,
        "psnr_step0": round(history.records[0]["psnr"], 4),
        "psnr_float": round(q["psnr_float"], 4), "psnr_quantised": round(q["psnr_quantised"], 4),
        "history": [{"step": r["step"], "psnr": round(r["psnr"], 3), "seconds": round(r["seconds"], 2)}
                    for r in history.records],
    }
    prov = {
        "technique": "Differentiable Indirection texture compression (Datta et al. 2023), 2D primary "
                     "(4 ch, (u,v,u,v) ramp, triangle F) -> 4D cascaded (k ch); 8-bit arrays",
        "training": f"stratified uv (one stratum per texel), bilinear targets, L1, Adam lr {lr:g}, "
                    f"{schedule} schedule, batch {batch}, {steps} steps, seed {seed}; the last "
                    f"{steps - finish_at} steps on texel centres with the squared error"
                    + (" by full-batch L-BFGS (as many texel samples as those steps' batches)"
                       if lbfgs else ""),
        "colour": "arrays hold sRGB-encoded values; the graph decodes to linear (sRGB EOTF tables)"
                  if decode else "arrays hold the channel values as given (no colour decode)",
        "uv_convention": "uv (0,0) = bottom-left of the picture, (1,1) = top-right; pixel centres",
        "notes": notes, "torch": torch.__version__, "device": str(device),
        "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }
    prov.update(provenance or {})
    render = {"program": RENDER_PROGRAM, "width": w, "height": h, "input": "uv",
              "output": graph.outputs[0][0]} if decode else None
    bundle = graph.export(KIND, name, provenance=prov, metrics=metrics, render=render)
    if gl_metrics:
        if progress is not False:
            print(f"{name}: decoding through the GLSL (exact and fast lookups) for its PSNR", file=sys.stderr,
                  flush=True)
        metrics.update(decoded_metrics(bundle, image, decode))
        bundle = graph.export(KIND, name, provenance=prov, metrics=metrics, render=render)
    return Result(graph, bundle, history, image, metrics)


# ---------------------------------------------------------------------------------------------
# asset folder

def scene_dict(name: str, title: str, size: int, output: str, lut_filter: str = "exact") -> dict:
    return {
        "format": "inshade.scene", "version": 1, "name": name, "title": title,
        "program": RENDER_PROGRAM, "size": [size, size],
        "networks": [{"bundle": ".", "prefix": "net", "output": output}],
        "reference": {"image": "reference.png", "colour": "srgb", "space": "field"},
        "camera": {"type": "plane2d", "center": [0.5, 0.5], "zoom": 1.0, "aspect": 1.0},
        "bookmarks": {
            "whole picture": {"type": "plane2d", "center": [0.5, 0.5], "zoom": 1.0, "aspect": 1.0},
            "detail 4x": {"type": "plane2d", "center": [0.45, 0.6], "zoom": 4.0, "aspect": 1.0},
        },
        "lights": [], "environment": None,
        "display": {"mode": "final", "modes": ["final", "network", "reference", "error", "split"], "split": 0.5},
        "settings": {
            "exposure": {"type": "float", "default": 1.0, "min": 0.0, "max": 8.0, "uniform": "u_exposure",
                         "label": "exposure"},
            "error_scale": {"type": "float", "default": 4.0, "min": 1.0, "max": 64.0,
                            "uniform": "u_error_scale", "label": "error x"},
            "lut_filter": {"type": "choice", "default": lut_filter, "choices": ["exact", "fast"],
                           "codegen": "lut_filter", "label": "LUT filtering"},
        },
        "requires": {"gl": 330},
    }


def write_asset(result: Result, out, title: str, lut_filter: str = "exact") -> Path:
    """bundle.json + weights.safetensors + scene.json + preview.png (torch decode of the quantised
    bundle, linear) + reference.png (the 8-bit original)."""
    from inshade.runtime.image_io import write_png

    out = Path(out)
    result.bundle.save(out)
    size = result.image.shape[0]
    output = result.graph.outputs[0][0]
    if result.bundle.meta.get("render"):
        atomic_write(out / "scene.json", json.dumps(scene_dict(out.name, title, size, output, lut_filter),
                                                   indent=2) + "\n")
        preview = torch_decode(result.bundle, size)
        ref = srgb_eotf(result.image)
        if preview.shape[-1] == 1:
            preview, ref = np.repeat(preview, 3, -1), np.repeat(ref, 3, -1)
        write_png(out / "preview.png", preview)
        write_png(out / "reference.png", ref)
    return out


# ---------------------------------------------------------------------------------------------
# command line

def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    d = DEFAULTS
    p.add_argument("image", metavar="IMAGE", help="image file (PNG/JPEG/...) or skimage:NAME (e.g. skimage:astronaut)")
    asset_folder.add_arguments(p, "di_texture_<image>")
    p.add_argument("--ratio", type=float, default=d["ratio"], help="compression ratio vs 8-bit (default %(default)s)")
    p.add_argument("--size", type=int, help="centre-crop to a square and resize to SIZE x SIZE first")
    p.add_argument("--rho", type=float, default=None,
                   help="N_p / N_c (default: largest primary next to an N_c = 4 cascaded array)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="quick",
                   help="training length: " + ", ".join(f"{k} = {v['steps']} steps" for k, v in PRESETS.items())
                        + "; ship with IMAGE, --size and --ratio of a shipped asset is exactly what built it "
                        "(README) (default %(default)s)")
    p.add_argument("--steps", type=int, help="training steps (overrides --preset)")
    p.add_argument("--lr", type=float, default=d["lr"], help="Adam learning rate (default %(default)s)")
    p.add_argument("--batch", type=int, default=d["batch"], help="samples per step (default %(default)s)")
    p.add_argument("--schedule", choices=sorted(di.SCHEDULES), default=d["schedule"])
    p.add_argument("--finish", type=float, default=d["finish"],
                   help="fraction of the steps trained last on texel centres with the squared error "
                        "(0: the paper's stratified L1 throughout; default %(default)s)")
    p.add_argument("--finish-optimizer", choices=FINISH_OPTIMIZERS, default=d["finish_optimizer"],
                   help="finish phase: minibatch Adam under the same schedule, or full-batch L-BFGS on all "
                        "texel centres with the same sample budget (default %(default)s)")
    p.add_argument("--seed", type=int, default=d["seed"])
    p.add_argument("--lut-filter", choices=("exact", "fast"), default="exact",
                   help="the scene's default LUT path (default %(default)s)")
    p.add_argument("--title", help="scene title")
    p.add_argument("--no-gl", action="store_true", help="skip the GLSL-decoded metrics (no GL context)")
    add_device_argument(p)
    return p


def run(args, argv=None) -> int:
    device = resolve_device(args.device)     # first: a missing CUDA device fails before any work
    args.out = str(asset_folder.claim(args.out, f"di_texture_{Path(args.image.removeprefix('skimage:')).stem}", force=args.force))
    if args.steps is None:
        args.steps = PRESETS[args.preset]["steps"]
    if args.steps < 0 or args.batch < 1:
        raise CompressionError("--steps must be >= 0 and --batch >= 1")
    image, notes, source = load_image(args.image, args.size)
    for n in notes:
        print(f"inshade: note: {n}", file=sys.stderr)
    argv = list(sys.argv[1:] if argv is None else argv)
    command = shlex.join(["inshade", "train", "di_texture", *argv])
    name = Path(args.out).name
    result = compress(image, args.ratio, rho=args.rho, steps=args.steps, lr=args.lr, batch=args.batch,
                      schedule=args.schedule, seed=args.seed, finish=args.finish,
                      finish_optimizer=args.finish_optimizer, gl_metrics=not args.no_gl,
                      name=name, device=device,
                      provenance={"command": command, "image": source, "image_notes": notes})
    title = args.title or f"DI texture: {source}, {result.metrics['ratio']:.2f}x"
    out = write_asset(result, args.out, title, args.lut_filter)
    m = result.metrics
    # metrics.json: the preset, the settings it resolved to (tests/test_presets.py holds the shipped
    # assets' equal to preset_settings("ship", asset)) and the bundle's metrics without the loss history
    settings = {k: getattr(args, k) for k in SETTINGS}
    atomic_write(out / "metrics.json", json.dumps({"command": command, "preset": args.preset, "settings": settings,
                                                   **{k: v for k, v in m.items() if k != "history"}},
                                                  indent=1) + "\n")
    gl = (f", GLSL exact {m['psnr_srgb8_glsl_exact']:.2f} dB / fast {m['psnr_srgb8_glsl_fast']:.2f} dB"
          if "psnr_srgb8_glsl_exact" in m else "")
    print(f"wrote {out}: {m['ratio']:.2f}x ({m['bytes']} bytes, N_p {m['n_primary']}, N_c {m['n_cascaded']}), "
          f"PSNR sRGB8 torch {m['psnr_srgb8_torch'] if 'psnr_srgb8_torch' in m else m['psnr_quantised']:.2f} dB"
          f"{gl}, {m['train_seconds']:.1f} s")
    return 0


def main(argv=None) -> int:
    return command.main("inshade train di_texture", __doc__, add_arguments, run, argv, errors=(DeviceError,))

