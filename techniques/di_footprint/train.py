"""Footprint-aware texture sampler with Differentiable Indirection, no mip chain stored
(Differentiable Indirection, Datta et al. 2023 §4.2.2 and supp. 1.4).

Graph (the bundle, kind ``di_footprint``): inputs ``uv`` (2, in [0, 1], the fract of a tiled
uv) and ``log2_footprint`` (1: log2 of the pixel footprint in uv units, see below).

    uv             -> primary      2D N_p0^2, 3 channels, (u, v, u) ramp, triangle F
    log2_footprint -> lod          dense 1 -> 1, fixed: x_f = (log2_footprint + log2 N) / L
                   -> lod_primary  1D N_p1 = 4 N_lod, 1 channel, identity ramp, triangle F
    [primary, lod_primary] -> cascaded  4D N_c x N_c x N_c x N_lod, k channels (LOD is axis 3,
                   the slice-block axis of the packed 3D texture: two fetches and a mix, the
                   analogue of trilinear's lerp between two mip levels)
    cascaded -> sRGB decode (texture_compression.decode_nodes) -> ``rgb`` (linear)

Footprint convention (one formula for training, the emulated sampler and the shader):
``log2_footprint = log2(max(|duv/dx|, |duv/dy|))``, the isotropic max-axis rule of GL's
trilinear LOD (GL 4.6 §8.14.1, rho = max of the two scaled derivative lengths), so the GL
mip level is ``lambda = log2_footprint + log2 N`` for an N x N base texture. The fixed ``lod``
node divides lambda by L = log2 N (the coarsest level), so x_f = 0 is the base level and 1 the
1x1 level; the lookup clamps x_f to [0, 1] exactly as GL clamps lambda to [0, L] (magnification
= level 0). The paper takes |duv/dx x duv/dy| (an area); the max-axis length is what the
emulated GL sampler uses, so the network and its target agree on what "footprint" means.
Keeping N inside the bundle makes the shader texture-size agnostic.

N_lod = L + 1: with the identity ramp in lod_primary each cascaded LOD slice starts exactly on
one mip level (paper: N_lod ~ log2 N_base, then tuned).

Training data (paper supp. 1.4): uv stratified (one jittered sample per texel, per epoch); the
linear footprint x = u^n, u ~ U(0, 1), n = log_p(1 / N) with p = 0.5 (half the samples in LOD 0),
i.e. log2_footprint = n log2 u. Target: ``emulated_trilinear`` -- the box-filtered mip chain
(2x2 means, each level rounded to 8 bits like an RGB8 texture's), bilinear in two levels
(GL_REPEAT wrap, texel centres at (i + 0.5) / n) mixed by the fractional LOD, i.e.
GL_LINEAR_MIPMAP_LINEAR. Colour as techniques/di_texture/train.py: arrays hold sRGB-encoded
values (filtering happens on the encoded values, as for an RGB8 texture); the graph decodes.

    from inshade.techniques.di_footprint import train as fp
    image, notes, source = fp.load_texture("skimage:astronaut", 256)
    result = fp.train_sampler(image, ratio=6)
    fp.write_asset(result, "/tmp/di_assets/di_footprint")

Command: ``inshade train di_footprint --out DIR [--preset quick|ship]``. ``--preset ship`` is exactly
what built trained/di_footprint (3000 steps); ``quick`` (the default) trains 1500; DIR/metrics.json
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
from inshade import asset_folder, command
from inshade.devices import DeviceError, add_device_argument, resolve_device
from inshade.metrics import srgb_eotf
from inshade.models import indirection as di
from inshade.techniques.di_texture import train as tc
from inshade.models.graph import GraphModule
from inshade.models.mlp import Dense

KIND = "di_footprint"
RENDER_PROGRAM = "passes/footprint_plane.frag"
PRIMARY_CHANNELS = 3
LOD_OVERSAMPLE = 4            # N_p1 = 4 N_lod (paper)
P_LOD0 = 0.5                  # fraction of training samples in LOD 0 (paper)
MIN_SIZE = 8
# Comparison modes of passes/footprint_plane.frag (FOOTPRINT_MODE); mirrored there as constants.
MODES = {"di": 0, "trilinear": 1, "anisotropic": 2, "bilinear": 3, "explicit_lod": 4}
DEFAULTS = dict(image="skimage:astronaut", size=256, ratio=6.0, n_cascaded=8, steps=1500, lr=1e-2,
                batch=16384, schedule="cosine", seed=0, threads=1)
# --preset: "ship" is what built trained/di_footprint; "quick" keeps the 1500-step default.
PRESETS = {"quick": dict(steps=1500), "ship": dict(steps=3000)}
SETTINGS = ("image", "size", "ratio", "n_cascaded", "steps", "lr", "batch", "schedule", "seed")


def preset_settings(preset: str, asset: str | None = None) -> dict:
    """The settings ``--preset PRESET`` resolves to with no other option (one asset: ``asset`` is ignored)."""
    return {k: PRESETS[preset].get(k, DEFAULTS[k]) for k in SETTINGS}


# threads = 1: on the shared 2-core machines torch's intra-op threads spin against each other and
# against other processes; one thread measured ~10x faster per step (0.045 s vs 0.46 s at load 4).


class FootprintError(tc.CompressionError):
    """A texture or setting the footprint sampler cannot use; the message says what to change."""


# ---------------------------------------------------------------------------------------------
# the emulated GL trilinear sampler (training targets)

def levels(size: int) -> int:
    """L = log2 N: the index of the 1x1 mip level of an N x N (power-of-two) texture."""
    return int(round(math.log2(size)))


def mip_chain(image: torch.Tensor, round_bits: int | None = 8) -> list[torch.Tensor]:
    """[N, N, C] power-of-two -> [level 0 .. level L]: each level the 2x2 box mean of the one
    before (glGenerateMipmap's filter for power-of-two sizes), rounded to `round_bits` as an RGB8
    texture stores it (None: keep float)."""
    chain = [image.float()]
    q = float((1 << round_bits) - 1) if round_bits else None
    while chain[-1].shape[0] > 1:
        a = chain[-1]
        h, w, c = a.shape
        m = a.reshape(h // 2, 2, w // 2, 2, c).mean((1, 3))
        chain.append(torch.round(m * q) / q if q else m)
    return chain


def bilinear_repeat(image: torch.Tensor, uv: torch.Tensor) -> torch.Tensor:
    """GL_LINEAR with GL_REPEAT: texel (i, j) centred at ((j + 0.5) / W, (i + 0.5) / H), u along
    the width, v along the rows. image [H, W, C], uv [B, 2] (any real values)."""
    h, w = image.shape[:2]

    def axis(t, n):
        p = t * n - 0.5
        i0 = torch.floor(p)
        f = (p - i0)[:, None]
        i0 = i0.long()
        return torch.remainder(i0, n), torch.remainder(i0 + 1, n), f

    x0, x1, fx = axis(uv[:, 0], w)
    y0, y1, fy = axis(uv[:, 1], h)
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bot = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return top * (1 - fy) + bot * fy


def gl_lod(log2_footprint: torch.Tensor, size: int) -> torch.Tensor:
    """GL's lambda for a max-axis footprint of 2^log2_footprint uv units on an N x N texture,
    clamped to [0, L] (below 0 GL magnifies from level 0)."""
    return (log2_footprint + math.log2(size)).clamp(0.0, float(levels(size)))


def emulated_trilinear(chain: list[torch.Tensor], uv: torch.Tensor, log2_footprint: torch.Tensor) -> torch.Tensor:
    """GL_LINEAR_MIPMAP_LINEAR: bilinear in levels floor(lambda) and floor(lambda) + 1, mixed by
    the fraction. chain from `mip_chain`, uv [B, 2], log2_footprint [B]."""
    lam = gl_lod(log2_footprint.reshape(-1), chain[0].shape[0])
    top = len(chain) - 1
    l0 = torch.floor(lam).clamp(max=top).long()
    l1 = (l0 + 1).clamp(max=top)
    f = (lam - l0.float())[:, None]
    flat, offsets = _packed(chain)
    return (1 - f) * _bilinear_levels(flat, offsets, uv, l0, top) + f * _bilinear_levels(flat, offsets, uv, l1, top)


def _packed(chain):
    """All levels in one [sum n^2, C] table (one gather for any mix of levels) + level offsets."""
    flat = torch.cat([c.reshape(-1, c.shape[-1]) for c in chain])
    offsets = torch.tensor(np.cumsum([0] + [c.shape[0] * c.shape[1] for c in chain[:-1]]), device=flat.device)
    return flat, offsets


def _bilinear_levels(flat, offsets, uv, level, top):
    """`bilinear_repeat` of level `level[b]` (a square of side 2^(top - level)) for each sample."""
    n = torch.bitwise_left_shift(torch.ones_like(level), top - level)
    nf = n.float()

    def axis(t):
        p = t * nf - 0.5
        i0 = torch.floor(p)
        f = (p - i0)[:, None]
        i0 = i0.long()
        return torch.remainder(i0, n), torch.remainder(i0 + 1, n), f

    x0, x1, fx = axis(uv[:, 0])
    y0, y1, fy = axis(uv[:, 1])
    base = offsets[level]

    def at(y, x):
        return flat[base + y * n + x]

    top_row = at(y0, x0) * (1 - fx) + at(y0, x1) * fx
    bottom = at(y1, x0) * (1 - fx) + at(y1, x1) * fx
    return top_row * (1 - fy) + bottom * fy


def footprint_exponent(size: int, p: float = P_LOD0) -> float:
    """n = log_p(t), t = 1 / N: x = u^n puts a fraction p of the samples at footprints <= one
    texel (LOD 0); p = 0.5 gives n = log2 N (paper supp. Eq. 5-8)."""
    return math.log(1.0 / size) / math.log(p)


def sample_log2_footprint(n: int, size: int, gen: torch.Generator, device=None) -> torch.Tensor:
    """The paper's footprint distribution as log2 of the linear footprint in uv units:
    x = u^n  =>  log2 x = n log2 u. Drawn on `gen` (a CPU generator), computed on `device`."""
    u = torch.rand(n, generator=gen).to(device).clamp_min(1e-12)
    return footprint_exponent(size) * torch.log2(u)


def footprint_sampler(image: torch.Tensor, batch: int, seed: int = 0, chain=None):
    """Endless (x [B, 3] = (u, v, log2_footprint), target [B, C]) batches: stratified uv (one
    jittered sample per texel per epoch, as indirection.image_sampler), the paper's footprint
    distribution, targets from `emulated_trilinear`. image [N, N, C] with row 0 at v ~ 0.
    Random numbers come from a seeded CPU generator (the same on every device); the batches are
    computed on the device `chain` (default: `image`) lives on."""
    chain = mip_chain(image) if chain is None else chain
    device = chain[0].device
    size = image.shape[0]
    gen = torch.Generator().manual_seed(seed)
    n = size * size
    while True:
        order = torch.randperm(n, generator=gen)
        for start in range(0, n, batch):
            idx = order[start:start + batch].to(device)
            jitter = torch.rand(len(idx), 2, generator=gen).to(device)
            uv = torch.stack([(idx % size + jitter[:, 0]) / size, (idx // size + jitter[:, 1]) / size], -1)
            lf = sample_log2_footprint(len(idx), size, gen, device)
            yield torch.cat([uv, lf[:, None]], -1), emulated_trilinear(chain, uv, lf)


def held_out_set(image: torch.Tensor, n: int = 65536, seed: int = 12345, chain=None):
    """(x, target) from the training distribution with an independent seed (uniform uv), on the
    device of `chain` (default: of `image`)."""
    chain = mip_chain(image) if chain is None else chain
    gen = torch.Generator().manual_seed(seed)
    uv = torch.rand(n, 2, generator=gen).to(chain[0].device)
    lf = sample_log2_footprint(n, image.shape[0], gen, chain[0].device)
    return torch.cat([uv, lf[:, None]], -1), emulated_trilinear(chain, uv, lf)


def lod_sets(image: torch.Tensor, n: int = 8192, seed: int = 777, chain=None):
    """{level: (x, target)} at each integer GL level 0..L with uniform uv (PSNR per level)."""
    chain = mip_chain(image) if chain is None else chain
    size = image.shape[0]
    gen = torch.Generator().manual_seed(seed)
    out = {}
    for level in range(levels(size) + 1):
        uv = torch.rand(n, 2, generator=gen).to(chain[0].device)
        lf = torch.full((n,), float(level) - math.log2(size), device=chain[0].device)
        out[level] = (torch.cat([uv, lf[:, None]], -1), emulated_trilinear(chain, uv, lf))
    return out


# ---------------------------------------------------------------------------------------------
# sizing and the graph

@dataclass(frozen=True)
class Sizing:
    n_primary: int      # N_p0 (multiple of 8)
    n_footprint: int    # N_p1 = 4 N_lod
    n_cascaded: int     # N_c (multiple of 4)
    n_lod: int          # L + 1
    channels: int
    bytes: int          # cells: 3 N_p0^2 + N_p1 + k N_c^3 N_lod (paper supp. Eq. 4)
    budget: float

    @property
    def rho(self) -> float:
        return self.n_primary / self.n_cascaded


def texture_bytes(size: int, channels: int, mips: bool = True) -> int:
    """Bytes of an RGB8-style texture (k bytes a texel), with its full mip chain or base only."""
    total, s = 0, size
    while True:
        total += s * s * channels
        if s == 1 or not mips:
            return total
        s //= 2


def plan(size: int, channels: int, ratio: float, n_cascaded: int = DEFAULTS["n_cascaded"]) -> Sizing:
    """Arrays for a budget of (N^2 k bytes) / ratio -- the ratio against the base level alone,
    as the paper counts it; the mip chain the sampler replaces adds another third. N_c is given
    (multiple of 4); N_p0 is the largest multiple of 8 that fits."""
    if size < MIN_SIZE or size & (size - 1):
        raise FootprintError(f"texture size {size}: must be a power of two >= {MIN_SIZE} (a full mip "
                             "chain halves to 1x1); pass --size 256")
    if not (isinstance(ratio, (int, float)) and math.isfinite(ratio) and ratio >= 1.0):
        raise FootprintError(f"ratio must be a number >= 1, got {ratio!r}")
    if n_cascaded < 4 or n_cascaded % 4:
        raise FootprintError(f"n_cascaded must be a multiple of 4 (>= 4), got {n_cascaded}")
    n_lod = levels(size) + 1
    n_fp = LOD_OVERSAMPLE * n_lod
    budget = size * size * channels / float(ratio)
    cascaded = n_cascaded ** 3 * n_lod * channels
    side = int(math.floor(math.sqrt(max(budget - cascaded - n_fp, 0) / PRIMARY_CHANNELS) / 8)) * 8
    if side < 8:
        need = PRIMARY_CHANNELS * 64 + n_fp + cascaded
        raise FootprintError(f"ratio {ratio:g} cannot be met for a {size}x{size}x{channels} texture with "
                             f"N_c = {n_cascaded}: the budget is {int(budget)} bytes and the smallest sampler "
                             f"(8x8x3 primary + {n_fp} footprint cells + {n_cascaded}^3x{n_lod}x{channels} "
                             f"cascaded) needs {need} (lower --ratio or --n-cascaded)")
    total = PRIMARY_CHANNELS * side * side + n_fp + cascaded
    return Sizing(side, n_fp, n_cascaded, n_lod, channels, total, budget)


def lod_node(size: int) -> Dense:
    """The fixed affine map log2_footprint -> x_f = (log2_footprint + log2 N) / L."""
    L = float(levels(size))
    d = Dense(1, 1, bias=True)
    with torch.no_grad():
        d.linear.weight.fill_(1.0 / L)
        d.linear.bias.fill_(math.log2(size) / L)
    for p in d.parameters():
        p.requires_grad_(False)
    return d


def sampler_graph(size: int, sizing: Sizing, mean) -> GraphModule:
    """The trainable core (no colour decode): output ``values`` = sRGB-encoded channels."""
    k = sizing.channels
    g = GraphModule([("uv", 2, "uv"), ("log2_footprint", 1, "log2_footprint_uv")])
    g.add("primary", di.make_array([sizing.n_primary] * 2, PRIMARY_CHANNELS, init="ramp", bits=8,
                                   nonlinearity="triangle"), "uv")
    g.add("lod", lod_node(size), "log2_footprint")
    g.add("lod_primary", di.make_array([sizing.n_footprint], 1, init="ramp", bits=8, nonlinearity="triangle"),
          "lod")
    g.add("cascaded", di.make_array([sizing.n_cascaded] * 3 + [sizing.n_lod], k, init="mean", bits=8,
                                    target=np.asarray(mean, np.float32).reshape(1, k)),
          ["primary", "lod_primary"])
    g.output("values", "cascaded", "generic")
    return g


def export_graph(core: GraphModule, channels: int) -> GraphModule:
    """The bundle graph: the trained arrays, then the sRGB decode to linear (k = 1 or 3)."""
    g = GraphModule(core.inputs)
    for name in ("primary", "lod", "lod_primary", "cascaded"):
        g.add(name, core.nodes[name], core.wiring[name])
    out = tc.decode_nodes(g, "cascaded", channels)
    g.output("rgb" if channels == 3 else "grey", out, "linear_rgb" if channels == 3 else "linear")
    for p in g.parameters():
        p.requires_grad_(False)
    return g


# ---------------------------------------------------------------------------------------------
# input

def load_texture(spec: str, size: int | None = DEFAULTS["size"]):
    """(image float32 [N, N, k] sRGB-encoded, row 0 = top; notes; source) from a file or
    skimage:NAME, centre-cropped and resized to `size` (a power of two) when given."""
    image, notes, source = tc.load_image(spec, size)
    if image.shape[2] not in (1, 3):
        raise FootprintError(f"{spec}: {image.shape[2]} channels; the footprint sampler decodes colour "
                             "(1 grey or 3 RGB channels)")
    n = image.shape[0]
    if n & (n - 1):
        raise FootprintError(f"{spec}: {n}x{n} is not a power of two (a full mip chain halves to 1x1); "
                             "pass --size 256")
    return image, notes, source


def texture_tensor(image: np.ndarray) -> torch.Tensor:
    """Image orientation (row 0 = top) -> texture orientation (row 0 at v ~ 0, the bottom)."""
    return torch.from_numpy(np.ascontiguousarray(image[::-1], dtype=np.float32))


# ---------------------------------------------------------------------------------------------
# train

@dataclass
class Result:
    graph: GraphModule          # bundle graph
    bundle: object              # inshade.bundle.Bundle (8-bit arrays)
    history: di.History
    image: np.ndarray           # [N, N, k] sRGB-encoded, row 0 = top
    sizing: Sizing
    metrics: dict = field(default_factory=dict)


def quantised_metrics(bundle, image: np.ndarray) -> dict:
    """PSNR (encoded values, peak 1) of the exported (8-bit) sampler vs the emulated trilinear
    sampler: on held-out samples of the training distribution and at each integer LOD."""
    tex = texture_tensor(image)
    chain = mip_chain(tex)
    g = GraphModule.from_bundle(bundle)
    core = _encoded_output(g)
    x, y = held_out_set(tex, chain=chain)
    with torch.no_grad():
        out = {"psnr_heldout": round(di.psnr(core(x), y), 4)}
        per = {}
        for level, (xl, yl) in lod_sets(tex, chain=chain).items():
            per[str(level)] = round(di.psnr(core(xl), yl), 3)
    out["psnr_per_lod"] = per
    return out


def _encoded_output(g: GraphModule) -> GraphModule:
    """A view of a bundle graph that stops at the cascaded array (sRGB-encoded values)."""
    core = GraphModule(g.inputs)
    for name in ("primary", "lod", "lod_primary", "cascaded"):
        core.add(name, g.nodes[name], g.wiring[name])
    core.output("values", "cascaded")
    return core


def train_sampler(image: np.ndarray, ratio: float = DEFAULTS["ratio"], *,
                  n_cascaded: int = DEFAULTS["n_cascaded"], steps: int = DEFAULTS["steps"],
                  lr: float = DEFAULTS["lr"], batch: int = DEFAULTS["batch"],
                  schedule: str = DEFAULTS["schedule"], seed: int = DEFAULTS["seed"],
                  threads: int | None = DEFAULTS["threads"], provenance: dict | None = None, name: str = KIND,
                  progress: bool | None = None, device=None) -> Result:
    """Train the footprint sampler on `image` ([N, N, k] sRGB-encoded in [0, 1], N a power of
    two, k 1 or 3) against the emulated trilinear sampler; export at 8 bits. `threads`: torch
    intra-op threads while training (None: leave as is). `device` (default the CPU): where the
    training and its data (mip chain, targets) live; the export and its metrics are on the CPU."""
    device = torch.device("cpu") if device is None else torch.device(device)
    prev = torch.get_num_threads()
    if threads:
        torch.set_num_threads(int(threads))
    try:
        return _train(image, ratio, n_cascaded, steps, lr, batch, schedule, seed, provenance, name, progress, device)
    finally:
        torch.set_num_threads(prev)


def _train(image, ratio, n_cascaded, steps, lr, batch, schedule, seed, provenance, name, progress,
           device) -> Result:
    image = np.asarray(image, np.float32)
    if image.ndim != 3 or image.shape[0] != image.shape[1] or image.shape[2] not in (1, 3):
        raise FootprintError(f"image: expected [N, N, 1 or 3], got shape {image.shape}")
    size, k = image.shape[0], image.shape[2]
    sizing = plan(size, k, ratio, n_cascaded)
    tex = texture_tensor(image).to(device)
    chain = mip_chain(tex)
    torch.manual_seed(seed)
    core = sampler_graph(size, sizing, image.reshape(-1, k).mean(0)).to(device)
    eval_set = held_out_set(tex, 16384, seed=seed + 1, chain=chain)
    t0 = time.perf_counter()
    history = di.train_cascade(core, footprint_sampler(tex, batch, seed, chain), steps, lr=lr,
                               schedule=schedule, seed=seed, eval_set=eval_set, progress=progress, desc=name)
    seconds = time.perf_counter() - t0
    core = core.to("cpu")       # export and metrics on the CPU
    graph = export_graph(core, k)
    prov = {
        "technique": "Differentiable Indirection footprint-aware texture sampler (Datta et al. 2023, "
                     "supp. 1.4): 2D primary (3 ch, (u,v,u) ramp) + 1D footprint primary (4 N_lod) -> "
                     "4D cascaded N_c^3 x N_lod; triangle F; 8-bit arrays; no mip chain stored",
        "footprint": "input log2_footprint = log2(max(|duv/dx|, |duv/dy|)) in uv units (GL's isotropic "
                     "max-axis LOD rule); node 'lod' maps it to (log2_footprint + log2 N) / log2 N",
        "training": f"stratified uv, footprint x = u^n (n = log2 N, half the samples in LOD 0), targets "
                    f"from the emulated GL trilinear sampler (box mip chain rounded to 8 bits, GL_REPEAT); "
                    f"L1, Adam lr {lr:g}, {schedule}, batch {batch}, {steps} steps, seed {seed}",
        "colour": "arrays hold sRGB-encoded values; the graph decodes to linear (sRGB EOTF tables)",
        "uv_convention": "uv (0,0) = bottom-left of the picture; the shader passes fract(tiled uv)",
        "torch": torch.__version__, "device": str(device),
        "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }
    prov.update(provenance or {})
    metrics = {
        "size": size, "channels": k, "ratio_requested": float(ratio),
        "bytes": sizing.bytes, "bytes_with_headers": sizing.bytes + 8 * (PRIMARY_CHANNELS + 1 + k),
        "texture_bytes_base": texture_bytes(size, k, False), "texture_bytes_mips": texture_bytes(size, k, True),
        "ratio_vs_base": round(texture_bytes(size, k, False) / sizing.bytes, 4),
        "ratio_vs_mip_chain": round(texture_bytes(size, k, True) / sizing.bytes, 4),
        "n_primary": sizing.n_primary, "n_footprint": sizing.n_footprint, "n_cascaded": sizing.n_cascaded,
        "n_lod": sizing.n_lod, "rho": round(sizing.rho, 4),
        "train_seconds": round(seconds, 2), "steps": steps,
        "psnr_step0": round(history.records[0]["psnr"], 4), "psnr_float": round(history.final["psnr"], 4),
        "history": [{"step": r["step"], "psnr": round(r["psnr"], 3), "seconds": round(r["seconds"], 2)}
                    for r in history.records],
    }
    bundle = graph.export(KIND, name, provenance=prov, metrics=metrics)
    metrics.update(quantised_metrics(bundle, image))
    bundle = graph.export(KIND, name, provenance=prov, metrics=metrics)
    return Result(graph, bundle, history, image, sizing, metrics)


# ---------------------------------------------------------------------------------------------
# asset folder

# A grazing view of the tiled ground plane (y = 0): eye 0.3 above it, looking 8 degrees down.
CAMERA = {"type": "fly", "position": [0.0, 0.3, 0.0], "yaw": 0.0, "pitch": -8.0, "fov_y": 50.0,
          "near": 0.05, "far": 100.0}
TILE = 1.0                    # world units per texture tile
EXTENT = 16.0                 # the plane is |x|, |z| <= EXTENT (a finite square: see lib/footprint.glsl)


def scene_dict(name: str, title: str, output: str, size=(512, 256), gl_modes: bool = False) -> dict:
    """The asset's scene. `gl_modes` adds the GL comparison modes (a FOOTPRINT_MODE define and the
    uncompressed texture bound as u_texture / u_texture_aniso): it needs scene.json "textures"
    support in runtime/scene.py + runtime/renderer.py, which the shipped renderer lacks (the report
    of this module's author carries the diff); without it the scene shows the DI sampler only."""
    scene = {
        "format": "inshade.scene", "version": 1, "name": name, "title": title,
        "program": RENDER_PROGRAM, "size": list(size),
        "networks": [{"bundle": ".", "prefix": "net", "output": output}],
        "camera": CAMERA,
        "bookmarks": {
            "grazing": CAMERA,
            "steeper": {**CAMERA, "position": [0.0, 0.6, 0.0], "pitch": -25.0},
            "horizon": {**CAMERA, "position": [0.0, 0.15, 0.0], "pitch": -3.0},
        },
        "lights": [], "environment": None,
        "display": {"mode": "final", "modes": ["final", "network"], "split": 0.5},
        "settings": {
            "exposure": {"type": "float", "default": 1.0, "min": 0.0, "max": 8.0, "uniform": "u_exposure",
                         "label": "exposure"},
            "extent": {"type": "float", "default": EXTENT, "min": 0.5, "max": 1000.0, "uniform": "u_extent",
                       "label": "plane half-size (world units)"},
            "tile": {"type": "float", "default": TILE, "min": 0.05, "max": 20.0, "uniform": "u_tile",
                     "label": "tile size (world units)"},
            "lut_filter": {"type": "choice", "default": "exact", "choices": ["exact", "fast"],
                           "codegen": "lut_filter", "label": "LUT filtering"},
        },
        "requires": {"gl": 330},
        "notes": "DI footprint sampler only: the GL trilinear / anisotropic / no-mip comparison modes of "
                 "the same pass need the uncompressed texture bound (inshade bench di_footprint renders them)",
    }
    if gl_modes:
        scene["textures"] = [{"uniform": "u_texture", "image": "texture.png", "mipmaps": True},
                             {"uniform": "u_texture_aniso", "image": "texture.png", "mipmaps": True,
                              "anisotropy": 16.0}]
        scene["settings"]["mode"] = {"type": "choice", "default": MODES["di"], "choices": sorted(MODES.values()),
                                     "define": "FOOTPRINT_MODE", "label": "sampler: " + ", ".join(
                                         f"{v} {k}" for k, v in MODES.items())}
        scene["notes"] = "--set mode=N: " + ", ".join(f"{v} {k}" for k, v in MODES.items())
        names = {"di": "DI footprint sampler", "trilinear": "GL trilinear (mip chain)",
                 "anisotropic": "GL anisotropic 16x", "bilinear": "GL bilinear (no mips)",
                 "explicit_lod": "GL explicit LOD"}
        scene["labels"] = [{"text": names.get(k, k), "at": [0.02, 0.95], "align": "left", "when": {"mode": v}}
                           for k, v in MODES.items()]
    return scene


def write_asset(result: Result, out, title: str | None = None, preview_size=(512, 256),
                gl_modes: bool = False) -> Path:
    """bundle.json + weights.safetensors + scene.json + texture.png (the 8-bit source) +
    preview.png (the scene rendered through the GL driver, DI mode)."""
    from inshade.runtime.image_io import write_png

    out = Path(out)
    result.bundle.save(out)
    output = result.graph.outputs[0][0]
    title = title or f"DI footprint sampler, {result.metrics['ratio_vs_base']:.1f}x vs RGB8 (no mip chain)"
    atomic_write(out / "scene.json", json.dumps(scene_dict(out.name, title, output, preview_size, gl_modes), indent=2) + "\n")
    src = result.image if result.image.shape[2] == 3 else np.repeat(result.image, 3, -1)
    write_png(out / "texture.png", srgb_eotf(src))
    from inshade.runtime.renderer import SceneRenderer
    from inshade.runtime.scene import load_scene

    scene = load_scene(out)
    r = SceneRenderer(scene)
    try:
        r.render(scene.make_camera(), *preview_size)
        write_png(out / "preview.png", r.read()[..., :3])
    finally:
        r.release()
    return out


# ---------------------------------------------------------------------------------------------
# command line

def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    d = DEFAULTS
    p.add_argument("--image", default=d["image"], help="image file or skimage:NAME (default %(default)s)")
    asset_folder.add_arguments(p, "di_footprint")
    p.add_argument("--size", type=int, default=d["size"], help="centre-crop and resize to SIZE^2, a power of two")
    p.add_argument("--ratio", type=float, default=d["ratio"], help="compression vs the RGB8 base level")
    p.add_argument("--n-cascaded", type=int, default=d["n_cascaded"], help="N_c (multiple of 4)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="quick",
                   help="ship: exactly what built trained/di_footprint (3000 steps); quick: 1500 steps; "
                        "options given explicitly override it (default %(default)s)")
    p.add_argument("--steps", type=int, help="training steps (default: the preset's)")
    p.add_argument("--lr", type=float, default=d["lr"])
    p.add_argument("--batch", type=int, default=d["batch"])
    p.add_argument("--schedule", choices=sorted(di.SCHEDULES), default=d["schedule"])
    p.add_argument("--seed", type=int, default=d["seed"])
    p.add_argument("--threads", type=int, default=d["threads"], help="torch threads while training (0: torch's default)")
    p.add_argument("--title", help="scene title")
    add_device_argument(p)
    return p


def run(args, argv=None) -> int:
    device = resolve_device(args.device)     # first: a missing CUDA device fails before any work
    args.out = str(asset_folder.claim(args.out, "di_footprint", force=args.force))
    if args.steps is None:
        args.steps = PRESETS[args.preset]["steps"]
    if args.steps < 0 or args.batch < 1:
        raise FootprintError("--steps must be >= 0 and --batch >= 1")
    image, notes, source = load_texture(args.image, args.size)
    for n in notes:
        print(f"inshade: note: {n}", file=sys.stderr)
    argv = list(sys.argv[1:] if argv is None else argv)
    command = shlex.join(["inshade", "train", "di_footprint", *argv])
    result = train_sampler(image, args.ratio, n_cascaded=args.n_cascaded, steps=args.steps, lr=args.lr,
                           batch=args.batch, schedule=args.schedule, seed=args.seed, threads=args.threads or None,
                           name=Path(args.out).name, device=device,
                           provenance={"command": command, "image": source, "image_notes": notes})
    out = write_asset(result, args.out, args.title)
    m = result.metrics
    # metrics.json: the preset, the settings it resolved to (tests/test_presets.py holds the shipped
    # asset's equal to preset_settings("ship")) and the bundle's metrics without the loss history
    settings = {k: getattr(args, k) for k in SETTINGS}
    atomic_write(out / "metrics.json", json.dumps({"command": command, "preset": args.preset, "settings": settings,
                                                   **{k: v for k, v in m.items() if k != "history"}},
                                                  indent=1) + "\n")
    print(f"wrote {out}: {m['bytes']} bytes ({m['ratio_vs_base']:.2f}x vs RGB8, {m['ratio_vs_mip_chain']:.2f}x vs "
          f"RGB8 + mips; N_p0 {m['n_primary']}, N_p1 {m['n_footprint']}, N_c {m['n_cascaded']}, N_lod {m['n_lod']}), "
          f"held-out PSNR vs emulated trilinear {m['psnr_heldout']:.2f} dB (8-bit arrays), {m['train_seconds']:.1f} s")
    return 0


def main(argv=None) -> int:
    return command.main("inshade train di_footprint", __doc__, add_arguments, run, argv, errors=(DeviceError,))

