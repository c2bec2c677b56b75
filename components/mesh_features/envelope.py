"""UV-free hashed per-triangle feature hierarchy: the parity envelope's rule."""
from __future__ import annotations

import numpy as np

from inshade.envelope_base import Site, rule


@rule("mesh_features")
def _mesh_features(s: Site):   # per level a barycentric (convex) blend of table rows
    b, n, p = s.bundle, s.node, s.params
    table = b.tensor(n, "table")
    if p["precision"] == "u8":   # value = offset + scale * q / 255 per lane
        table = b.tensor(n, "offset") + b.tensor(n, "scale") * (table / np.float32(255.0))
    return np.tile(table.min(0), p["levels"]), np.tile(table.max(0), p["levels"])
