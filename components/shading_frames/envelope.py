"""Learned shading frames: the parity envelope's rule."""
from __future__ import annotations

import numpy as np

from inshade.envelope_base import Site, rule


@rule("shading_frames")
def _shading_frames(s: Site):   # unit frame vectors dotted with unit directions
    return np.full(s.node.out_dim, -1.0), np.full(s.node.out_dim, 1.0)
