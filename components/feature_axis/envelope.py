"""The feature axis of an imported network: the parity envelope's rules."""
from __future__ import annotations

import math

import numpy as np

from inshade.envelope_base import NOTE, TOL, Site, mag, min_abs, rule


@rule("affine")
def _affine(s: Site):
    scale, offset = s.tensor("scale"), s.tensor("offset")
    a, b = s.lo * scale + offset, s.hi * scale + offset
    return np.minimum(a, b), np.maximum(a, b)


@rule("select", keeps_exact=True)
def _select(s: Site):
    idx = np.asarray(s.params["lanes"])
    return s.lo[idx], s.hi[idx]


# --- binary: the node's input is its two operands, each out_dim wide --------------------------

@rule("add")
def _add(s: Site):
    (alo, ahi), (blo, bhi) = s.halves()
    return alo + blo, ahi + bhi


@rule("sub", "mul", "div")
def _binary(s: Site):
    (alo, ahi), (blo, bhi) = s.halves()
    t = s.node.type
    if t == "sub":
        return alo - bhi, ahi - blo
    if t == "div":
        spans = (blo <= 0) & (bhi >= 0)
        if np.any(spans):
            s.warn("divisor range includes 0", float(np.max(mag(blo, bhi))), math.nan,
                   "a / b is unbounded near b = 0: no bound downstream")
        with np.errstate(divide="ignore", invalid="ignore"):
            blo, bhi = np.where(spans, -np.inf, 1 / bhi), np.where(spans, np.inf, 1 / blo)
    with np.errstate(invalid="ignore"):
        corners = np.stack([alo * blo, alo * bhi, ahi * blo, ahi * bhi])
    corners = np.where(np.isnan(corners), np.inf, corners)
    return corners.min(0), corners.max(0)


@rule("atan2")
def _atan2(s: Site):
    """atan2(a, b), the angle of the point (x = b, y = a): the corners' angles where the box of the
    two inputs keeps off the negative x axis and the origin (the angle is continuous there), else
    [-pi, pi]."""
    (alo, ahi), (blo, bhi) = s.halves()
    cut = (blo <= 0) & (alo <= 0) & (ahi >= 0)
    with np.errstate(invalid="ignore"):
        corners = np.stack([np.arctan2(y, x) for y in (alo, ahi) for x in (blo, bhi)])
    if not s.src_exact and np.any(cut):
        s.warn("atan2 inputs reach the negative x axis or the origin (computed)", float(np.max(mag(alo, ahi))),
               math.nan, "a 1-ulp discrepancy in a there flips the result between pi and -pi, and near the "
               "origin a discrepancy d moves it by d / |(a, b)|", NOTE)
    return np.where(cut, -np.pi, corners.min(0)), np.where(cut, np.pi, corners.max(0))


@rule("where")
def _where(s: Site):   # one of the two branches
    k, lo, hi = s.node.out_dim, s.lo, s.hi
    return np.minimum(lo[2 * k:3 * k], lo[3 * k:]), np.maximum(hi[2 * k:3 * k], hi[3 * k:])


# --- reductions ------------------------------------------------------------------------------

@rule("reduce")
def _reduce(s: Site):
    op, groups = s.params["op"], s.params["groups"]
    lo, hi = s.lo.reshape(groups, -1), s.hi.reshape(groups, -1)
    size = lo.shape[1]
    if op in ("sum", "mean"):
        k = 1.0 if op == "sum" else 1.0 / size
        return lo.sum(1) * k, hi.sum(1) * k
    if op == "norm":
        return np.sqrt((min_abs(lo, hi) ** 2).sum(1)), np.sqrt((mag(lo, hi) ** 2).sum(1))
    pick = np.max if op == "max" else np.min
    return pick(lo, 1), pick(hi, 1)


@rule("layer_norm")
def _layer_norm(s: Site):   # |(x - mean) / std| <= sqrt(size - 1) for any run
    p = s.params
    size = s.node.out_dim // p["groups"]
    w = s.tensor("weight") if p["affine"] else np.ones(size)
    b = s.tensor("bias") if p["affine"] else np.zeros(size)
    r = math.sqrt(max(size - 1, 0)) * np.abs(w)
    gain = float(np.max(mag(s.lo, s.hi))) / math.sqrt(p["eps"]) if p["eps"] > 0 else math.inf
    if size > 1 and 5.7e-8 * gain > TOL:
        s.warn("layer_norm gain max|x| / sqrt(eps) (a run whose variance nears 0)", gain,
               TOL / 5.7e-8, "an ulp of the input is multiplied by 1 / sqrt(var + eps); rows whose "
               "features are nearly equal can break the rule", NOTE)
    return np.tile(b - r, p["groups"]), np.tile(b + r, p["groups"])


# --- integer gathers ----------------------------------------------------------------------

@rule("int_gather", keeps_exact=True)
def _int_gather(s: Site):   # table rows as stored (zeros past the table)
    table = s.tensor("table")
    olo = np.tile(np.minimum(table.min(0), 0.0), len(s.params["indices"]))
    ohi = np.tile(np.maximum(table.max(0), 0.0), len(s.params["indices"]))
    if not s.src_exact:
        s.warn("integer index from a computed value", float(np.max(mag(s.lo, s.hi))), math.nan,
               "exact on both sides, but a value one ulp across an integer picks another row", NOTE)
    return olo, ohi
