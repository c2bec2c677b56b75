"""The parity envelope: where fp32 itself, not the code, stops GLSL and torch agreeing.

Every parity test holds |glsl - torch| <= 1e-5 * max(1, |torch|) (tests/parity.py). The two
sides sum in different orders and use different transcendental implementations, so they differ
by a few ulp of every intermediate value; that is harmless until a node *amplifies* it past the
rule. This module bounds, from the weights alone (numpy, no torch, no GL), the quantities that
do the amplifying, by interval arithmetic over the bundle's input ranges, and reports each one
that leaves the measured envelope:

- periodic arguments (``sin`` = sin(omega0 x), ``frequency`` = sin/cos(2^k pi x),
  ``triangle_wave`` = tri(2^k x)): a discrepancy in the argument moves the output by as much.
  Measured on llvmpipe: a 64-input dense feeding sin(omega0 .) gives a scaled error of about
  5.7e-8 * A (A = argument bound): 5.7e-6 at A = 2^5 pi, 1.4e-5 at 2^6 pi, 2.3e-5 at 2^7 pi.
  Limit for a computed argument: ``PERIODIC_ARG_COMPUTED`` = 128 (below it the argument's own
  ulp is <= 2^-17 = 7.6e-6). For an argument taken straight from a bundle input (both sides
  round the same product), llvmpipe's sin/cos agree with torch to 1 ulp up to 2^20 pi; the
  limit is then ``PERIODIC_ARG_INPUT`` = 2^7 pi (n_freqs <= 8 on [-1, 1], the range the parity
  suite covers: beyond it agreement is up to the driver's argument reduction). A triangle wave
  of an input is exact (power-of-two scale, mod 2), so only its computed arguments are checked.
- ``exp`` arguments: float32 overflows at ln(FLT_MAX) = 88.72; up to 88.7 llvmpipe's exp is
  within 3.9e-6 relative of torch's, and a computed argument adds ~5.7e-8 * A relative (4.6e-6
  at 80). Limit ``EXP_ARG`` = 80.
- dense accumulations: |glsl - torch| measured <= 5.7e-8 * S (n = 16 and 64 inputs,
  S = sum_j |W_ij| max|x_j| + |b_i|, the magnitude of the sum). The rule allows
  1e-5 * max(1, |y|), so a node whose S can exceed ``DENSE_MAGNITUDE`` (1e-5 / 5.7e-8 = 175)
  times max(1, min |y|) can break it by cancellation alone. Interval bounds on deep layers are
  loose, so this is reported as a warning only past ``DENSE_MAGNITUDE_WARN`` = 2^24 / 16
  (~1e6): there one ulp of S is >= 1/16, i.e. the sum cannot even represent its own result to
  the rule's absolute scale; between 175 and that it is a note.
- lookup arrays: a computed coordinate's discrepancy is multiplied by the array's gain
  sum over axes of (N - 1) * max |adjacent cell difference|, divided by max(1, max |cell|)
  (the rule is relative beyond 1). Measured: a dense (|coord| <= 1) feeding a 1D array gives
  1.0e-6 at gain 13, 5.0e-5 at gain 252 (~2e-7 * gain): limit ``LOOKUP_GAIN`` = 50. A
  coordinate read straight from another lookup array (the DI cascade) carries a smaller
  discrepancy: the shipped DI textures measure <= 6.9e-6 at gain 147 (~4.7e-8 * gain): limit
  ``LOOKUP_GAIN_CHAINED`` = 200. An input coordinate is rounded identically on both sides (no
  limit). Coordinates outside [0, 1] are clamped by both sides (a note, not a warning).
- grid encodings (``hash_grid``, ``dense_grid``): per level the position p = scale * x + 0.5 is
  rounded twice here (as llvmpipe and GLSL 4's ``precise`` keep it); where it is fused (tiny-cuda-nn's
  fmaf, some GLSL 3.30 / ES drivers) the two differ by one ulp of p, which moves the output by
  ulp(max p) * sum over axes of the max difference between neighbouring vertices' features (the
  level's rows as laid out for a dense level, wrap-around included; the spread max - min of its
  features for a hashed one), divided by max(1, max |feature|): a note past the 1e-5 rule. A
  computed coordinate is amplified like a lookup array's: gain sum over axes of scale * that
  neighbour difference / max(1, max |feature|). Measured: a 16- or 64-input dense feeding a 2D grid
  gives 6.1e-8 to 8.2e-8 * gain (1.0e-5 at gain 122, 6.5e-5 at 1020): limit ``GRID_GAIN`` = 100.
  Outside [0, 1] the levels wrap (the same on both sides: a note).
- ``one_blob``: the blob's slope is at most 15/16 n_bins, the gain of a computed input: limit
  ``LOOKUP_GAIN`` (measured on llvmpipe, a 16- or 64-input dense feeding it: 1.2e-7 to 2.9e-7 * gain).
  An input is bit-identical on both sides (no limit).

- ``power`` (x^p, p constant): torch's own paths (p = 0, 1, 0.5, -0.5, -1) agree to an ulp or two, and an
  integer p with |p| <= 32 is computed by repeated squaring (|p| - 1 roundings: measured <= 3.2e-6 at
  p = -32). Other exponents are exp2(p log2|x|), whose error grows with q = p log2|x| (the log2 of the
  result) and with |p| (log2's absolute error near x = 1, times p): measured on llvmpipe ~6e-8 q +
  1.1e-7 |p| (6.1e-6 at p = 2.5, q in [112, 127); 1.1e-5 at p = 100.5 near x = 1; a 16-input dense
  feeding it: 6.6e-6 at p = 31.5). Limits ``POW_ARG`` = 64 on the largest q and ``POW_EXPONENT`` = 32 on
  |p| there (<= 6e-6 measured inside both). Any path: a warning from q = 127 (float32 overflows at 128).
  The domain: x < 0 with a non-integer p is NaN, x = 0 with p < 0 is inf (warnings).
- ``log`` / ``log2``: measured <= 2.3e-7 scaled; an argument range reaching 0 or below is a warning
  (-inf at 0, NaN below).
- stepped ops (``floor``, ``ceil``, ``trunc``, ``round``, ``frac``, ``fmod``, ``remainder``): exact on both
  sides, so an input stays bit-identical through them. A computed argument whose range holds a step
  (an integer; a half-integer for round; a multiple of the divisor) can land one ulp on the other side
  of it in GLSL and move the output by the whole step: a note. ``fmod`` / ``remainder`` where
  |x / divisor| can reach 2^128: a warning (torch's vectorised CPU kernel returns NaN there, its
  scalar tail and the shader the exact value).
- ``int_gather``: the uint32 program and the fetch are exact on both sides; like the stepped ops, a
  computed value one ulp across an integer lands on another row (a note).
- ``atan2``: measured <= 2.4e-7. Where the box of its two inputs reaches the negative x axis or the
  origin and they are computed: a note (a 1-ulp discrepancy in a flips the result between pi and
  -pi; near the origin a discrepancy d moves it by d / |(a, b)|).

Saturating activations (sigmoid, tanh, softplus) are safe at any argument: lib/activations
evaluates them in overflow-free forms. The probes behind these numbers are described in the
docs' parity page (docs/parity.md, "The parity envelope").

API: ``analyse(bundle, ranges=None) -> Envelope``; ``format_findings(envelope) -> list[str]``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .bundle import Bundle, Node
from .components import STEPPED_ELEMENTWISE, grid_node_levels

TOL = 1e-5
PERIODIC_ARG_INPUT = 2.0 ** 7 * math.pi    # ~402: sin/cos of a bundle input
PERIODIC_ARG_COMPUTED = 128.0              # sin/cos/tri of a computed value
EXP_ARG = 80.0
DENSE_MAGNITUDE = 175.0                    # S / max(1, min|y|) where cancellation can break the rule
DENSE_MAGNITUDE_WARN = 2.0 ** 24 / 16      # ~1.05e6: one ulp of S >= 1/16
LOOKUP_GAIN = 50.0                         # gain / max(1, max|cell|), coordinate from a dense etc.
LOOKUP_GAIN_CHAINED = 200.0                # same, coordinate straight from another lookup array
GRID_GAIN = 100.0                          # sum_d scale * neighbour difference / max(1, max|feature|)
POW_ARG = 64.0                             # log2 of the largest |x^p| computed as exp2(p log2|x|)
POW_EXPONENT = 32.0                        # |p| there
POW_SQUARING = 32                          # integer |p| up to this: repeated squaring (lib/activations)

WARNING, NOTE = "warning", "note"


@dataclass(frozen=True)
class Finding:
    """One quantity outside (warning) or near/assumed about (note) the parity envelope."""

    level: str          # "warning" or "note"
    node: str           # node id (or input port name for range assumptions)
    quantity: str       # what was bounded, e.g. "sin argument |omega0 * x|"
    bound: float        # its bound over the input ranges
    threshold: float    # the envelope's limit for it (nan for pure notes)
    why: str            # one sentence: what breaks beyond the threshold

    def line(self) -> str:
        thr = "" if math.isnan(self.threshold) else f" > {self.threshold:.4g}"
        return f"{self.level}: {self.node}: {self.quantity} bound {self.bound:.4g}{thr}: {self.why}"


@dataclass
class Envelope:
    """What `analyse` found: findings, the input ranges used, and each value's interval."""

    findings: list[Finding]
    ranges: dict[str, tuple[float, float]]
    intervals: dict[str, tuple[np.ndarray, np.ndarray]] = field(repr=False, default_factory=dict)
    # per sin / cos / frequency node: the bound of |argument| of each GLSL call group (a sin / cos
    # node: one; a frequency encoding: one per frequency), for codegen's range reduction
    periodic_args: dict[str, list[float]] = field(repr=False, default_factory=dict)

    @property
    def warnings(self) -> list[Finding]:
        return [f for f in self.findings if f.level == WARNING]

    @property
    def notes(self) -> list[Finding]:
        return [f for f in self.findings if f.level == NOTE]

    @property
    def ok(self) -> bool:
        return not self.warnings


def input_ranges(bundle: Bundle) -> tuple[dict[str, tuple[float, float]], list[Finding]]:
    """The range of every input port from its semantic, plus notes for assumed ones.

    uv, barycentric: [0, 1]; triangle_id: [0, 2^24 - 1]; normal / direction: [-1, 1] (unit vectors); position: [-1, 1] when a
    `render.transfer` or `render.sdf` frame normalises it (q = (p - center) / radius lies in
    the unit ball), assumed [-1, 1] otherwise; anything else: assumed [-1, 1]."""
    render = bundle.meta.get("render") or {}
    framed = isinstance(render, dict) and any(isinstance(render.get(k), dict) for k in ("transfer", "sdf"))
    ranges, notes = {}, []
    for p in bundle.inputs:
        sem = p.semantic.lower()
        if sem in ("uv", "barycentric"):
            ranges[p.name] = (0.0, 1.0)
        elif sem == "triangle_id":    # a face index (uint input): 0 .. 2^24 - 1
            ranges[p.name] = (0.0, float((1 << 24) - 1))
        elif sem in ("normal", "direction"):
            ranges[p.name] = (-1.0, 1.0)
        elif sem == "position" and framed:
            ranges[p.name] = (-1.0, 1.0)
        else:
            ranges[p.name] = (-1.0, 1.0)
            what = "no render.transfer/render.sdf frame" if sem == "position" else "no known range"
            notes.append(Finding(NOTE, p.name, f"input range (semantic {p.semantic!r})", 1.0, math.nan,
                                 f"{what}: assumed [-1, 1]; pass ranges= to analyse() for the real one"))
    return ranges, notes


# --- interval helpers ----------------------------------------------------------------------

def _sin_range(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact range of sin over [lo, hi], elementwise (float64)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    out_lo = np.minimum(np.sin(lo), np.sin(hi))
    out_hi = np.maximum(np.sin(lo), np.sin(hi))
    with np.errstate(invalid="ignore"):
        # a maximum pi/2 + 2k pi inside [lo, hi]?  a minimum -pi/2 + 2k pi?
        has_max = np.floor((hi - math.pi / 2) / (2 * math.pi)) >= np.ceil((lo - math.pi / 2) / (2 * math.pi))
        has_min = np.floor((hi + math.pi / 2) / (2 * math.pi)) >= np.ceil((lo + math.pi / 2) / (2 * math.pi))
    wide = ~np.isfinite(lo) | ~np.isfinite(hi) | (hi - lo >= 2 * math.pi)
    out_hi = np.where(has_max | wide, 1.0, out_hi)
    out_lo = np.where(has_min | wide, -1.0, out_lo)
    return out_lo, out_hi


def _mag(lo, hi) -> np.ndarray:
    return np.maximum(np.abs(lo), np.abs(hi))


def _min_abs(lo, hi) -> np.ndarray:
    return np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(np.abs(lo), np.abs(hi)))


def _lut_cells(bundle: Bundle, node: Node) -> np.ndarray:
    """The cells as the shader sees them, float64 [N_{d-1}, ..., N_0, C]."""
    cells = bundle.tensor(node, "cells")
    bits = node.params["bits"]
    if bits == 32:
        return cells.astype(np.float64)
    levels = float((1 << bits) - 1)
    scale = bundle.tensor(node, "scale").astype(np.float64)
    offset = bundle.tensor(node, "offset").astype(np.float64)
    return offset + scale * (cells.astype(np.float64) / levels)


_SIN_WHY_INPUT = ("beyond 2^7 pi (n_freqs > 8 on [-1, 1]) GLSL/torch agreement depends on the "
                  "driver's sin argument reduction, outside what the parity suite covers")
_SIN_WHY_COMPUTED = ("an upstream discrepancy of ~1 ulp is multiplied by the argument: measured "
                     "~5.7e-8 * bound scaled error (1.4e-5 at 2^6 pi), past the 1e-5 rule")


def analyse(bundle: Bundle, ranges: dict[str, tuple[float, float]] | None = None) -> Envelope:
    """Propagates interval bounds from the input ranges through the graph and returns every
    quantity outside the parity envelope (warnings) plus range assumptions and near-misses
    (notes). `ranges` overrides the semantic ranges per input port: {name: (lo, hi)}."""
    rng, findings = input_ranges(bundle)
    if ranges:
        for name, (lo, hi) in ranges.items():
            if name not in rng:
                raise ValueError(f"no input port named {name!r} (ports: {', '.join(rng)})")
            rng[name] = (float(lo), float(hi))
        findings = [f for f in findings if f.node not in ranges]

    iv: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    periodic_args: dict[str, list[float]] = {}
    exact: dict[str, bool] = {}       # value bit-identical on both sides (bundle inputs, relu of them)
    lut_ids: set[str] = set()
    for p in bundle.inputs:
        lo, hi = rng[p.name]
        iv[p.name] = (np.full(p.dim, lo, np.float64), np.full(p.dim, hi, np.float64))
        exact[p.name] = True

    def warn(node, quantity, bound, threshold, why, level=WARNING):
        findings.append(Finding(level, node, quantity, float(bound), float(threshold), why))

    def periodic(node, quantity, bound, is_exact, check_input=True):
        if is_exact:
            if check_input and bound > PERIODIC_ARG_INPUT:
                warn(node, quantity, bound, PERIODIC_ARG_INPUT, _SIN_WHY_INPUT)
        elif bound > PERIODIC_ARG_COMPUTED:
            warn(node, quantity, bound, PERIODIC_ARG_COMPUTED, _SIN_WHY_COMPUTED)

    with np.errstate(over="ignore", invalid="ignore"):
        for n in bundle.nodes:
            lo = np.concatenate([iv[s][0] for s in n.inputs])
            hi = np.concatenate([iv[s][1] for s in n.inputs])
            src_exact = all(exact[s] for s in n.inputs)
            t, p = n.type, n.params
            is_exact = False
            if t == "dense":
                w = bundle.tensor(n, "weight").astype(np.float64)
                b = bundle.tensor(n, "bias").astype(np.float64) if p["bias"] else np.zeros(n.out_dim)
                if np.isfinite(lo).all() and np.isfinite(hi).all():
                    c, r = (lo + hi) / 2, (hi - lo) / 2
                    yc, yr = w @ c + b, np.abs(w) @ r
                    olo, ohi = yc - yr, yc + yr
                else:   # an unbounded input: term by term, a zero weight contributes nothing
                    wp, wn = np.maximum(w, 0), np.minimum(w, 0)
                    term = lambda m, v: np.where(m != 0, m * v, 0.0).sum(1)  # noqa: E731
                    olo, ohi = term(wp, lo) + term(wn, hi) + b, term(wp, hi) + term(wn, lo) + b
                s = np.abs(w) @ _mag(lo, hi) + np.abs(b)
                ratio = s / np.maximum(1.0, _min_abs(olo, ohi))
                i = int(np.nanargmax(np.where(np.isnan(ratio), np.inf, ratio)))
                if not np.isfinite(ratio[i]) or ratio[i] > DENSE_MAGNITUDE_WARN:
                    warn(n.id, f"accumulation magnitude sum|W||x|+|b| (row {i})", s[i], DENSE_MAGNITUDE_WARN,
                         "one ulp of the sum is >= 1/16: fp32 cannot hold the result to the rule's scale, "
                         "and summation order alone (GEMM vs mat4 blocks) breaks parity")
                elif ratio[i] > DENSE_MAGNITUDE:
                    warn(n.id, f"accumulation magnitude sum|W||x|+|b| (row {i})", s[i], DENSE_MAGNITUDE,
                         "measured summation-order discrepancy ~5.7e-8 * magnitude; if the output can "
                         "cancel to |y| <= 1 that exceeds 1e-5 (interval bound, may be loose)", NOTE)
            elif t in ("relu", "identity"):
                olo, ohi = (np.maximum(lo, 0), np.maximum(hi, 0)) if t == "relu" else (lo, hi)
                is_exact = src_exact
            elif t == "leaky_relu":
                s = p["slope"]
                f = lambda x: np.maximum(x, 0) + s * np.minimum(x, 0)  # noqa: E731
                cand = np.stack([f(lo), f(hi), np.where((lo < 0) & (hi > 0), 0.0, f(lo))])
                olo, ohi = cand.min(0), cand.max(0)
                is_exact = src_exact
            elif t == "sigmoid":
                olo, ohi = 1 / (1 + np.exp(-lo)), 1 / (1 + np.exp(-hi))
            elif t == "tanh":
                olo, ohi = np.tanh(lo), np.tanh(hi)
            elif t in _MONOTONE:          # non-decreasing: the ends map to the ends
                f = _MONOTONE[t](p)
                olo, ohi = f(lo), f(hi)
            elif t in _DIPPING:           # a single minimum (value m at x0), increasing beyond it
                f, x0, m = _DIPPING[t](p)
                olo = np.where((lo <= x0) & (hi >= x0), m, np.minimum(f(lo), f(hi)))
                ohi = np.maximum(f(lo), f(hi))
            elif t == "abs":
                olo, ohi = _min_abs(lo, hi), _mag(lo, hi)
                is_exact = src_exact
            elif t == "clamp":
                olo, ohi = lo, hi
                if p["min"] is not None:
                    olo, ohi = np.maximum(olo, p["min"]), np.maximum(ohi, p["min"])
                if p["max"] is not None:
                    olo, ohi = np.minimum(olo, p["max"]), np.minimum(ohi, p["max"])
                is_exact = src_exact
            elif t in ("sqrt", "reciprocal", "log", "log2"):
                olo, ohi = _partial(n, t, lo, hi, warn)
            elif t in STEPPED_ELEMENTWISE:
                olo, ohi = _stepped(n, t, lo, hi, src_exact, warn)
                is_exact = src_exact
            elif t == "power":
                olo, ohi = _power(n, p["exponent"], lo, hi, warn)
            elif t == "affine":
                s_, o_ = bundle.tensor(n, "scale").astype(np.float64), bundle.tensor(n, "offset").astype(np.float64)
                a, b = lo * s_ + o_, hi * s_ + o_
                olo, ohi = np.minimum(a, b), np.maximum(a, b)
            elif t == "select":
                idx = np.asarray(p["lanes"])
                olo, ohi = lo[idx], hi[idx]
                is_exact = src_exact
            elif t in ("sub", "mul", "div"):
                half = n.out_dim
                olo, ohi = _binary_range(n, t, (lo[:half], hi[:half]), (lo[half:], hi[half:]), warn)
            elif t == "atan2":
                half = n.out_dim
                olo, ohi = _atan2_range(n, (lo[:half], hi[:half]), (lo[half:], hi[half:]), src_exact, warn)
            elif t == "where":            # one of the two branches
                k = n.out_dim
                olo, ohi = np.minimum(lo[2 * k:3 * k], lo[3 * k:]), np.maximum(hi[2 * k:3 * k], hi[3 * k:])
            elif t == "reduce":
                olo, ohi = _reduce_range(p["op"], lo.reshape(p["groups"], -1), hi.reshape(p["groups"], -1))
            elif t == "layer_norm":       # |(x - mean) / std| <= sqrt(size - 1) for any run
                size = n.out_dim // p["groups"]
                w = bundle.tensor(n, "weight").astype(np.float64) if p["affine"] else np.ones(size)
                b = bundle.tensor(n, "bias").astype(np.float64) if p["affine"] else np.zeros(size)
                r = math.sqrt(max(size - 1, 0)) * np.abs(w)
                olo, ohi = np.tile(b - r, p["groups"]), np.tile(b + r, p["groups"])
                gain = float(np.max(_mag(lo, hi))) / math.sqrt(p["eps"]) if p["eps"] > 0 else math.inf
                if size > 1 and 5.7e-8 * gain > TOL:
                    warn(n.id, "layer_norm gain max|x| / sqrt(eps) (a run whose variance nears 0)", gain,
                         TOL / 5.7e-8, "an ulp of the input is multiplied by 1 / sqrt(var + eps); rows whose "
                         "features are nearly equal can break the rule", NOTE)
            elif t in ("exp", "expm1"):   # expm1 = exp(x) - 1 in GLSL: the same overflow
                bound = float(np.max(hi))
                if bound > EXP_ARG:
                    warn(n.id, f"{t} argument", bound, EXP_ARG,
                         "float32 exp overflows to inf at 88.72 (and relative agreement nears 1e-5 above 80)")
                fn = np.exp if t == "exp" else np.expm1
                olo, ohi = fn(lo), fn(hi)
            elif t == "latent_pyramid":   # bilinear within a level: a convex combination of texels
                levels = [bundle.tensor(n, f"level{k}").reshape(-1, p["channels"]) for k in range(p["levels"])]
                olo = np.min([lv.min(0) for lv in levels], 0)
                ohi = np.max([lv.max(0) for lv in levels], 0)
            elif t == "mesh_features":    # per level a barycentric (convex) blend of table rows
                table = bundle.tensor(n, "table")
                if p["precision"] == "u8":   # value = offset + scale * q / 255 per lane
                    table = bundle.tensor(n, "offset") + bundle.tensor(n, "scale") * (table / np.float32(255.0))
                olo, ohi = np.tile(table.min(0), p["levels"]), np.tile(table.max(0), p["levels"])
            elif t in ("hash_grid", "dense_grid"):   # per level a convex blend of the level's rows
                olo, ohi = _grid(bundle, n, lo, hi, src_exact, warn)
            elif t == "one_blob":         # bin masses of a unit blob
                gain = 15.0 / 16.0 * p["n_bins"]
                if not src_exact and gain > LOOKUP_GAIN:
                    warn(n.id, f"one_blob gain 15/16 n_bins (n_bins {p['n_bins']}, input computed)", gain, LOOKUP_GAIN,
                         "an upstream discrepancy is multiplied by the blob's slope: measured ~2.9e-7 * gain "
                         "(1.6e-5 at n_bins 64 after a 64-input dense)")
                olo, ohi = np.zeros(n.out_dim), np.ones(n.out_dim)
            elif t == "int_gather":       # table rows as stored (zeros past the table)
                table = bundle.tensor(n, "table").astype(np.float64)
                olo = np.tile(np.minimum(table.min(0), 0.0), len(p["indices"]))
                ohi = np.tile(np.maximum(table.max(0), 0.0), len(p["indices"]))
                if not src_exact:
                    warn(n.id, "integer index from a computed value", float(np.max(_mag(lo, hi))), math.nan,
                         "exact on both sides, but a value one ulp across an integer picks another row", NOTE)
                is_exact = src_exact
            elif t == "sparse_voxels":    # one latent row per slot, fetched as stored
                latents = bundle.tensor(n, "latents").astype(np.float64)
                olo, ohi = latents.min(0), latents.max(0)
            elif t == "add":              # the sum of the two halves of its input
                half = n.out_dim
                olo, ohi = lo[:half] + lo[half:], hi[:half] + hi[half:]
            elif t == "shading_frames":   # unit frame vectors dotted with unit directions
                olo, ohi = np.full(n.out_dim, -1.0), np.full(n.out_dim, 1.0)
            elif t == "proxy_params":     # weights, slopes (sinh-like of the inputs), alphas, correlation
                olo, ohi = _proxy_ranges(p, lo, hi)
            elif t in ("sin", "cos"):     # cos(t) = sin(t + pi/2)
                w0 = p["omega0"]
                alo, ahi = np.minimum(w0 * lo, w0 * hi), np.maximum(w0 * lo, w0 * hi)
                periodic_args[n.id] = [float(np.max(_mag(alo, ahi)))]
                periodic(n.id, f"{t} argument |omega0 * x| (omega0 {w0:g})", periodic_args[n.id][0], src_exact)
                shift = math.pi / 2 if t == "cos" else 0.0
                olo, ohi = _sin_range(alo + shift, ahi + shift)
            elif t == "frequency":
                nf, d = p["n_freqs"], n.in_dim
                parts_lo, parts_hi = ([lo], [hi]) if p["include_input"] else ([], [])
                for fn in ("sin", "cos"):
                    for k in range(nf):
                        a = (2.0 ** k) * math.pi
                        alo, ahi = a * lo, a * hi
                        if fn == "cos":   # cos(t) = sin(t + pi/2)
                            alo, ahi = alo + math.pi / 2, ahi + math.pi / 2
                        slo, shi = _sin_range(alo, ahi)
                        parts_lo.append(slo)
                        parts_hi.append(shi)
                bound = (2.0 ** (nf - 1)) * math.pi * float(np.max(_mag(lo, hi)))
                periodic_args[n.id] = [(2.0 ** k) * math.pi * float(np.max(_mag(lo, hi))) for k in range(nf)]
                periodic(n.id, f"frequency argument 2^{nf - 1} pi |x| (n_freqs {nf})", bound, src_exact)
                olo, ohi = np.concatenate(parts_lo), np.concatenate(parts_hi)
                assert olo.size == n.out_dim == d * (2 * nf + int(p["include_input"]))
            elif t == "triangle_wave":
                nf = p["n_freqs"]
                bound = (2.0 ** (nf - 1)) * float(np.max(_mag(lo, hi)))
                periodic(n.id, f"triangle_wave argument 2^{nf - 1} |x| (n_freqs {nf})", bound, src_exact,
                         check_input=False)
                olo, ohi = np.zeros(n.out_dim), np.ones(n.out_dim)
            elif t == "spherical_harmonics":
                deg = p["degree"]
                # real orthonormal SH: sum_m Y_lm^2 = (2l+1)/4pi on the unit sphere, so |Y_lm| <= that root
                m = np.concatenate([np.full(2 * l + 1, math.sqrt((2 * l + 1) / (4 * math.pi))) for l in range(deg)])
                olo, ohi = -m, m
            elif t == "lookup_array":
                cells = _lut_cells(bundle, n)
                if np.any(lo < 0) or np.any(hi > 1):
                    warn(n.id, "lookup coordinate", float(np.max(np.maximum(-lo, hi - 1) + 1)), 1.0,
                         "coordinates outside [0, 1] are clamped (same on both sides)", NOTE)
                if not src_exact:
                    res = list(reversed(cells.shape[:-1]))    # N_0 .. N_{d-1}
                    gain = 0.0
                    for k, nk in enumerate(res):
                        if nk > 1:
                            axis = cells.ndim - 2 - k
                            gain += (nk - 1) * float(np.abs(np.diff(cells, axis=axis)).max())
                    gain /= max(1.0, float(np.abs(cells).max()))   # the rule is relative beyond 1
                    chained = all(s in lut_ids for s in n.inputs)
                    limit = LOOKUP_GAIN_CHAINED if chained else LOOKUP_GAIN
                    if gain > limit:
                        src_kind = "another lookup array" if chained else "a computed value"
                        warn(n.id, f"lookup gain sum_k (N_k - 1) max|cell step| / max(1, max|cell|) "
                             f"(coordinate from {src_kind})", gain, limit,
                             "an upstream coordinate discrepancy is multiplied by the gain: measured "
                             + ("~4.7e-8 * gain (shipped DI textures: 6.9e-6 at gain 147)" if chained
                                else "~2e-7 * gain scaled error (5e-5 at gain 252)"))
                lut_ids.add(n.id)
                flat = cells.reshape(-1, cells.shape[-1])
                olo, ohi = flat.min(0), flat.max(0)
            else:  # a component this module does not know: no bound, say so
                warn(n.id, f"unknown component {t!r}", math.inf, math.nan,
                     "no interval rule: downstream bounds are unknown", NOTE)
                olo, ohi = np.full(n.out_dim, -np.inf), np.full(n.out_dim, np.inf)
            iv[n.id] = (np.asarray(olo, np.float64).reshape(n.out_dim), np.asarray(ohi, np.float64).reshape(n.out_dim))
            exact[n.id] = is_exact
    return Envelope(findings, rng, iv, periodic_args)


def _grid_steps(rows: np.ndarray, level, dims: int, wraps: bool) -> np.ndarray:
    """Per axis, the max |feature difference| between neighbouring vertices of a level: for a dense
    level row i against row (i + resolution^d) mod rows (every neighbour pair, the wrap-around and
    padding rows included); for a hashed level (or coordinates that wrap uint32) the features' spread."""
    if not level.dense or wraps:
        return np.full(dims, float((rows.max(0) - rows.min(0)).max()))
    return np.array([float(np.abs(rows - np.roll(rows, -level.resolution ** d, axis=0)).max()) for d in range(dims)])


def _grid(bundle: Bundle, n: Node, lo, hi, src_exact: bool, warn):
    """hash_grid / dense_grid: output bounds per level, and what its position rounding amplifies."""
    table = bundle.tensor(n, "table").astype(np.float64)
    if np.any(lo < 0) or np.any(hi > 1):
        warn(n.id, "grid coordinate", float(np.max(np.maximum(-lo, hi - 1) + 1)), 1.0,
             "coordinates outside [0, 1] wrap around the levels (the same on both sides)", NOTE)
    wraps = bool(np.any(lo < 0))          # negative vertices wrap uint32: no neighbour structure
    xmag = float(np.max(_mag(lo, hi)))
    olo, ohi, fused, gain = [], [], (0.0, 0), (0.0, 0)
    for i, level in enumerate(grid_node_levels(n.type, n.params, n.in_dim)):
        rows = table[level.offset:level.offset + level.rows]
        olo.append(rows.min(0))
        ohi.append(rows.max(0))
        step = _grid_steps(rows, level, n.in_dim, wraps).sum() / max(1.0, float(np.abs(rows).max()))
        ulp = float(np.spacing(np.float32(float(level.scale) * xmag + 0.5)))
        fused, gain = max(fused, (ulp * step, i)), max(gain, (float(level.scale) * step, i))
    if fused[0] > TOL:
        warn(n.id, f"fused position: ulp(max p) * neighbour difference / max(1, max|feature|) (level {fused[1]})",
             fused[0], TOL, "where a driver fuses p = scale * x + 0.5 (tiny-cuda-nn's fmaf; llvmpipe and GLSL 4's "
             "precise do not) p moves by one ulp and the output by this much", NOTE)
    if not src_exact and gain[0] > GRID_GAIN:
        warn(n.id, f"grid gain sum_d scale * neighbour difference / max(1, max|feature|) (level {gain[1]}, "
             "coordinate computed)", gain[0], GRID_GAIN,
             "an upstream coordinate discrepancy is multiplied by the gain: measured ~8.2e-8 * gain at most "
             "(6.5e-5 at gain 1020)")
    return np.concatenate(olo), np.concatenate(ohi)


def _softplus(p):
    beta, threshold = p["beta"], p["threshold"]
    if threshold is None:
        return lambda x: np.logaddexp(0, beta * x) / beta
    return lambda x: np.where(beta * x > threshold, x, np.logaddexp(0, beta * x) / beta)


_MONOTONE = {
    "softplus": _softplus,
    "erf": lambda p: np.vectorize(math.erf, otypes=[np.float64]),
    "elu": lambda p: (lambda x: np.where(x > 0, x, p["alpha"] * np.expm1(np.minimum(x, 0)))),
}
_SILU = lambda x: x / (1 + np.exp(-x))  # noqa: E731
_DIPPING = {   # x0 and the minimum from the closed forms, rounded outwards
    "silu": lambda p: (_SILU, -1.2784645, -0.2784646),
    "gelu": lambda p: (lambda x: x * 0.5 * (1 + np.vectorize(math.erf, otypes=[np.float64])(x / math.sqrt(2))), -0.7517916, -0.1700404),
}


def _partial(n: Node, t: str, lo, hi, warn):
    """sqrt / reciprocal / log / log2: bounds, and a warning where the input range reaches outside the domain."""
    if t == "sqrt":
        if np.any(lo < 0):
            warn(n.id, "sqrt argument (lowest)", float(np.min(lo)), 0.0, "sqrt of a negative value is NaN")
        return np.sqrt(np.maximum(lo, 0)), np.sqrt(np.maximum(hi, 0))
    if t in ("log", "log2"):
        if np.any(lo <= 0):
            warn(n.id, f"{t} argument (lowest)", float(np.min(lo)), 0.0,
                 f"{t} of 0 is -inf and of a negative value NaN: no bound downstream")
        fn = np.log if t == "log" else np.log2
        with np.errstate(divide="ignore"):
            return fn(np.maximum(lo, 0)), fn(np.maximum(hi, 0))
    spans = (lo <= 0) & (hi >= 0)
    if np.any(spans):
        warn(n.id, "reciprocal argument range includes 0", float(np.max(_mag(lo, hi))), math.nan,
             "1 / x is unbounded near 0: no bound downstream")
    with np.errstate(divide="ignore"):
        a, b = 1 / lo, 1 / hi
    return np.where(spans, -np.inf, np.minimum(a, b)), np.where(spans, np.inf, np.maximum(a, b))


def _binary_range(n: Node, t: str, a, b, warn):
    (alo, ahi), (blo, bhi) = a, b
    if t == "sub":
        return alo - bhi, ahi - blo
    if t == "div":
        spans = (blo <= 0) & (bhi >= 0)
        if np.any(spans):
            warn(n.id, "divisor range includes 0", float(np.max(_mag(blo, bhi))), math.nan,
                 "a / b is unbounded near b = 0: no bound downstream")
        with np.errstate(divide="ignore", invalid="ignore"):
            blo, bhi = np.where(spans, -np.inf, 1 / bhi), np.where(spans, np.inf, 1 / blo)
    with np.errstate(invalid="ignore"):
        corners = np.stack([alo * blo, alo * bhi, ahi * blo, ahi * bhi])
    corners = np.where(np.isnan(corners), np.inf, corners)
    return corners.min(0), corners.max(0)


_ROUNDING = {"floor": np.floor, "ceil": np.ceil, "trunc": np.trunc, "round": np.round}   # np.round: halves to even
# the piece of the line an argument lies in, per stepped op: a step between two arguments' pieces
_PIECE = {"floor": np.floor, "ceil": np.ceil, "trunc": np.trunc, "frac": np.trunc, "fmod": np.trunc,
          "remainder": np.floor, "round": lambda x: np.floor(x + 0.5)}


def _stepped(n: Node, t: str, lo, hi, src_exact: bool, warn):
    """floor / ceil / trunc / round / frac / fmod / remainder: bounds, and what a step can do."""
    c = n.params.get("divisor", 1.0)
    with np.errstate(invalid="ignore"):
        plo, phi = _PIECE[t](lo / c), _PIECE[t](hi / c)
    one_piece = np.isfinite(lo) & np.isfinite(hi) & (plo == phi)
    if not src_exact and not one_piece.all():
        what = {"round": "a half-integer", "fmod": "a multiple of the divisor",
                "remainder": "a multiple of the divisor"}.get(t, "an integer")
        warn(n.id, f"{t} argument range holds {what} (computed argument)",
             float(np.max(_mag(lo, hi))), math.nan,
             "an upstream discrepancy of an ulp can put the argument on the other side of a step in GLSL, and "
             "the output then differs by the whole step", NOTE)
    if t in _ROUNDING:   # non-decreasing: the ends map to the ends
        return _ROUNDING[t](lo), _ROUNDING[t](hi)
    if t in ("fmod", "remainder") and float(np.max(_mag(lo, hi))) / abs(c) >= 2.0 ** 128:
        warn(n.id, f"{t} quotient |x / divisor|", float(np.max(_mag(lo, hi))) / abs(c), 2.0 ** 128,
             "torch's vectorised CPU kernel (Sleef) returns NaN where x / divisor overflows float32; its "
             "scalar tail and the shader return the exact value")
    # within one piece the op is x - k c; across pieces, its whole range: |r| < |c| with the sign of x
    # (frac, fmod), or between 0 and c inclusive (remainder: r + c can round to c)
    if t == "remainder":
        full_lo, full_hi = np.full_like(lo, min(c, 0.0)), np.full_like(hi, max(c, 0.0))
    else:
        c = abs(c)
        full_lo = np.where(lo < 0, np.maximum(lo, -c), 0.0)
        full_hi = np.where(hi > 0, np.minimum(hi, c), 0.0)
    k = np.where(one_piece, plo, 0.0) * n.params.get("divisor", 1.0)
    return np.where(one_piece, lo - k, full_lo), np.where(one_piece, hi - k, full_hi)


def _power(n: Node, p: float, lo, hi, warn):
    """power: bounds, domain warnings, and the accuracy limits of its exp2(p log2|x|) path."""
    if p == 0:
        return np.ones_like(lo), np.ones_like(hi)
    integer = float(p).is_integer()
    odd = integer and abs(p) < 2 ** 24 and int(p) % 2 == 1
    if not integer:
        if np.any(lo < 0):
            warn(n.id, "power base (lowest)", float(np.min(lo)), 0.0,
                 f"a negative base with the non-integer exponent {p:g} is NaN")
        lo, hi = np.maximum(lo, 0.0), np.maximum(hi, 0.0)
    spans = (lo <= 0) & (hi >= 0)
    if p < 0 and np.any(spans):
        warn(n.id, f"power base range includes 0 (exponent {p:g})", float(np.max(_mag(lo, hi))), math.nan,
             "0 to a negative power is inf: no bound downstream")
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        if odd:     # increasing (p > 0) or decreasing on each side of 0 (p < 0)
            a, b = np.power(lo, p), np.power(hi, p)
            olo = np.where(spans & (p < 0), -np.inf, np.minimum(a, b))
            ohi = np.where(spans & (p < 0), np.inf, np.maximum(a, b))
        else:       # a function of |x| (x >= 0 after the domain clamp), monotone in it
            a, b = np.power(_min_abs(lo, hi), p), np.power(_mag(lo, hi), p)
            olo, ohi = np.minimum(a, b), np.maximum(a, b)
        q = float(np.max(np.log2(_mag(olo, ohi))))
    if not np.isfinite(q):
        return olo, ohi
    squared = integer and abs(p) <= POW_SQUARING
    if squared or p in (0.5, -0.5, 1.0):
        if q > 127:
            warn(n.id, f"power result log2|x^p| (exponent {p:g})", q, 127.0,
                 "float32 overflows to inf at 2^128: near it the two sides can round to inf differently")
        return olo, ohi
    if q > POW_ARG:
        warn(n.id, f"power result log2|x^p| = p log2|x| (exponent {p:g})", q, POW_ARG,
             "exp2(p log2|x|) loses relative accuracy as it grows: measured ~6e-8 q + 1.1e-7 |p| scaled error "
             "(6.1e-6 at q = 127, p = 2.5), near 1e-5 beyond (and float32 overflows at 128)")
    if abs(p) > POW_EXPONENT:
        warn(n.id, "power exponent |p| (exp2(p log2|x|) path)", abs(p), POW_EXPONENT,
             "log2's absolute error near x = 1 is multiplied by p: measured ~1.1e-7 |p| scaled error "
             "(1.1e-5 at p = 100.5)")
    return olo, ohi


def _atan2_range(n: Node, a, b, src_exact: bool, warn):
    """atan2(a, b), the angle of the point (x = b, y = a): the corners' angles where the box of the
    two inputs keeps off the negative x axis and the origin (the angle is continuous there), else
    [-pi, pi]."""
    (alo, ahi), (blo, bhi) = a, b
    cut = (blo <= 0) & (alo <= 0) & (ahi >= 0)
    with np.errstate(invalid="ignore"):
        corners = np.stack([np.arctan2(y, x) for y in (alo, ahi) for x in (blo, bhi)])
    if not src_exact and np.any(cut):
        warn(n.id, "atan2 inputs reach the negative x axis or the origin (computed)", float(np.max(_mag(alo, ahi))),
             math.nan, "a 1-ulp discrepancy in a there flips the result between pi and -pi, and near the "
             "origin a discrepancy d moves it by d / |(a, b)|", NOTE)
    return np.where(cut, -np.pi, corners.min(0)), np.where(cut, np.pi, corners.max(0))


def _reduce_range(op: str, lo, hi):
    size = lo.shape[1]
    if op in ("sum", "mean"):
        k = 1.0 if op == "sum" else 1.0 / size
        return lo.sum(1) * k, hi.sum(1) * k
    if op == "norm":
        return np.sqrt((_min_abs(lo, hi) ** 2).sum(1)), np.sqrt((_mag(lo, hi) ** 2).sum(1))
    pick = np.max if op == "max" else np.min
    return pick(lo, 1), pick(hi, 1)


def _proxy_ranges(p: dict, lo: np.ndarray, hi: np.ndarray):
    """Output bounds of proxy_params (models/proxy_lobe.py): w in [0, 1], alpha in [alpha_min, 1],
    rho in [-0.99, 0.99], slopes mu = x (1 + |x| / 4) (monotone) of raw lanes 2, 3, 7, 8."""
    olo = np.array([0.0, 0.0, 0.0, 0.0, p["alpha_min"], p["alpha_min"], -0.99, 0.0, 0.0])
    ohi = np.array([1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.99, 0.0, 0.0])
    if p["isotropic"]:
        ohi[6] = olo[6] = 0.0
    else:
        mu = lambda x: x * (1 + np.abs(x) / 4)  # noqa: E731
        for i in (2, 3, 7, 8):
            olo[i], ohi[i] = mu(lo[i]), mu(hi[i])
    return olo, ohi


def format_findings(envelope: Envelope, *, notes: bool = True) -> list[str]:
    """One line per finding, warnings first: 'warning: NODE: QUANTITY bound B > T: WHY'.
    With no warnings the first line says the bundle is inside the envelope."""
    lines = [f.line() for f in envelope.warnings]
    if not lines:
        lines.append("inside the parity envelope (no fp32 limit reached over the input ranges: "
                     + ", ".join(f"{k} [{lo:g}, {hi:g}]" for k, (lo, hi) in envelope.ranges.items()) + ")")
    if notes:
        lines += [f.line() for f in envelope.notes]
    return lines
