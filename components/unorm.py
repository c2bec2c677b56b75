"""Tables stored as 8-bit codes with a range per lane: value = offset + scale * q / 255 (q in 0..255,
an unorm8 texel the shader reads as q / 255). The table components' u8 form (hash and dense grids,
latent pyramids, sparse voxels, mesh features; lookup arrays at 8 bits are the same map), which
inshade/quantize.py gives them under i8: their values are not centred on zero, so a symmetric
int8 code would waste half its range.

The range covers the table (offset = the lane's minimum, scale = its max - min), so every value
codes to within half a step (scale / 510). Interpolating tables decode after the blend (offset +
scale * blend): the blend's weights sum to 1, so the affine map commutes with it.
"""
from __future__ import annotations

import numpy as np

from .spec import ComponentError, TensorSpec

U8_LEVELS = 255
# a table component's precision -> (its table's dtype, what the values must survive): f16 values in
# float16 textures, f32 as trained, u8 codes beside a range per lane (range_tensors)
TABLE_PRECISIONS = {"f16": ("float32", "float16"), "f32": ("float32", None), "u8": ("uint8", None)}


def table_spec(shape, precision: str) -> TensorSpec:
    return TensorSpec(tuple(shape), *TABLE_PRECISIONS[precision])


def lane_range(table) -> tuple[np.ndarray, np.ndarray]:
    """Per-lane (scale, offset) covering the table (lanes on the last axis): offset = min,
    scale = max - min (1 for a constant lane)."""
    t = np.asarray(table, np.float32).reshape(-1, np.shape(table)[-1])
    lo, hi = t.min(0), t.max(0)
    return np.where(hi > lo, hi - lo, 1.0).astype(np.float32), lo.astype(np.float32)


def encode(table, scale, offset) -> np.ndarray:
    """float [..., lanes] -> uint8 q = clamp(rint((table - offset) / scale * 255), 0, 255)."""
    u = (np.asarray(table, np.float32) - offset) / scale
    return np.clip(np.rint(u * np.float32(U8_LEVELS)), 0, U8_LEVELS).astype(np.uint8)


def decode(q, scale, offset) -> np.ndarray:
    """uint8 q [..., lanes] -> float32 offset + scale * (q / 255)."""
    return (offset + scale * (np.asarray(q).astype(np.float32) / np.float32(U8_LEVELS))).astype(np.float32)


def range_tensors(lanes: int) -> dict[str, TensorSpec]:
    """The u8 form's per-lane range, beside its codes."""
    return {"scale": TensorSpec((lanes,), "float32"), "offset": TensorSpec((lanes,), "float32")}


def checked_range(scale, offset, lanes: int) -> tuple[np.ndarray, np.ndarray]:
    """(scale, offset) as float32 [lanes] each, or one ComponentError."""
    scale, offset = np.asarray(scale, np.float32), np.asarray(offset, np.float32)
    if scale.shape != (lanes,) or offset.shape != (lanes,):
        raise ComponentError(f"scale, offset: shape [{lanes}] each, got {list(scale.shape)}, {list(offset.shape)}")
    if not (np.isfinite(scale).all() and np.isfinite(offset).all() and (scale > 0).all()):
        raise ComponentError("scale: must be finite and > 0 per lane, offset finite")
    return scale, offset


def as_codes(tensors: dict, slots) -> None:
    """The float tables ``slots`` of {slot: array} turned to codes in place over one range per lane
    (shared by the slots: a pyramid's levels decode alike), the range added as "scale" / "offset"."""
    lanes = np.asarray(tensors[slots[0]]).shape[-1]
    scale, offset = lane_range(np.concatenate([np.asarray(tensors[s], np.float32).reshape(-1, lanes) for s in slots]))
    for s in slots:
        tensors[s] = encode(tensors[s], scale, offset)
    tensors["scale"], tensors["offset"] = scale, offset


def decoded(tensors: dict, slot: str) -> np.ndarray:
    """A slot's values as the shader decodes them (float32), from {slot: codes, scale, offset}."""
    return decode(tensors[slot], tensors["scale"], tensors["offset"])
