"""Training machinery for Differentiable Indirection cascades (Datta et al. 2023).

A cascade is a `GraphModule` of `LookupArray` nodes: one (or more) *primary* arrays looked up
with the input coordinate, whose outputs (wrapped into [0, 1] by a periodic F) are the
coordinate of a *cascaded* array that returns the output. This module adds what training one
needs; the primitive itself, its export (F baked into the cells, 8/16/32-bit quantisation) and
its GLSL live in `components/lookup_array/`. The training loop, its schedules, losses
and stability tools live in `models/indirection_training.py` and are importable from here.

    sizing = size_cascade(budget, rho=64, primary_dims=2, primary_channels=4,
                          cascaded_dims=4, cascaded_channels=3)
    g = cascade(2, 3, sizing.n_primary, sizing.n_cascaded, redundant=2,
                cascaded_init="mean", cascaded_init_args={"target": image})
    history = train_cascade(g, image_sampler(image, 8192), steps=2000,
                            eval_set=image_eval_set(image))
    print(evaluate_quantised(g, 8, *image_eval_set(image)))
    g.export("di_texture").save("trained/...")

Pieces, each a table where there is a choice (no if-chains):

- `INITS`: named initialisations (paper §1.3) giving the *table* values F(cells); `make_array`
  inverts F so that e.g. a constant 0.3 under a sinusoid F reads back as 0.3.
- `size_cascade`: ρ = N_p / N_c sizing for a byte budget (paper §1.4).
- `train_cascade`: L1 loss (the paper's; or `LOSSES["mse"]`), Adam (lr 1e-3), `SCHEDULES`,
  per-eval PSNR history, primary-array gradient clipping (`CLIPPERS`), the soft-monotonicity
  regulariser (`monotonicity_penalty`).
- `image_sampler` / `image_eval_set` / `bilinear`: stratified uv sampling with bilinear targets;
  `texel_sampler`: texel centres and their exact values (what a decoded texture is scored on).
- `finish_lbfgs`: full-batch L-BFGS on the squared error at given points (texel centres), the
  refinement that follows the Adam phase in texture compression.
- `evaluate_quantised`: PSNR before and after the export's quantisation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
import torch

from inshade.components.lookup_array.torch_twin import LookupArray

from .graph import GraphModule
from .indirection_training import (  # noqa: F401  (re-exported: this module is the cascades' one import)
    CLIPPERS, LOSSES, SCHEDULES, History, auto_clip_bound, cell_diagonal, clip_primary_gradients, finish_lbfgs,
    lookup_nodes, monotonicity_penalty, primary_nodes, psnr, train_cascade)
from .lookup_array import multilinear

# ---------------------------------------------------------------------------------------------
# initialisation (paper §1.3)
#
# Every init is `fn(resolution, channels, **args) -> Tensor [N_{d-1}, ..., N_0, C]` holding the
# values the array should *read back* (F(cells)); `make_array` maps them through F^-1.


def _ramp(resolution, channels):
    """Identity ramp; channel c ramps along axis c % d, so a 2D array with 4 channels holds
    (u, v, u, v) -- the paper's "repeated ramp" for extra channels. (LookupArray's own ramp.)"""
    return LookupArray(resolution, channels, init="ramp").cells.detach().clone()


def _shape(resolution, channels):
    return tuple(reversed([int(n) for n in resolution])) + (int(channels),)


def _per_channel(value, channels) -> torch.Tensor:
    v = torch.as_tensor(np.asarray(value, dtype=np.float32)).reshape(-1)
    if v.numel() == 1:
        return v.expand(channels).clone()
    if v.numel() != channels:
        raise ValueError(f"a per-channel value needs {channels} entries, got {v.numel()}")
    return v


def _constant(resolution, channels, value=0.5):
    """A constant (the paper's 0.5 for GGX); `value` a scalar or one per channel (e.g. grey
    albedo, light-blue (0.5, 0.5, 1) normal, white AO for a PBR set)."""
    return _per_channel(value, channels).expand(_shape(resolution, channels)).clone()


def _mean(resolution, channels, target):
    """The DC value: the per-channel mean of `target` (any [..., C] array of output samples)."""
    t = torch.as_tensor(np.asarray(target, dtype=np.float32))
    return _constant(resolution, channels, t.reshape(-1, channels).mean(0))


def grid_points(resolution) -> torch.Tensor:
    """The cells' coordinates under the corner-aligned convention, [N_{d-1}, ..., N_0, d]
    (x_k = i_k / (N_k - 1)); the last axis lists coordinates in input order x_0..x_{d-1}."""
    axes = [torch.linspace(0, 1, n) if n > 1 else torch.zeros(1) for n in resolution]
    grid = torch.meshgrid(*reversed(axes), indexing="ij")
    return torch.stack(list(reversed(grid)), -1)


def _downsample(resolution, channels, target, taps: int | None = None):
    """A downsampled target (the paper's init for SDF/NeRF cascaded arrays). `target` is
    either an array [M_{d-1}, ..., M_0, C] over [0, 1]^d (corner-aligned like the arrays
    themselves), box-filtered over each cell's footprint with `taps` samples per axis, or a
    callable x [P, d] -> [P, C] evaluated at the cell points (e.g. nearest truncated SDF)."""
    d = len(resolution)
    pts = grid_points(resolution).reshape(-1, d)
    if callable(target):
        with torch.no_grad():
            vals = torch.as_tensor(np.asarray(target(pts), dtype=np.float32))
        return vals.reshape(_shape(resolution, channels))
    t = torch.as_tensor(np.asarray(target, dtype=np.float32))
    if t.ndim == d:
        t = t[..., None]
    if t.ndim != d + 1 or t.shape[-1] != channels:
        raise ValueError(f"downsample target must be [M_(d-1), .., M_0, {channels}] for a {d}D array, "
                         f"got shape {tuple(t.shape)}")
    src = list(reversed(t.shape[:-1]))
    if taps is None:
        ratio = max((m - 1) / max(n - 1, 1) for m, n in zip(src, resolution))
        taps = int(min(4, max(1, math.ceil(ratio))))
    cell = torch.tensor([1.0 / max(n - 1, 1) for n in resolution])
    offs = (torch.arange(taps, dtype=torch.float32) + 0.5) / taps - 0.5 if taps > 1 else torch.zeros(1)
    acc = 0.0
    for combo in torch.cartesian_prod(*([offs] * d)).reshape(-1, d):
        acc = acc + multilinear(t, (pts + combo * cell).clamp(0, 1))
    return (acc / taps ** d).reshape(_shape(resolution, channels))


def _tensor(resolution, channels, values):
    """Explicit table values."""
    return torch.as_tensor(np.asarray(values, dtype=np.float32)).reshape(_shape(resolution, channels)).clone()


INITS: dict[str, Callable[..., torch.Tensor]] = {
    "ramp": _ramp,
    "constant": _constant,
    "mean": _mean,
    "downsample": _downsample,
    "tensor": _tensor,
}

# F^-1 on F's range, so an init's table values survive `LookupArray.table()`. The triangle wave
# is the identity on [0, 1] (values outside are clamped: F cannot produce them).
INVERSE_F: dict[str, Callable[[torch.Tensor, float], torch.Tensor]] = {
    "none": lambda t, n: t,
    "triangle": lambda t, n: t.clamp(0.0, 1.0),
    "sinusoid": lambda t, n: torch.asin((2.0 * t - 1.0).clamp(-1.0, 1.0)) / n,
}


def make_array(resolution, channels: int, *, init: str = "ramp", bits: int = 32,
               nonlinearity: str = "none", frequency: float = math.pi, **init_args) -> LookupArray:
    """A LookupArray whose table (F(cells)) starts as `INITS[init](resolution, channels, **init_args)`."""
    if init not in INITS:
        raise ValueError(f"unknown init {init!r}; known: {', '.join(INITS)}")
    table = INITS[init](list(resolution), int(channels), **init_args)
    cells = INVERSE_F[nonlinearity](table, float(frequency))
    return LookupArray(resolution, channels, bits, nonlinearity, frequency, init=cells)


def cascade(in_dim: int, out_channels: int, n_primary: int, n_cascaded: int, *, redundant: int = 0,
            primary_bits: int = 8, cascaded_bits: int = 8, primary_nonlinearity: str = "triangle",
            cascaded_nonlinearity: str = "none", primary_init: str = "ramp", primary_init_args=None,
            cascaded_init: str = "constant", cascaded_init_args=None, input_name: str = "x",
            input_semantic: str = "generic", output_name: str = "y",
            output_semantic: str = "generic") -> GraphModule:
    """The common cascade: an `in_dim`-D primary (N_p per side, in_dim + `redundant` channels,
    identity/repeated ramp, triangle F) -> an (in_dim + redundant)-D cascaded array (N_c per side,
    `out_channels`). `redundant` is the paper's redundant-channels fix (§4.4): extra primary
    channels and cascaded dimensions; texture compression's 2D -> 4D is `redundant=2`.
    Nodes are named "primary" and "cascaded"."""
    m = int(in_dim) + int(redundant)
    g = GraphModule([(input_name, int(in_dim), input_semantic)])
    g.add("primary", make_array([n_primary] * in_dim, m, init=primary_init, bits=primary_bits,
                                nonlinearity=primary_nonlinearity, **(primary_init_args or {})), input_name)
    g.add("cascaded", make_array([n_cascaded] * m, out_channels, init=cascaded_init, bits=cascaded_bits,
                                 nonlinearity=cascaded_nonlinearity, **(cascaded_init_args or {})), "primary")
    g.output(output_name, "cascaded", output_semantic)
    return g


# ---------------------------------------------------------------------------------------------
# sizing (paper §1.4)

@dataclass(frozen=True)
class Sizing:
    n_primary: int      # side of the primary array (multiple of 8)
    n_cascaded: int     # side of the cascaded array (multiple of 4)
    bytes: int          # cells only (see array_bytes)
    budget: int
    rho: float          # achieved N_p / N_c

    def ratio(self, uncompressed_bytes: int) -> float:
        return uncompressed_bytes / self.bytes


def array_bytes(side: int, dims: int, channels: int, bits: int) -> int:
    """Bytes of an array's cells: side^dims * channels * bits / 8 (the paper's count, supp.
    Eq. 3; the per-channel scale/offset of a quantised export -- 8 bytes a channel -- and any
    texture padding to 4 channels are not counted)."""
    return side ** dims * channels * bits // 8


def size_cascade(budget_bytes: int, rho: float, *, primary_dims: int, primary_channels: int,
                 cascaded_dims: int, cascaded_channels: int, primary_bits: int = 8,
                 cascaded_bits: int = 8, slack: float = 0.0) -> Sizing:
    """Largest cascade within `budget_bytes` (times 1 + `slack`) at ρ = N_p / N_c: a 1-D search
    over N_c = 4k with N_p the multiple of 8 nearest ρ·N_c (at least 8). Bytes never decrease
    with N_c, so the search gallops (k = 1, 2, 4, ...) to the first N_c over budget and bisects
    back to the last that fits -- the same answer as the paper's linear scan, in O(log) steps.
    Raises ValueError when even N_c = 4 does not fit. Example (notes §2.2): 1K RGB at 12x
    (262,144 bytes), ρ = 64, 2D/4ch primary -> 4D/3ch cascaded: N_c = 4, N_p = 256 needs
    262,912 bytes, so it needs slack >= 0.3%."""
    if not budget_bytes > 0 or not rho > 0:
        raise ValueError(f"budget ({budget_bytes}) and rho ({rho}) must be positive")
    limit = budget_bytes * (1.0 + slack)

    def config(k):
        n_c = 4 * k
        n_p = max(8, 8 * int(round(rho * n_c / 8)))
        total = (array_bytes(n_p, primary_dims, primary_channels, primary_bits)
                 + array_bytes(n_c, cascaded_dims, cascaded_channels, cascaded_bits))
        return n_p, n_c, total

    if config(1)[2] > limit:
        n_p, _, total = config(1)
        raise ValueError(
            f"a budget of {budget_bytes} bytes cannot be met at rho = {rho:g}: the smallest cascade "
            f"(N_c = 4, N_p = {n_p}, primary {primary_dims}D x {primary_channels} ch @ {primary_bits} bit, "
            f"cascaded {cascaded_dims}D x {cascaded_channels} ch @ {cascaded_bits} bit) needs {total} bytes; "
            f"lower rho or raise the budget")
    lo, hi = 1, 2                       # config(lo) fits; find hi that does not
    while config(hi)[2] <= limit:
        lo, hi = hi, hi * 2
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if config(mid)[2] <= limit else (lo, mid)
    n_p, n_c, total = config(lo)
    return Sizing(n_p, n_c, total, int(budget_bytes), n_p / n_c)


# ---------------------------------------------------------------------------------------------
# image data: stratified uv with bilinear targets (paper §2.2)

def _image_tensor(image) -> torch.Tensor:
    """[H, W] or [H, W, C] -> float32 [H, W, C]; integer images scaled by their dtype's max."""
    a = np.asarray(image)
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3:
        raise ValueError(f"an image must be [H, W] or [H, W, C], got shape {a.shape}")
    if np.issubdtype(a.dtype, np.integer):
        a = a.astype(np.float32) / np.iinfo(a.dtype).max
    return torch.from_numpy(np.ascontiguousarray(a, dtype=np.float32))


def bilinear(image: torch.Tensor, uv: torch.Tensor) -> torch.Tensor:
    """GL texture convention: texel (i, j) centred at ((j + 0.5) / W, (i + 0.5) / H), u along
    the width, v along the rows (row 0 at v = 0), clamp-to-edge. image [H, W, C], uv [B, 2]."""
    h, w = image.shape[:2]

    def axis(t, n):
        p = (t * n - 0.5).clamp(0, n - 1)
        i0 = p.floor().clamp(max=max(n - 2, 0))
        return i0.long(), (i0 + 1).clamp(max=n - 1).long(), (p - i0)[:, None]

    x0, x1, fx = axis(uv[:, 0], w)
    y0, y1, fy = axis(uv[:, 1], h)
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bot = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return top * (1 - fy) + bot * fy


def image_eval_set(image):
    """(uv, rgb): every texel centre and its exact value, [H*W, 2] and [H*W, C]."""
    img = _image_tensor(image)
    h, w = img.shape[:2]
    ys, xs = torch.meshgrid(torch.arange(h), torch.arange(w), indexing="ij")
    uv = torch.stack([(xs + 0.5) / w, (ys + 0.5) / h], -1).reshape(-1, 2).float()
    return uv, img.reshape(-1, img.shape[-1])


def texel_sampler(image, batch: int, seed: int = 0):
    """Endless (uv, target) batches of texel centres and their exact values, each epoch a random
    permutation of the texels: the points where decoded textures are compared with the original
    (and with block codecs), rather than the paper's jittered uv with bilinear targets."""
    uv, values = image_eval_set(image)
    gen = torch.Generator().manual_seed(seed)
    while True:
        order = torch.randperm(len(uv), generator=gen)
        for start in range(0, len(uv), batch):
            idx = order[start:start + batch]
            yield uv[idx], values[idx]


def mixed_sampler(image, batch: int, seed: int = 0):
    """Endless batches, half `texel_sampler`'s texel centres (the points PSNR and the block
    codecs are scored on) and half `image_sampler`'s stratified points with bilinear targets
    (the points between texels that a renderer's filtering reads), so a fit to one does not
    come at the other's cost."""
    for (u0, t0), (u1, t1) in zip(texel_sampler(image, batch // 2, seed), image_sampler(image, batch - batch // 2,
                                                                                           seed=seed + 1)):
        yield torch.cat([u0, u1]), torch.cat([t0, t1])


def image_sampler(image, batch: int, stratified: bool = True, seed: int = 0):
    """Endless (uv, target) batches. Stratified: one stratum per texel -- each epoch visits the
    texels in a random order, one uniformly jittered uv inside each -- and the target is the
    bilinear sample there (paper §2.2). Otherwise uv is uniform over [0, 1)^2."""
    img = _image_tensor(image)
    h, w = img.shape[:2]
    gen = torch.Generator().manual_seed(seed)
    n = h * w
    while True:
        if not stratified:
            uv = torch.rand(batch, 2, generator=gen)
            yield uv, bilinear(img, uv)
            continue
        order = torch.randperm(n, generator=gen)
        for start in range(0, n, batch):
            idx = order[start:start + batch]
            jitter = torch.rand(len(idx), 2, generator=gen)
            uv = torch.stack([(idx % w + jitter[:, 0]) / w, (idx // w + jitter[:, 1]) / h], -1)
            yield uv, bilinear(img, uv)


# ---------------------------------------------------------------------------------------------
# post-training quantisation (the export's)

def quantised_copy(cascade: GraphModule, bits: int | dict[str, int]) -> GraphModule:
    """What a bundle exported with these bits reads back as: every lookup array (or those named
    in `bits`) exported at `bits` and re-imported (dequantised cells, F baked)."""
    nodes = lookup_nodes(cascade)
    want = bits if isinstance(bits, dict) else {k: int(bits) for k in nodes}
    saved = {k: cascade.nodes[k].bits for k in want}
    try:
        for k, b in want.items():
            cascade.nodes[k].bits = int(b)
        bundle = cascade.export("quantised")
    finally:
        for k, b in saved.items():
            cascade.nodes[k].bits = b
    return GraphModule.from_bundle(bundle)


def evaluate_quantised(cascade: GraphModule, bits: int | dict[str, int], x: torch.Tensor,
                       target: torch.Tensor, peak: float = 1.0) -> dict:
    """PSNR of the float cascade and of its `bits`-quantised export on (x, target)."""
    with torch.no_grad():
        before = psnr(cascade(x), target, peak)
        after = psnr(quantised_copy(cascade, bits)(x), target, peak)
    return {"bits": bits, "psnr_float": before, "psnr_quantised": after, "psnr_drop": before - after}
