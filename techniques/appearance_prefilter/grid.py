"""The sun's shadow caster of an appearance_prefilter bundle: the finest scale's occupied cells as
closed cubes (numpy only; the record's ProgramSpec.shadows hook builds it from the bundle's
``cells`` tensor, so a shadow map needs no mesh beside the bundle)."""
from __future__ import annotations

import numpy as np

_CORNERS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1]],
                    np.float32)
# two triangles per face, outward winding (the shadow pass draws both faces anyway)
_FACES = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                   [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]], np.uint32)


def caster_cubes(cells: np.ndarray, scale: int) -> tuple[np.ndarray, np.ndarray]:
    """(vertices float32 [8C, 3], faces uint32 [12C, 3]) of the cubes of the cells [N, 4] = (scale,
    i, j, k) at ``scale``; ValueError naming the field when that scale has no cell."""
    cells = np.asarray(cells, np.int64)
    if cells.ndim != 2 or cells.shape[1] != 4:
        raise ValueError(f"cells: expected [N, 4] (scale, i, j, k), got {list(cells.shape)}")
    ijk = cells[cells[:, 0] == scale, 1:4]
    if not len(ijk):
        raise ValueError(f"cells: no voxel at scale {scale} to cast shadows")
    size = np.float32(1.0 / (1 << scale))
    vertices = (ijk[:, None, :].astype(np.float32) + _CORNERS[None]) * size
    faces = _FACES[None] + (8 * np.arange(len(ijk), dtype=np.uint32))[:, None, None]
    return vertices.reshape(-1, 3), faces.reshape(-1, 3)
