"""Texture compression with Differentiable Indirection (Datta et al. 2023 §4.2.1), the library
every DI texture shares: a k-channel texture (k <= 8, 8-bit) becomes a 2D primary array (4
channels, triangle F) looked up at uv, whose output indexes a 4D
cascaded array holding the k channels, both exported at 8 bits. `compress` sizes the cascade for a
ratio, starts it from the image's principal colour axes (`pca_init`), trains it (the squared
error on texel centres and stratified points under Adam: see DEFAULTS) and exports the bundle;
`decode_nodes` appends the sRGB -> linear decode (per channel a one-hot pick and
a 256-entry float32 EOTF table: the job an SRGB8 texture format does in hardware).

Colour: the arrays hold the sRGB-*encoded* values (what an RGB8 texture, ASTC and BC compress), so
8-bit cells lose no more than the source's own precision. uv (0, 0) is the bottom-left of the
picture; `inshade.pixels.pixel_uvs` gives the pixel centres.
"""
from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from inshade.components.dense.torch_twin import Dense
from inshade.components.lookup_array.torch_twin import LookupArray
from inshade.metrics import srgb_eotf, srgb_oetf
from inshade.models import indirection as di
from inshade.models.fit_loop import history_rows
from inshade.models.graph import GraphModule
from inshade.pixels import pixel_uvs
from inshade.progress import default_interval
from inshade.provenance import recorded_at

KIND = "di_texture"          # the bundle kind of a DI texture
MAX_CHANNELS = 8
MIN_SIZE = 8
DECODE_TABLE_SIZE = 256
FIELD_PROGRAM = "passes/field2d.frag"   # a decoded texture draws as a 2D field
# Chosen by measurement on astronaut 256x256 at 6x on the shared 2-core CPU (see
# docs in the report of `inshade bench di_texture`): lr 1e-2 with cosine decay reaches in ~2 min what
# 1e-3 does not reach in 10; batch 16384 stratified samples (4 batches an epoch at 256^2).
DEFAULTS = dict(ratio=6.0, rho=None, steps=1500, lr=1e-2, batch=16384, schedule="cosine",
                seed=0, clip_primary=None, finish=1.0, finish_optimizer="adam", init="pca")
# The recipe, measured on hubble_deep_field at 1K / 6x (3000 steps, the pca start, N_c 8; PSNR at
# texel centres / between texels as `inshade bench di_texture` scores them): the paper's stratified
# L1 for the first half then a texel-centre squared-error finish 37.85 / 38.58 dB (L-BFGS finish,
# N_c 4: 37.34 / 38.64); the squared error throughout on texel centres only 39.20 / 37.86 (a fit
# to the scored points at the cost of the points between them); on stratified points only
# 37.96 / 40.05; on both (`indirection.mixed_sampler`) 38.64 / 39.73 -- the default: finish 1.0
# on mixed points. The pca start: +1.9 dB on astronaut 256^2 (1500 steps), +2.6 dB on retina at
# 1K, +5 dB on the 8-lane PBR bricks at 256^2 (3000 steps) over the ramp.
# The finish phase's optimiser. "adam": the same minibatch Adam and schedule on mixed batches
# (texel centres + stratified points). "lbfgs": the Adam phase (schedule over its own steps) is
# followed by full-batch L-BFGS on all texel centres, given the same number of samples as the Adam finish would see
# (finish steps * batch / texels evaluations of the whole texture), so it costs no more time.
# Measured on astronaut 256^2 / 6x, 6000 steps, 1 thread (8-bit PSNR, seeds 0 / 1): Adam finish
# 32.54 / 32.51 dB in 120 / 122 s, L-BFGS 32.62 / 33.02 dB in 110 / 116 s; 12000 steps, seed 0:
# Adam 32.97 dB in 232 s, L-BFGS 33.33 dB in 208 s; the shipped 12000-step RGB assets gained
# 0.25-0.72 dB (the previous default); the gain follows the Adam phase's (seed-dependent) end
# point, and on the 8-lane PBR set (144^2 primary) L-BFGS was 0.17 dB *worse*. At 1K its sample
# budget buys few whole-texture evaluations (23 in 3000 steps): 0.7 dB below the Adam finish on
# hubble_deep_field, and it fits the texel centres alone.
FINISH_OPTIMIZERS = ("adam", "lbfgs")
# rho = N_p / N_c. None: the cascaded side from CASCADE_SIDES -- the largest whose array stays
# within CASCADE_SHARE of the budget -- next to the largest primary that fits. Measured with the
# "pca" start (3000 steps, sRGB 8-bit PSNR): at 1K, N_c = 8 beat N_c = 4 by 0.47 dB (hubble, 6x:
# N_p 352 vs 360), 0.74 dB (hubble, 12x) and 0.93 dB (retina, 6x), while N_c = 12 (12% of the
# budget) only tied N_c = 8 and N_c = 16 (22%) lost 0.9 dB; at 256^2 / 6x an N_c = 8 cascade
# would take 38% of the budget (N_p 64) and lost 0.8 dB to N_c = 4 (N_p 88). At the small sizes
# the primary carries the detail (paper: rho in [40, 128] for 1K-4K textures).
CASCADE_SIDES = (4, 8)
CASCADE_SHARE = 0.05
# The cascaded cells are kept within CASCADED_RANGE while training (None: unbounded). Its 8-bit
# export steps by (hi - lo) / 255, and hardware filtering of unorm8 textures may round its
# filtered value to that step (llvmpipe does): unbounded, the cascade of astronaut 256^2 / 6x
# grew to a range of 6.5-8.4 (its fast path 0.97 dB below the exact one; 8-bit weights alone
# cost 0.01 dB, simulated); clamped to [0, 1] the fast path lost 0.03 dB but the exact one 0.55.
CASCADED_RANGE = (-0.5, 1.5)


class CompressionError(ValueError):
    """An image or a setting the compressor cannot use; the message says what to change."""


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
    """The cascade for `ratio` (uncompressed 8-bit bytes / ratio). rho None: the cascaded side
    CASCADE_SIDES / CASCADE_SHARE choose, and the largest primary that fits next to it."""
    h, w, k = image_shape
    if not (isinstance(ratio, (int, float)) and math.isfinite(ratio) and ratio >= 1.0):
        raise CompressionError(f"ratio must be a number >= 1, got {ratio!r}")
    budget = uncompressed_bytes(image_shape) / float(ratio)
    common = dict(primary_dims=2, primary_channels=4, cascaded_dims=4, cascaded_channels=int(k))
    if rho is None:
        n_c = max([n for n in CASCADE_SIDES if di.array_bytes(n, 4, int(k), 8) <= CASCADE_SHARE * budget],
                  default=CASCADE_SIDES[0])
        side = int(math.floor(math.sqrt(max(budget - di.array_bytes(n_c, 4, int(k), 8), 0) / 4.0) / 8)) * 8
        rho = max(side, 8) / n_c
    try:
        return di.size_cascade(int(budget), float(rho), **common)
    except ValueError as e:
        smallest = di.array_bytes(8, 2, 4, 8) + di.array_bytes(4, 4, int(k), 8)
        raise CompressionError(
            f"ratio {ratio:g} cannot be met for a {w}x{h}x{k} texture: the budget is {int(budget)} bytes "
            f"and the smallest cascade (8x8x4 primary + 4^4x{k} cascaded) needs {smallest} bytes "
            f"(max ratio {uncompressed_bytes(image_shape) / smallest:.1f}); details: {e}") from None


def pca_init(flipped: np.ndarray, n_primary: int, n_cascaded: int):
    """A starting point drawn from the image itself: its colours' principal axes. The cascaded
    array starts as the affine map from a 4D point to mean + sum_i p_i-scaled axis i (exact under
    multilinear interpolation), and the primary as the image's coordinates on those axes,
    box-filtered to its cells, so step 0 already decodes the image at the primary's resolution
    (the paper starts from the uv ramp and a constant cascade, which at 1K spends most of a CPU
    budget unfolding the ramp). Primary channels past the image's component count keep the
    ramp (the cascade is constant along them). `flipped` is [H, W, k], row 0 at v = 0.
    Returns (primary table [N_p, N_p, 4], cascaded table [N_c]*4 + [k]) in F's range."""
    h, w, k = flipped.shape
    x = torch.from_numpy(flipped.reshape(-1, k).astype(np.float64))
    mean = x.mean(0)
    d = x - mean
    values, vectors = torch.linalg.eigh(d.T @ d / len(d))
    axes = vectors[:, torch.argsort(values, descending=True)][:, :min(k, 4)]     # [k, n]
    z = d @ axes                                                                     # [H*W, n]
    lo, hi = z.min(0).values, z.max(0).values
    span = torch.where(hi > lo, hi - lo, torch.ones_like(hi))
    coords = ((z - lo) / span).reshape(h, w, -1).float()
    n = coords.shape[-1]
    primary = di._ramp([n_primary] * 2, 4)
    pts = di.grid_points([n_primary] * 2).reshape(-1, 2)
    taps = max(1, min(4, math.ceil(w / max(n_primary - 1, 1))))
    offs = ((torch.arange(taps, dtype=torch.float32) + 0.5) / taps - 0.5) / max(n_primary - 1, 1)
    acc = 0.0
    for dx in offs:
        for dy in offs:
            acc = acc + di.bilinear(coords, (pts + torch.stack([dx, dy])).clamp(0, 1))
    primary[..., :n] = (acc / taps ** 2).reshape(n_primary, n_primary, n)
    grid = di.grid_points([n_cascaded] * 4).double()                                # [..., 4]
    cascaded = mean + (lo + grid[..., :n] * span) @ axes.T
    return primary.float(), cascaded.float()


INITS = ("ramp", "pca")   # the paper's uv ramp + mean-colour cascade, or `pca_init`


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
             finish_optimizer: str = DEFAULTS["finish_optimizer"], init: str = DEFAULTS["init"],
             decode: bool | None = None, measure: Callable[[object, np.ndarray, bool], dict] | None = None,
             provenance: dict | None = None, name: str = KIND, kind: str = KIND, progress: bool | None = None,
             device=None) -> Result:
    """Compress `image` (anything `prepare_image` accepts, e.g. uint8 [H, W, 3]) by `ratio`.
    Returns the Result with an exported 8-bit bundle whose metrics hold the sizes, the training
    time and PSNR (sRGB 8-bit) in torch, and what `measure(bundle, image, decoded)` adds (e.g. the
    GLSL-decoded PSNR; the bundle is exported again with them). `decode` (default: for 1 or 3 channels) appends the sRGB -> linear decode.
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
    if init == "pca":
        primary, cascaded = pca_init(flipped, sizing.n_primary, sizing.n_cascaded)
        inits = dict(primary_init="tensor", primary_init_args={"values": primary},
                     cascaded_init="tensor", cascaded_init_args={"values": cascaded})
    else:
        inits = dict(cascaded_init="mean", cascaded_init_args={"target": image.reshape(-1, k)})
    core = di.cascade(2, k, sizing.n_primary, sizing.n_cascaded, redundant=2, **inits,
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
                               bounds={"cascaded": CASCADED_RANGE} if CASCADED_RANGE else None,
                               finish=(finish_at, on_device(di.mixed_sampler(flipped, batch, seed=seed + 1), device),
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
        "history": history_rows(history.records, "psnr", 3),
    }
    prov = {
        "technique": "Differentiable Indirection texture compression (Datta et al. 2023), 2D primary "
                     "(4 ch, triangle F) -> 4D cascaded (k ch); 8-bit arrays",
        "training": f"{init} start; Adam lr {lr:g}, {schedule} schedule, batch {batch}, {steps} steps, "
                    f"seed {seed}: {finish_at} steps on stratified uv (one stratum per texel) with bilinear "
                    f"targets and L1, then {steps - finish_at} with the squared error"
                    + (" by full-batch L-BFGS on the texel centres (as many samples as those steps' batches)"
                       if lbfgs else " on batches of half texel centres, half stratified points"),
        "colour": "arrays hold sRGB-encoded values; the graph decodes to linear (sRGB EOTF tables)"
                  if decode else "arrays hold the channel values as given (no colour decode)",
        "uv_convention": "uv (0,0) = bottom-left of the picture, (1,1) = top-right; pixel centres",
        "notes": notes, "torch": torch.__version__, "device": str(device),
        **recorded_at(),
    }
    prov.update(provenance or {})
    render = {"program": FIELD_PROGRAM, "width": w, "height": h, "input": "uv",
              "output": graph.outputs[0][0]} if decode else None
    bundle = graph.export(kind, name, provenance=prov, metrics=metrics, render=render)
    if measure is not None:
        metrics.update(measure(bundle, image, decode))
        bundle = graph.export(kind, name, provenance=prov, metrics=metrics, render=render)
    return Result(graph, bundle, history, image, metrics)


