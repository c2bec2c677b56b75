"""Elementwise functions: the parity envelope's rules. Each bounds its node's output from its input
interval and reports what leaves the envelope (the limits and their measurements: inshade/envelope.py)."""
from __future__ import annotations

import math

import numpy as np

from inshade.components.elementwise.spec import STEPPED_ELEMENTWISE
from inshade.envelope_base import (EXP_ARG, NOTE, POW_ARG, POW_EXPONENT, POW_SQUARING, Site, mag, min_abs, rule,
                                   sin_range)


@rule("identity", keeps_exact=True)
def _identity(s: Site):
    return s.lo, s.hi


@rule("relu", keeps_exact=True)
def _relu(s: Site):
    return np.maximum(s.lo, 0), np.maximum(s.hi, 0)


@rule("leaky_relu", keeps_exact=True)
def _leaky_relu(s: Site):
    lo, hi, slope = s.lo, s.hi, s.params["slope"]
    f = lambda x: np.maximum(x, 0) + slope * np.minimum(x, 0)  # noqa: E731
    cand = np.stack([f(lo), f(hi), np.where((lo < 0) & (hi > 0), 0.0, f(lo))])
    return cand.min(0), cand.max(0)


@rule("sigmoid")
def _sigmoid(s: Site):
    return 1 / (1 + np.exp(-s.lo)), 1 / (1 + np.exp(-s.hi))


@rule("tanh")
def _tanh(s: Site):
    return np.tanh(s.lo), np.tanh(s.hi)


def _softplus(p):
    beta, threshold = p["beta"], p["threshold"]
    if threshold is None:
        return lambda x: np.logaddexp(0, beta * x) / beta
    return lambda x: np.where(beta * x > threshold, x, np.logaddexp(0, beta * x) / beta)


# non-decreasing: the ends map to the ends
_MONOTONE = {
    "softplus": _softplus,
    "erf": lambda p: np.vectorize(math.erf, otypes=[np.float64]),
    "elu": lambda p: (lambda x: np.where(x > 0, x, p["alpha"] * np.expm1(np.minimum(x, 0)))),
}
_SILU = lambda x: x / (1 + np.exp(-x))  # noqa: E731
# a single minimum (value m at x0), increasing beyond it; x0 and m from the closed forms, rounded outwards
_DIPPING = {
    "silu": lambda p: (_SILU, -1.2784645, -0.2784646),
    "gelu": lambda p: (lambda x: x * 0.5 * (1 + np.vectorize(math.erf, otypes=[np.float64])(x / math.sqrt(2))),
                       -0.7517916, -0.1700404),
}


@rule(*_MONOTONE)
def _monotone(s: Site):
    f = _MONOTONE[s.node.type](s.params)
    return f(s.lo), f(s.hi)


@rule(*_DIPPING)
def _dipping(s: Site):
    lo, hi = s.lo, s.hi
    f, x0, m = _DIPPING[s.node.type](s.params)
    return np.where((lo <= x0) & (hi >= x0), m, np.minimum(f(lo), f(hi))), np.maximum(f(lo), f(hi))


@rule("abs", keeps_exact=True)
def _abs(s: Site):
    return min_abs(s.lo, s.hi), mag(s.lo, s.hi)


@rule("clamp", keeps_exact=True)
def _clamp(s: Site):
    olo, ohi, p = s.lo, s.hi, s.params
    if p["min"] is not None:
        olo, ohi = np.maximum(olo, p["min"]), np.maximum(ohi, p["min"])
    if p["max"] is not None:
        olo, ohi = np.minimum(olo, p["max"]), np.minimum(ohi, p["max"])
    return olo, ohi


# --- partial functions: a warning where the input range reaches outside the domain ----------

@rule("sqrt")
def _sqrt(s: Site):
    lo, hi = s.lo, s.hi
    if np.any(lo < 0):
        s.warn("sqrt argument (lowest)", float(np.min(lo)), 0.0, "sqrt of a negative value is NaN")
    return np.sqrt(np.maximum(lo, 0)), np.sqrt(np.maximum(hi, 0))


_LOGS = {"log": np.log, "log2": np.log2}


@rule(*_LOGS)
def _log(s: Site):
    lo, hi, t = s.lo, s.hi, s.node.type
    if np.any(lo <= 0):
        s.warn(f"{t} argument (lowest)", float(np.min(lo)), 0.0,
               f"{t} of 0 is -inf and of a negative value NaN: no bound downstream")
    with np.errstate(divide="ignore"):
        return _LOGS[t](np.maximum(lo, 0)), _LOGS[t](np.maximum(hi, 0))


@rule("reciprocal")
def _reciprocal(s: Site):
    lo, hi = s.lo, s.hi
    spans = (lo <= 0) & (hi >= 0)
    if np.any(spans):
        s.warn("reciprocal argument range includes 0", float(np.max(mag(lo, hi))), math.nan,
               "1 / x is unbounded near 0: no bound downstream")
    with np.errstate(divide="ignore"):
        a, b = 1 / lo, 1 / hi
    return np.where(spans, -np.inf, np.minimum(a, b)), np.where(spans, np.inf, np.maximum(a, b))


_EXPS = {"exp": np.exp, "expm1": np.expm1}


@rule(*_EXPS)
def _exp(s: Site):   # expm1 = exp(x) - 1 in GLSL: the same overflow
    t = s.node.type
    bound = float(np.max(s.hi))
    if bound > EXP_ARG:
        s.warn(f"{t} argument", bound, EXP_ARG,
               "float32 exp overflows to inf at 88.72 (and relative agreement nears 1e-5 above 80)")
    return _EXPS[t](s.lo), _EXPS[t](s.hi)


# --- stepped ops -------------------------------------------------------------------------------

_ROUNDING = {"floor": np.floor, "ceil": np.ceil, "trunc": np.trunc, "round": np.round}   # np.round: halves to even
# the piece of the line an argument lies in, per stepped op: a step between two arguments' pieces
_PIECE = {"floor": np.floor, "ceil": np.ceil, "trunc": np.trunc, "frac": np.trunc, "fmod": np.trunc,
          "remainder": np.floor, "round": lambda x: np.floor(x + 0.5)}
_STEP = {"round": "a half-integer", "fmod": "a multiple of the divisor", "remainder": "a multiple of the divisor"}


@rule(*STEPPED_ELEMENTWISE, keeps_exact=True)
def _stepped(s: Site):
    """floor / ceil / trunc / round / frac / fmod / remainder: bounds, and what a step can do."""
    n, t, lo, hi = s.node, s.node.type, s.lo, s.hi
    c = n.params.get("divisor", 1.0)
    with np.errstate(invalid="ignore"):
        plo, phi = _PIECE[t](lo / c), _PIECE[t](hi / c)
    one_piece = np.isfinite(lo) & np.isfinite(hi) & (plo == phi)
    if not s.src_exact and not one_piece.all():
        s.warn(f"{t} argument range holds {_STEP.get(t, 'an integer')} (computed argument)",
               float(np.max(mag(lo, hi))), math.nan,
               "an upstream discrepancy of an ulp can put the argument on the other side of a step in GLSL, and "
               "the output then differs by the whole step", NOTE)
    if t in _ROUNDING:   # non-decreasing: the ends map to the ends
        return _ROUNDING[t](lo), _ROUNDING[t](hi)
    if t in ("fmod", "remainder") and float(np.max(mag(lo, hi))) / abs(c) >= 2.0 ** 128:
        s.warn(f"{t} quotient |x / divisor|", float(np.max(mag(lo, hi))) / abs(c), 2.0 ** 128,
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


# --- power ---------------------------------------------------------------------------------------

def _power_range(s: Site, p: float, lo, hi, integer: bool):
    """x^p over [lo, hi] (after the domain clamp), with a warning where 0 meets a negative exponent."""
    odd = integer and abs(p) < 2 ** 24 and int(p) % 2 == 1
    spans = (lo <= 0) & (hi >= 0)
    if p < 0 and np.any(spans):
        s.warn(f"power base range includes 0 (exponent {p:g})", float(np.max(mag(lo, hi))), math.nan,
               "0 to a negative power is inf: no bound downstream")
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        if odd:     # increasing (p > 0) or decreasing on each side of 0 (p < 0)
            a, b = np.power(lo, p), np.power(hi, p)
            return (np.where(spans & (p < 0), -np.inf, np.minimum(a, b)),
                    np.where(spans & (p < 0), np.inf, np.maximum(a, b)))
        # a function of |x| (x >= 0 after the domain clamp), monotone in it
        a, b = np.power(min_abs(lo, hi), p), np.power(mag(lo, hi), p)
        return np.minimum(a, b), np.maximum(a, b)


@rule("power")
def _power(s: Site):
    """power: bounds, domain warnings, and the accuracy limits of its exp2(p log2|x|) path."""
    p, lo, hi = s.params["exponent"], s.lo, s.hi
    if p == 0:
        return np.ones_like(lo), np.ones_like(hi)
    integer = float(p).is_integer()
    if not integer:
        if np.any(lo < 0):
            s.warn("power base (lowest)", float(np.min(lo)), 0.0,
                   f"a negative base with the non-integer exponent {p:g} is NaN")
        lo, hi = np.maximum(lo, 0.0), np.maximum(hi, 0.0)
    olo, ohi = _power_range(s, p, lo, hi, integer)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        q = float(np.max(np.log2(mag(olo, ohi))))
    if not np.isfinite(q):
        return olo, ohi
    squared = integer and abs(p) <= POW_SQUARING
    if squared or p in (0.5, -0.5, 1.0):
        if q > 127:
            s.warn(f"power result log2|x^p| (exponent {p:g})", q, 127.0,
                   "float32 overflows to inf at 2^128: near it the two sides can round to inf differently")
        return olo, ohi
    if q > POW_ARG:
        s.warn(f"power result log2|x^p| = p log2|x| (exponent {p:g})", q, POW_ARG,
               "exp2(p log2|x|) loses relative accuracy as it grows: measured ~6e-8 q + 1.1e-7 |p| scaled error "
               "(6.1e-6 at q = 127, p = 2.5), near 1e-5 beyond (and float32 overflows at 128)")
    if abs(p) > POW_EXPONENT:
        s.warn("power exponent |p| (exp2(p log2|x|) path)", abs(p), POW_EXPONENT,
               "log2's absolute error near x = 1 is multiplied by p: measured ~1.1e-7 |p| scaled error "
               "(1.1e-5 at p = 100.5)")
    return olo, ohi


@rule("sin", "cos")
def _sin(s: Site):   # cos(t) = sin(t + pi/2)
    t, lo, hi = s.node.type, s.lo, s.hi
    w0 = s.params["omega0"]
    alo, ahi = np.minimum(w0 * lo, w0 * hi), np.maximum(w0 * lo, w0 * hi)
    s.walk.periodic_args[s.node.id] = [float(np.max(mag(alo, ahi)))]
    s.periodic(f"{t} argument |omega0 * x| (omega0 {w0:g})", s.walk.periodic_args[s.node.id][0])
    shift = math.pi / 2 if t == "cos" else 0.0
    return sin_range(alo + shift, ahi + shift)
