"""Multiresolution grid encodings: the parity envelope's rule."""
from __future__ import annotations

import numpy as np

from inshade.components import grid_node_levels
from inshade.envelope_base import GRID_GAIN, NOTE, TOL, Site, mag, rule


def _grid_steps(rows: np.ndarray, level, dims: int, wraps: bool) -> np.ndarray:
    """Per axis, the max |feature difference| between neighbouring vertices of a level: for a dense
    level row i against row (i + resolution^d) mod rows (every neighbour pair, the wrap-around and
    padding rows included); for a hashed level (or coordinates that wrap uint32) the features' spread."""
    if not level.dense or wraps:
        return np.full(dims, float((rows.max(0) - rows.min(0)).max()))
    return np.array([float(np.abs(rows - np.roll(rows, -level.resolution ** d, axis=0)).max()) for d in range(dims)])


@rule("hash_grid", "dense_grid")
def _grid(s: Site):
    """Per level a convex blend of the level's rows: output bounds per level, and what its position
    rounding amplifies."""
    n, lo, hi = s.node, s.lo, s.hi
    table = s.table("table")
    if np.any(lo < 0) or np.any(hi > 1):
        s.warn("grid coordinate", float(np.max(np.maximum(-lo, hi - 1) + 1)), 1.0,
               "coordinates outside [0, 1] wrap around the levels (the same on both sides)", NOTE)
    wraps = bool(np.any(lo < 0))          # negative vertices wrap uint32: no neighbour structure
    xmag = float(np.max(mag(lo, hi)))
    olo, ohi, fused, gain = [], [], (0.0, 0), (0.0, 0)
    for i, level in enumerate(grid_node_levels(n.type, n.params, n.in_dim)):
        rows = table[level.offset:level.offset + level.rows]
        olo.append(rows.min(0))
        ohi.append(rows.max(0))
        step = _grid_steps(rows, level, n.in_dim, wraps).sum() / max(1.0, float(np.abs(rows).max()))
        ulp = float(np.spacing(np.float32(float(level.scale) * xmag + 0.5)))
        fused, gain = max(fused, (ulp * step, i)), max(gain, (float(level.scale) * step, i))
    if fused[0] > TOL:
        s.warn(f"fused position: ulp(max p) * neighbour difference / max(1, max|feature|) (level {fused[1]})",
               fused[0], TOL, "where a driver fuses p = scale * x + 0.5 (tiny-cuda-nn's fmaf; llvmpipe and GLSL 4's "
               "precise do not) p moves by one ulp and the output by this much", NOTE)
    if not s.src_exact and gain[0] > GRID_GAIN:
        s.warn(f"grid gain sum_d scale * neighbour difference / max(1, max|feature|) (level {gain[1]}, "
               "coordinate computed)", gain[0], GRID_GAIN,
               "an upstream coordinate discrepancy is multiplied by the gain: measured ~8.2e-8 * gain at most "
               "(6.5e-5 at gain 1020)")
    return np.concatenate(olo), np.concatenate(ohi)
