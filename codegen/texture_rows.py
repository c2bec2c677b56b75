"""Tables as 2D textures whose rows are 2^n texels wide (the largest power of two that fits
GL_MAX_TEXTURE_SIZE, or less for small data): item `index` is texel (index & (W-1), index >> n)
(shaders/lib/texture_rows.glsl reads them), so a table longer than one texture row still fits."""
from __future__ import annotations

import numpy as np

from .limits import LimitError, limit, source


def row_layout(node_id: str, what: str, items: int, limits: dict) -> tuple[int, int]:
    """(log2 of the row width, rows) for `items` texels; LimitError when they cannot fit."""
    name = "GL_MAX_TEXTURE_SIZE"
    cap = limit(limits, name)
    log2w = min(cap.bit_length() - 1, max(1, (items - 1).bit_length()))
    rows = -(-items // (1 << log2w))
    if rows > cap:
        raise LimitError(f"node {node_id}: the {what} needs {items} texels, {1 << log2w}x{rows} in rows; "
                         f"{name} is {cap} ({source(limits, name)})")
    return log2w, rows


def rows_data(data: np.ndarray, log2w: int, rows: int) -> np.ndarray:
    """[items, C] -> [rows, 2^log2w, C], zero-padded."""
    out = np.zeros((rows << log2w, data.shape[1]), data.dtype)
    out[:data.shape[0]] = data
    return out.reshape(rows, 1 << log2w, data.shape[1])
