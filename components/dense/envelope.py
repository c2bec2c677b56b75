"""The dense layer: the parity envelope's rule (the bound of its output, and the accumulation magnitude
past which fp32 summation order alone breaks parity: inshade/envelope.py has the measurements)."""
from __future__ import annotations

import numpy as np

from inshade.envelope_base import DENSE_MAGNITUDE, DENSE_MAGNITUDE_WARN, NOTE, Site, mag, min_abs, rule


@rule("dense")
def _dense(s: Site):
    n, lo, hi = s.node, s.lo, s.hi
    w = s.tensor("weight")
    b = s.tensor("bias") if s.params["bias"] else np.zeros(n.out_dim)
    if np.isfinite(lo).all() and np.isfinite(hi).all():
        c, r = (lo + hi) / 2, (hi - lo) / 2
        yc, yr = w @ c + b, np.abs(w) @ r
        olo, ohi = yc - yr, yc + yr
    else:   # an unbounded input: term by term, a zero weight contributes nothing
        wp, wn = np.maximum(w, 0), np.minimum(w, 0)
        term = lambda m, v: np.where(m != 0, m * v, 0.0).sum(1)  # noqa: E731
        olo, ohi = term(wp, lo) + term(wn, hi) + b, term(wp, hi) + term(wn, lo) + b
    total = np.abs(w) @ mag(lo, hi) + np.abs(b)
    ratio = total / np.maximum(1.0, min_abs(olo, ohi))
    i = int(np.nanargmax(np.where(np.isnan(ratio), np.inf, ratio)))
    if not np.isfinite(ratio[i]) or ratio[i] > DENSE_MAGNITUDE_WARN:
        s.warn(f"accumulation magnitude sum|W||x|+|b| (row {i})", total[i], DENSE_MAGNITUDE_WARN,
               "one ulp of the sum is >= 1/16: fp32 cannot hold the result to the rule's scale, "
               "and summation order alone (GEMM vs mat4 blocks) breaks parity")
    elif ratio[i] > DENSE_MAGNITUDE:
        s.warn(f"accumulation magnitude sum|W||x|+|b| (row {i})", total[i], DENSE_MAGNITUDE,
               "measured summation-order discrepancy ~5.7e-8 * magnitude; if the output can "
               "cancel to |y| <= 1 that exceeds 1e-5 (interval bound, may be loose)", NOTE)
    return olo, ohi


# --- elementwise ----------------------------------------------------------------------------
