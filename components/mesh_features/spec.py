"""The UV-free hashed per-triangle feature hierarchy (Walloner 2024; models/mesh_features.py has the exact rules): the bundle-level spec."""
from __future__ import annotations

import numpy as np

from inshade.components.spec import ComponentError, ComponentSpec, Param, TensorSpec, pos_int, register


MESH_FEATURE_PRECISIONS = {"f16": "float16", "f32": None, "u8": None}
MESH_FEATURE_STORAGE = {"f16": "float32", "f32": "float32", "u8": "uint8"}   # the table tensor's dtype

MESH_MAX_FACES = 1 << 24          # triangle ids travel through torch as exact float32 integers
MESH_MAX_TABLE = 1 << 24
MESH_MAX_VALUES = 1 << 28         # levels * table_size * features (1 GiB of float32)


def _mesh_feature_tensors(p, d):
    out = {"table": TensorSpec((p["levels"] * p["table_size"], p["features"]), MESH_FEATURE_STORAGE[p["precision"]],
                               MESH_FEATURE_PRECISIONS[p["precision"]]),
           "corners": TensorSpec((p["faces"], 3), "uint32"),
           "edges": TensorSpec((p["faces"], 3), "uint32")}
    if p["precision"] == "u8":   # per feature lane: value = offset + scale * q / 255
        out["scale"] = TensorSpec((p["features"],), "float32")
        out["offset"] = TensorSpec((p["features"],), "float32")
    return out


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
     "precision": Param(str, "f16", lambda v: v in MESH_FEATURE_PRECISIONS, doc="f16, f32 or u8")},
    out_dim=lambda p, d: p["levels"] * p["features"],
    tensors=_mesh_feature_tensors,
    in_dim=lambda p, d: d == 3,
    category="lookup",
    extra_checks=_mesh_feature_checks,
))


U8_LEVELS = 255


def quantize_u8(table: np.ndarray, scale: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """[rows, F] float -> uint8 q = clamp(rint((table - offset) / scale * 255), 0, 255) per lane."""
    u = (np.asarray(table, np.float32) - offset) / scale
    return np.clip(np.rint(u * np.float32(U8_LEVELS)), 0, U8_LEVELS).astype(np.uint8)


def dequantize_u8(q: np.ndarray, scale: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """uint8 q [rows, F] -> float32 offset + scale * (q / 255)."""
    return (offset + scale * (q.astype(np.float32) / np.float32(U8_LEVELS))).astype(np.float32)


def lane_range(table: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-lane (scale, offset) covering the table: offset = min, scale = max - min (1 when equal)."""
    t = np.asarray(table, np.float32).reshape(-1, np.shape(table)[-1])
    lo, hi = t.min(0), t.max(0)
    return np.where(hi > lo, hi - lo, 1.0).astype(np.float32), lo.astype(np.float32)


def as_u8(params: dict, tensors: dict) -> None:
    """A table stored at f32 or f16 turned to its u8 form in place (``params`` and {slot: array}): the
    per-lane range covering it, and its codes (inshade/quantize.py under i8)."""
    scale, offset = lane_range(tensors["table"])
    tensors["table"] = quantize_u8(tensors["table"], scale, offset)
    tensors["scale"], tensors["offset"] = scale, offset
    params["precision"] = "u8"
