"""Multiresolution grid encodings (instant-NGP; inshade/grid_layout.py has the rules): the bundle-level spec."""
from __future__ import annotations

import numpy as np

from inshade.components.spec import ComponentError, ComponentSpec, Param, pos_int, register
from inshade.components.unorm import TABLE_PRECISIONS, range_tensors, table_spec
from inshade.grid_layout import MAX_DENSE_RESOLUTION, GridLayoutError, grid_levels, table_rows


GRID_KINDS = {"hash_grid": "hash", "dense_grid": "dense"}
MAX_GRID_ROWS = 1 << 26


def grid_node_levels(node_type: str, p: dict, d: int):
    """The levels (inshade/grid_layout.py) of a resolved hash_grid / dense_grid node."""
    try:
        return grid_levels(d, p["levels"], p["base_resolution"], p["per_level_scale"],
                           p.get("log2_table_size", 24), GRID_KINDS[node_type])
    except GridLayoutError as exc:
        raise ComponentError(str(exc)) from None


def _grid_tensors(node_type):
    def tensors(p, d):
        table = table_spec((table_rows(grid_node_levels(node_type, p, d)), p["features"]), p["precision"])
        return {"table": table, **(range_tensors(p["features"]) if p["precision"] == "u8" else {})}
    return tensors


def _grid_checks(node_type):
    return lambda p, d: _check_grid(node_type, p, d)


def _check_grid(node_type, p, d):
    levels = grid_node_levels(node_type, p, d)
    if GRID_KINDS[node_type] == "dense" and levels[-1].resolution > MAX_DENSE_RESOLUTION[d]:
        raise ComponentError(f"levels: the finest dense level has {levels[-1].resolution} vertices per axis, "
                             f"more than {MAX_DENSE_RESOLUTION[d]} (its index would overflow uint32)")
    if table_rows(levels) > MAX_GRID_ROWS:
        raise ComponentError(f"levels: the table needs {table_rows(levels)} rows, more than {MAX_GRID_ROWS}")


_GRID_PARAMS = {
    "levels": Param(int, check=pos_int(32), doc="1..32"),
    "features": Param(int, 2, lambda v: v in (1, 2, 4, 8), doc="1, 2, 4 or 8 per level"),
    "base_resolution": Param(int, 16, pos_int(1 << 16), doc="vertices per axis of level 0"),
    "per_level_scale": Param(float, 2.0, lambda v: np.isfinite(v) and 1.0 <= v <= 16.0, doc="1..16"),
    "precision": Param(str, "f16", lambda v: v in TABLE_PRECISIONS,
                       doc="f16, f32 or u8 (8-bit codes, value = offset + scale * q / 255 per feature)"),
}
register(ComponentSpec(
    "hash_grid",
    "multiresolution hash encoding (instant-NGP, tiny-cuda-nn's Grid/HashGrid): input x in [0, 1]^dims "
    "(dims 2 or 3); per level a grid of resolution ceil(scale)+1, dense indexing where it fits the "
    "level's rows, else the spatial hash; linear interpolation; output levels*features lanes",
    {**_GRID_PARAMS,
     "log2_table_size": Param(int, 19, pos_int(24), doc="1..24"),
     "hash": Param(str, "coherent_prime", lambda v: v in ("coherent_prime", "prime", "reversed_prime"))},
    out_dim=lambda p, d: p["levels"] * p["features"],
    tensors=_grid_tensors("hash_grid"),
    in_dim=lambda p, d: d in (2, 3),
    category="lookup",
    extra_checks=_grid_checks("hash_grid"),
))
register(ComponentSpec(
    "dense_grid",
    "multiresolution dense grid (tiny-cuda-nn's DenseGrid): the hash grid's rules with every level "
    "indexed densely (rows = resolution^dims rounded up to 8)",
    dict(_GRID_PARAMS),
    out_dim=lambda p, d: p["levels"] * p["features"],
    tensors=_grid_tensors("dense_grid"),
    in_dim=lambda p, d: d in (2, 3),
    category="lookup",
    extra_checks=_grid_checks("dense_grid"),
))
