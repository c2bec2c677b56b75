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
Each component type's rule is one function registered once with ``rule(type)`` in the table
``RULES`` (inshade/envelope_base.py, with the limits and ``Finding``), each in its component's folder
(components/<name>/envelope.py). A type with no rule gets a note and no bound downstream.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .bundle import Bundle
# the limits, findings and the rule table are public here, where the other modules import them
from .envelope_base import (DENSE_MAGNITUDE, DENSE_MAGNITUDE_WARN, EXP_ARG, GRID_GAIN, LOOKUP_GAIN,  # noqa: F401
                            LOOKUP_GAIN_CHAINED, NOTE, PERIODIC_ARG_COMPUTED, PERIODIC_ARG_INPUT, POW_ARG,
                            POW_EXPONENT, POW_SQUARING, RULES, TOL, WARNING, Finding, Site, Walk, rule)
from .components import registry as component_registry

component_registry.load("envelope")


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


def _unknown(s: Site):
    """A component no rule knows: no bound, say so."""
    s.warn(f"unknown component {s.node.type!r}", math.inf, math.nan,
           "no interval rule: downstream bounds are unknown", NOTE)
    return np.full(s.node.out_dim, -np.inf), np.full(s.node.out_dim, np.inf)


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
    exact: dict[str, bool] = {}       # value bit-identical on both sides (bundle inputs, relu of them)
    for p in bundle.inputs:
        lo, hi = rng[p.name]
        iv[p.name] = (np.full(p.dim, lo, np.float64), np.full(p.dim, hi, np.float64))
        exact[p.name] = True

    walk = Walk(bundle, findings)
    with np.errstate(over="ignore", invalid="ignore"):
        for n in bundle.nodes:
            lo = np.concatenate([iv[s][0] for s in n.inputs])
            hi = np.concatenate([iv[s][1] for s in n.inputs])
            src_exact = all(exact[s] for s in n.inputs)
            r = RULES.get(n.type)
            olo, ohi = (r.bounds if r else _unknown)(Site(walk, n, lo, hi, src_exact))
            iv[n.id] = (np.asarray(olo, np.float64).reshape(n.out_dim), np.asarray(ohi, np.float64).reshape(n.out_dim))
            exact[n.id] = bool(r and r.keeps_exact and src_exact)
    return Envelope(walk.findings, rng, iv, walk.periodic_args)


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
