"""Training machinery for Differentiable Indirection cascades (Datta et al. 2023).

A cascade is a `GraphModule` of `LookupArray` nodes: one (or more) *primary* arrays looked up
with the input coordinate, whose outputs (wrapped into [0, 1] by a periodic F) are the
coordinate of a *cascaded* array that returns the output. This module adds what training one
needs; the primitive itself, its export (F baked into the cells, 8/16/32-bit quantisation) and
its GLSL live in `models/lookup_array.py` and `codegen/`.

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
import time
from dataclasses import dataclass, field
from typing import Callable, Iterable

import numpy as np
import torch

from inshade import metrics

from .graph import GraphModule
from .lookup_array import LookupArray, multilinear

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
# stability tools (notes §4)

def lookup_nodes(g: GraphModule) -> list[str]:
    return [k for k, c in g.nodes.items() if isinstance(c, LookupArray)]


def primary_nodes(g: GraphModule) -> list[str]:
    """Lookup arrays whose output is (part of) another lookup array's coordinate."""
    luts = set(lookup_nodes(g))
    fed = {s for k in luts for s in g.wiring[k]}
    return [k for k in g.nodes if k in luts and k in fed]


def cell_diagonal(array: LookupArray) -> float:
    """Length of one cell's diagonal in coordinate space, sqrt(sum_k 1/(N_k - 1)^2)."""
    return math.sqrt(sum(1.0 / (n - 1) ** 2 for n in array.resolution if n > 1))


def auto_clip_bound(array: LookupArray, lr: float) -> float:
    """The paper's bound (§4.3): a plain gradient step lr * g should move a cell by at most half a
    cell diagonal, so |g| <= diag / (2 lr); for 1D that is (N lr)^-1 / 2 as in the paper (up to
    N vs N - 1, our corner-aligned spacing)."""
    return cell_diagonal(array) / (2.0 * lr)


def _clip_cells(array: LookupArray, bound: float):
    """Per cell: scale each cell's gradient vector (its channels) to L2 norm <= bound."""
    g = array.cells.grad
    if g is not None:
        norms = g.norm(dim=-1, keepdim=True)
        g.mul_((bound / norms.clamp_min(1e-30)).clamp(max=1.0))


def _clip_global(array: LookupArray, bound: float):
    """The whole array's gradient to L2 norm <= bound (torch's clip_grad_norm_)."""
    torch.nn.utils.clip_grad_norm_([array.cells], bound)


CLIPPERS: dict[str, Callable[[LookupArray, float], None]] = {"cell": _clip_cells, "global": _clip_global}


def clip_primary_gradients(g: GraphModule, bound: float | str, lr: float, mode: str = "cell",
                           primaries: list[str] | None = None):
    """Clip the primary arrays' gradients in place (`bound` a number or "auto")."""
    for name in primaries if primaries is not None else primary_nodes(g):
        arr = g.nodes[name]
        CLIPPERS[mode](arr, auto_clip_bound(arr, lr) if bound == "auto" else float(bound))


def monotonicity_penalty(array: LookupArray, kappa: float = 1.0, eps: float | None = None,
                         eps_scale: float = 0.5, axes: list[int] | None = None,
                         central: bool = False) -> torch.Tensor:
    """Soft-monotonicity regulariser (paper supp. §2, notes §4.5):

        R = (κ / N) Σ_c Σ_i ReLU(ε_c + F(c)[i] - sg(F(c)[i + 1]))

    over every cell i and channel c, the difference taken along the axis that channel ramps
    along (`axes[c]`, default c % d as in the (u, v, u, v) ramp), N the number of cells, sg a
    stop-gradient copy padded with its border value (so the last cell compares with itself,
    giving ReLU(ε) = 0). ε ≤ 0 tolerates small decreases: by default ε_c = -eps_scale / (N_a - 1),
    half the identity ramp's step. It is zero on any non-decreasing table and positive where a
    channel falls by more than |ε| between neighbours (a fold). `central=True` adds the mirrored
    term ReLU(ε + sg(F(c)[i - 1]) - F(c)[i]), so both cells of a fold are pushed apart."""
    t = array.table()
    res, d = array.resolution, len(array.resolution)
    axes = axes if axes is not None else [c % d for c in range(array.channels)]
    total = t.new_zeros(())
    for c, k in enumerate(axes):
        n = res[k]
        if n < 2:
            continue
        dim = d - 1 - k  # cells are stored [N_{d-1}, ..., N_0, C]
        e = eps if eps is not None else -eps_scale / (n - 1)
        tc = t[..., c]
        sg = tc.detach()
        # indices on the table's device (index_select refuses a CPU index for a CUDA table)
        nxt = sg.index_select(dim, torch.arange(1, n + 1, device=sg.device).clamp(max=n - 1))
        total = total + torch.relu(e + tc - nxt).sum()
        if central:
            prv = sg.index_select(dim, torch.arange(-1, n - 1, device=sg.device).clamp(min=0))
            total = total + torch.relu(e + prv - tc).sum()
    return kappa * total / float(np.prod(res))


# ---------------------------------------------------------------------------------------------
# training

def _cosine(opt, steps, patience):
    """Cosine decay from lr to 5% of it over `steps` (stepped every iteration)."""
    s = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda i: 0.05 + 0.95 * 0.5 * (1 + math.cos(math.pi * min(i / max(steps, 1), 1.0))))
    return (lambda: s.step()), (lambda loss: None)


def _plateau(opt, steps, patience):
    """The authors' choice: ReduceLROnPlateau (halve after `patience` evals without a 1e-3
    relative improvement of the interval's mean training loss; floor at 1% of lr)."""
    floor = [g["lr"] * 1e-2 for g in opt.param_groups]
    s = torch.optim.lr_scheduler.ReduceLROnPlateau(opt, factor=0.5, patience=patience, threshold=1e-3,
                                                   min_lr=floor)
    return (lambda: None), (lambda loss: s.step(loss))


def _constant_lr(opt, steps, patience):
    return (lambda: None), (lambda loss: None)


SCHEDULES = {"cosine": _cosine, "plateau": _plateau, "constant": _constant_lr}
# Training losses: the paper's MAE, or the squared error that PSNR measures.
LOSSES = {"l1": lambda d: torch.mean(torch.abs(d)), "mse": lambda d: torch.mean(d * d)}


def psnr(pred: torch.Tensor, target: torch.Tensor, peak: float = 1.0) -> float:
    """`inshade.metrics.psnr` (float64 difference, torch mean) of two tensors."""
    return metrics.psnr(pred, target, peak)


@dataclass
class History:
    """One record per evaluation: step (steps done), loss (mean training loss since the last
    record; the first record, at step 0, has the eval set's), psnr (on the eval set, else
    on the last batch), lr, seconds."""

    records: list[dict] = field(default_factory=list)

    def column(self, key):
        return [r[key] for r in self.records]

    @property
    def loss(self):
        return self.column("loss")

    @property
    def psnr(self):
        return self.column("psnr")

    @property
    def final(self) -> dict:
        return self.records[-1]


def train_cascade(cascade: GraphModule, sampler: Iterable, steps: int, *, lr: float = 1e-3,
                  schedule: str = "cosine", seed: int = 0, eval_set=None, eval_every: int | None = None,
                  clip_primary: float | str | None = None, clip_mode: str = "cell",
                  bounds: dict[str, tuple[float, float]] | None = None,
                  monotonicity: float = 0.0, monotonicity_args: dict | None = None,
                  primaries: list[str] | None = None, peak: float = 1.0, loss: str = "l1",
                  finish: tuple[int, Iterable, str] | None = None,
                  objective: Callable[[GraphModule, object], torch.Tensor] | None = None,
                  metric: Callable[[GraphModule], tuple[float, float]] | None = None,
                  progress: bool | None = None, desc: str = "cascade") -> History:
    """Fit `cascade` (any GraphModule of lookup arrays) to `sampler`'s (x, target) batches.

    Loss: `LOSSES[loss]` of cascade(x) - target (default L1, the paper's MAE) + `monotonicity` (κ) times
    `monotonicity_penalty` of each primary array. Adam at `lr` (paper: 1e-3) with
    `SCHEDULES[schedule]`: "cosine" (default; decays to 5% over `steps`, which suits the short
    CPU budgets here), "plateau" (the authors' ReduceLROnPlateau, on the mean training loss at
    each eval) or "constant". `clip_primary` (a bound, or "auto" for the paper's half-cell
    bound) clips the primary arrays' gradients per cell (`clip_mode="cell"`) or as a whole
    ("global") before each step. Primaries default to the lookup arrays that feed another one.
    `bounds` {node: (lo, hi)} keeps those arrays' cells within [lo, hi] after every step (a
    projection: e.g. an 8-bit cascaded array whose range stays near its outputs' range).

    `finish` = (step, sampler, loss): from that step on, batches come from the second sampler and
    the loss is `LOSSES[loss]`, under the same optimiser and schedule (texture compression trains
    the paper's way first, then finishes on texel centres with the squared error PSNR measures).

    For losses that are not a distance to targets (e.g. the GGX balls' display-space error):
    `objective(cascade, batch)` returns the loss of a sampler batch, and `metric(cascade)` the
    (loss, PSNR) each history record holds, in place of `eval_set`.

    Deterministic for a seed: global torch RNG is seeded (and restored afterwards); samplers
    should carry their own seeded generator, as `image_sampler` does. Progress on stderr: a bar
    on a TTY, a line every ~30 s off it (`progress=False`: silent). Evaluates every `eval_every`
    steps (default steps / 20) and at the end; returns the History.
    """
    from inshade.progress import progress as progress_bar

    if schedule not in SCHEDULES:
        raise ValueError(f"unknown schedule {schedule!r}; known: {', '.join(SCHEDULES)}")
    if clip_mode not in CLIPPERS:
        raise ValueError(f"unknown clip mode {clip_mode!r}; known: {', '.join(CLIPPERS)}")
    if objective is not None and finish is not None:
        raise ValueError("a custom objective has no finish phase")
    for name in (loss, finish[2] if finish else loss):
        if name not in LOSSES:
            raise ValueError(f"unknown loss {name!r}; known: {', '.join(LOSSES)}")
    loss_fn = LOSSES[loss]
    prim = primaries if primaries is not None else primary_nodes(cascade)
    eval_every = eval_every or max(1, steps // 20)
    history = History()
    batches = iter(sampler)

    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        opt = torch.optim.Adam(cascade.parameters(), lr=lr)
        on_step, on_eval = SCHEDULES[schedule](opt, steps, 3)

        def evaluate(step, interval_loss, last_batch, start):
            with torch.no_grad():
                if metric is not None:
                    eval_loss, eval_psnr = metric(cascade)
                else:
                    x, y = eval_set if eval_set is not None else last_batch
                    pred = cascade(x)
                    eval_loss, eval_psnr = float(loss_fn(pred - y)), psnr(pred, y, peak)
                rec = {"step": step, "loss": eval_loss if interval_loss is None else interval_loss,
                       "psnr": eval_psnr, "lr": opt.param_groups[0]["lr"], "seconds": time.perf_counter() - start}
            history.records.append(rec)
            return rec

        start = time.perf_counter()
        held_out = eval_set is not None or metric is not None
        first = None if held_out else next(batches)
        evaluate(0, None, first, start)
        pending = first
        acc, count = 0.0, 0
        bar = progress_bar(range(1, steps + 1), desc=desc, enabled=progress)
        for step in bar:
            if finish is not None and step == finish[0] + 1:
                batches, loss_fn, pending = iter(finish[1]), LOSSES[finish[2]], None
            batch = pending if pending is not None else next(batches)
            pending = None
            value = objective(cascade, batch) if objective is not None else loss_fn(cascade(batch[0]) - batch[1])
            total = value
            if monotonicity:
                for name in prim:
                    total = total + monotonicity_penalty(cascade.nodes[name], monotonicity,
                                                         **(monotonicity_args or {}))
            opt.zero_grad(set_to_none=True)
            total.backward()
            if clip_primary is not None:
                clip_primary_gradients(cascade, clip_primary, lr, clip_mode, prim)
            opt.step()
            if bounds:
                with torch.no_grad():
                    for name, (lo, hi) in bounds.items():
                        cascade.nodes[name].cells.clamp_(lo, hi)
            on_step()
            acc, count = acc + float(value.detach()), count + 1
            if step % eval_every == 0 or step == steps:
                rec = evaluate(step, acc / count, batch, start)
                on_eval(rec["loss"])
                bar.set_postfix(loss=f"{rec['loss']:.4f}", psnr=f"{rec['psnr']:.2f}")
                acc, count = 0.0, 0
    return history


def finish_lbfgs(cascade: GraphModule, data, evaluations: int, *, history: History | None = None,
                 history_size: int = 20, peak: float = 1.0, eval_every: int | None = None,
                 first_step: int = 0) -> History:
    """Refine `cascade` by full-batch L-BFGS (strong-Wolfe line search) on the mean squared error
    over `data` = (x, target), for at most `evaluations` loss/gradient evaluations.

    Why: on texel centres the finish is a deterministic least-squares problem (65K residuals,
    ~32K cells at 256^2 / 6x); minibatch Adam spends its steps on gradient noise, while the
    full batch with a quasi-Newton direction and a line search needs no learning rate and gets
    further per second (astronaut 256^2 / 6x, 6000 steps: +0.1 / +0.5 dB over the minibatch Adam
    finish for seeds 0 / 1, in less time). Appends records to `history` (or a new one) every `eval_every` evaluations
    (default evaluations / 10) and at the end, with step = `first_step` + evaluations so far."""
    x, y = data
    history = history if history is not None else History()
    eval_every = eval_every or max(1, evaluations // 10)
    params = [p for p in cascade.parameters() if p.requires_grad]
    # tolerances ~0: at ~33 dB the loss changes by < 1e-9 per iteration while still improving
    opt = torch.optim.LBFGS(params, lr=1.0, max_iter=evaluations, max_eval=evaluations,
                            history_size=history_size, tolerance_grad=1e-12, tolerance_change=1e-15,
                            line_search_fn="strong_wolfe")
    start, count = time.perf_counter(), [0]
    offset = history.records[-1]["seconds"] if history.records else 0.0   # continue a train_cascade clock

    def record(loss):
        history.records.append({"step": first_step + count[0], "loss": loss,
                                "psnr": metrics.psnr_from_mse(max(loss, 1e-30), peak),
                                "lr": 1.0, "seconds": offset + time.perf_counter() - start})

    def closure():
        opt.zero_grad(set_to_none=True)
        loss = LOSSES["mse"](cascade(x) - y)
        loss.backward()
        count[0] += 1
        if count[0] % eval_every == 0:
            record(float(loss.detach()))
        return loss

    if evaluations > 0:
        opt.step(closure)
    if count[0] and history.records and history.records[-1]["step"] == first_step + count[0]:
        history.records.pop()       # the last evaluation was recorded before the final step
    with torch.no_grad():
        record(float(LOSSES["mse"](cascade(x) - y)))
    return history


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
