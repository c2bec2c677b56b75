"""The parity envelope's rule for the periodic elementwise functions (sin, cos): it bounds the node's
output from its input interval and reports what its input's discrepancy is amplified by (the limits
and their measurements: inshade/envelope.py). The encodings', tables' and grids' rules live in their
component folders (components/<name>/envelope.py)."""
from __future__ import annotations

import math

import numpy as np

from .envelope_base import Site, mag, rule, sin_range


@rule("sin", "cos")
def _sin(s: Site):   # cos(t) = sin(t + pi/2)
    t, lo, hi = s.node.type, s.lo, s.hi
    w0 = s.params["omega0"]
    alo, ahi = np.minimum(w0 * lo, w0 * hi), np.maximum(w0 * lo, w0 * hi)
    s.walk.periodic_args[s.node.id] = [float(np.max(mag(alo, ahi)))]
    s.periodic(f"{t} argument |omega0 * x| (omega0 {w0:g})", s.walk.periodic_args[s.node.id][0])
    shift = math.pi / 2 if t == "cos" else 0.0
    return sin_range(alo + shift, ahi + shift)
