"""UV-free hashed per-triangle feature hierarchy: the parity envelope's rule."""
from __future__ import annotations

import numpy as np

from inshade.envelope_base import Site, rule


@rule("mesh_features")
def _mesh_features(s: Site):   # per level a barycentric (convex) blend of table rows
    p = s.params
    table = s.table("table")
    return np.tile(table.min(0), p["levels"]), np.tile(table.max(0), p["levels"])
