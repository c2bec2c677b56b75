"""The UV-free hashed per-triangle feature hierarchy (Walloner 2024; models/mesh_features.py has the exact rules): the bundle-level spec."""
from __future__ import annotations

from inshade.components.spec import ComponentError, ComponentSpec, Param, TensorSpec, pos_int, register
from inshade.components.unorm import TABLE_PRECISIONS, range_tensors, table_spec


MESH_MAX_FACES = 1 << 24          # triangle ids travel through torch as exact float32 integers
MESH_MAX_TABLE = 1 << 24
MESH_MAX_VALUES = 1 << 28         # levels * table_size * features (1 GiB of float32)


def _mesh_feature_tensors(p, d):
    return {"table": table_spec((p["levels"] * p["table_size"], p["features"]), p["precision"]),
            "corners": TensorSpec((p["faces"], 3), "uint32"),
            "edges": TensorSpec((p["faces"], 3), "uint32"),
            **(range_tensors(p["features"]) if p["precision"] == "u8" else {})}


def _mesh_feature_checks(p, d):
    t, n = p["table_size"], p["faces"]
    if not (2 <= t <= MESH_MAX_TABLE and t & (t - 1) == 0):
        raise ComponentError(f"table_size: must be a power of two, got {t}")
    if not 1 <= n <= MESH_MAX_FACES:
        raise ComponentError(f"faces: must be 1..{MESH_MAX_FACES} (triangle ids travel as exact float32 "
                             f"integers), got {n}")
    if p["levels"] * t * p["features"] > MESH_MAX_VALUES:
        raise ComponentError(f"table_size: levels * table_size * features = {p['levels'] * t * p['features']} "
                             f"values, more than {MESH_MAX_VALUES}")


register(ComponentSpec(
    "mesh_features",
    "UV-free hashed per-triangle feature hierarchy: input (triangle id, t0, t1); per level l a "
    "2^l subdivision, sub-vertices canonicalised by the corners/edges owner tables, hashed into "
    "table rows l*T..l*T+T-1, barycentric blend; output levels*features lanes; precision u8: the "
    "table is uint8 q with per-lane value = offset + scale * q / 255 (applied after the blend)",
    {"levels": Param(int, check=pos_int(16)),
     "features": Param(int, 2, lambda v: v in (1, 2, 4, 8), doc="1, 2, 4 or 8"),
     "table_size": Param(int, doc="a power of two, 2..2^24"),
     "faces": Param(int, doc="1..2^24"),
     "precision": Param(str, "f16", lambda v: v in TABLE_PRECISIONS, doc="f16, f32 or u8")},
    out_dim=lambda p, d: p["levels"] * p["features"],
    tensors=_mesh_feature_tensors,
    in_dim=lambda p, d: d == 3,
    category="lookup",
    extra_checks=_mesh_feature_checks,
))

