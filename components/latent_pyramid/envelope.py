"""Latent texture pyramids: the parity envelope's rule."""
from __future__ import annotations

import numpy as np

from inshade.envelope_base import Site, rule


@rule("latent_pyramid")
def _latent_pyramid(s: Site):   # bilinear within a level: a convex combination of texels
    p = s.params
    levels = [s.table(f"level{k}").reshape(-1, p["channels"]) for k in range(p["levels"])]
    return np.min([lv.min(0) for lv in levels], 0), np.max([lv.max(0) for lv in levels], 0)
