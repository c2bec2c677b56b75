"""The pixel-centre uv convention of 2D fields: ``uv`` (0, 0) is the *bottom-left* corner of the
picture and (1, 1) the top-right (GL's texture convention, v grows upwards); pixel (column c, row r)
of an image-oriented array (row 0 = top) is sampled at its centre,
``uv = ((c + 0.5) / W, (H - 1 - r + 0.5) / H)`` -- ``gl_FragCoord.xy / size`` for the GL pixel the
read-back puts at row r."""
from __future__ import annotations

import numpy as np


def pixel_uvs(width: int, height: int) -> np.ndarray:
    """Pixel-centre uvs ``[H, W, 2]`` float32 in image orientation (row 0 = top). Computed in
    float32 as the shader does: ``gl_FragCoord.xy / size``."""
    x = (np.arange(width, dtype=np.float32) + np.float32(0.5)) / np.float32(width)
    y = (np.arange(height, dtype=np.float32)[::-1] + np.float32(0.5)) / np.float32(height)
    u, v = np.meshgrid(x, y)
    return np.stack([u, v], -1).astype(np.float32)
