"""Differentiable Indirection's lookup arrays: the parity envelope's rule."""
from __future__ import annotations

import numpy as np

from inshade.envelope_base import LOOKUP_GAIN, LOOKUP_GAIN_CHAINED, NOTE, Site, rule


def _lut_cells(s: Site) -> np.ndarray:
    """The cells as the shader sees them, float64 [N_{d-1}, ..., N_0, C]."""
    cells = s.bundle.tensor(s.node, "cells")
    bits = s.params["bits"]
    if bits == 32:
        return cells.astype(np.float64)
    levels = float((1 << bits) - 1)
    return s.tensor("offset") + s.tensor("scale") * (cells.astype(np.float64) / levels)


@rule("lookup_array")
def _lookup_array(s: Site):
    n, lo, hi = s.node, s.lo, s.hi
    cells = _lut_cells(s)
    if np.any(lo < 0) or np.any(hi > 1):
        s.warn("lookup coordinate", float(np.max(np.maximum(-lo, hi - 1) + 1)), 1.0,
               "coordinates outside [0, 1] are clamped (same on both sides)", NOTE)
    if not s.src_exact:
        res = list(reversed(cells.shape[:-1]))    # N_0 .. N_{d-1}
        gain = 0.0
        for k, nk in enumerate(res):
            if nk > 1:
                axis = cells.ndim - 2 - k
                gain += (nk - 1) * float(np.abs(np.diff(cells, axis=axis)).max())
        gain /= max(1.0, float(np.abs(cells).max()))   # the rule is relative beyond 1
        chained = all(i in s.walk.lut_ids for i in n.inputs)
        limit = LOOKUP_GAIN_CHAINED if chained else LOOKUP_GAIN
        if gain > limit:
            src_kind = "another lookup array" if chained else "a computed value"
            s.warn(f"lookup gain sum_k (N_k - 1) max|cell step| / max(1, max|cell|) "
                   f"(coordinate from {src_kind})", gain, limit,
                   "an upstream coordinate discrepancy is multiplied by the gain: measured "
                   + ("~4.7e-8 * gain (shipped DI textures: 6.9e-6 at gain 147)" if chained
                      else "~2e-7 * gain scaled error (5e-5 at gain 252)"))
    s.walk.lut_ids.add(n.id)
    flat = cells.reshape(-1, cells.shape[-1])
    return flat.min(0), flat.max(0)
