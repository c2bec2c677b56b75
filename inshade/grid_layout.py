"""The multiresolution grid encoding's layout (instant-NGP; tiny-cuda-nn's GridEncoding), in numpy:
per level its scale, resolution, table rows and first row, and the integer index of a grid vertex.

The rules are tiny-cuda-nn's (docs/tcnn.md cites the file and function of each):

- scale_l = exp2f(l * log2f(per_level_scale)) * base_resolution - 1, in float32;
  resolution_l = ceil(scale_l) + 1 (``base_resolution`` counts vertices, not cells);
- rows_l = next_multiple(resolution_l ^ dims, 8), capped at 2^log2_table_size for a hash grid
  (a dense grid keeps them all); the levels' rows follow each other in the one table;
- a vertex (uint32 coordinates c) of level l is row  index % rows_l  of that level, where
  index = sum_d c_d * resolution_l^d (uint32 wrap-around) when resolution_l ^ dims <= rows_l
  (the level fits: dense indexing), else the spatial hash  xor_d (c_d * prime_d)  (uint32);
- a point x (the input, [0, 1] per axis) is p = fma(scale_l, x, 0.5), c = uint(int(floor(p))),
  f = p - floor(p); the 2^dims vertices c + b (b in {0, 1}^dims, bit d of the corner number is
  axis d) are weighted by prod_d (b_d ? f_d : 1 - f_d) and summed in corner order.

The torch twin (components/grids/torch_twin.py) and the GLSL emitter (components/grids/emit.py,
components/grids/hash_grid.glsl) both read the levels from here.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# tiny-cuda-nn's spatial hashes: the prime per axis (common_device.h, prime_hash & co.)
HASH_PRIMES = {
    "coherent_prime": (1, 2654435761, 805459861),
    "prime": (1958374283, 2654435761, 805459861),
    "reversed_prime": (2165219737, 1434869437, 2097192037),
}
GRID_TYPES = ("hash", "dense")
MAX_LEVELS = 32
MAX_LOG2_TABLE = 24
MASK = 0xFFFFFFFF
MAX_DENSE_RESOLUTION = {2: 0xFFFF, 3: 0x659}   # common_device.h grid_index: no uint32 overflow below these
# Finest usable scale: beyond 2^24 float32 p = scale * x + 0.5 keeps no fraction (no interpolation),
# and past 2^31 its int conversion is undefined (torch, GLSL and CUDA then read different rows).
MAX_SCALE = 2.0 ** 24


@dataclass(frozen=True)
class GridLevel:
    scale: np.float32     # p = fma(scale, x, 0.5)
    resolution: int       # vertices per axis
    rows: int             # table rows of the level
    offset: int           # its first row in the table
    dense: bool           # indexed densely (resolution^dims <= rows), else hashed


def level_scale(level: int, per_level_scale: float, base_resolution: int) -> np.float32:
    """exp2f(level * log2f(per_level_scale)) * base_resolution - 1, every step a float32 result.
    log2f and exp2f are correctly rounded here (float64, rounded once), as glibc's are in
    tiny-cuda-nn's host code, which sizes the levels; numpy's float32 ones are up to 2 ulp off. (CUDA's
    device exp2f, which the kernel's scale uses, may differ from both by up to 2 ulp: docs/tcnn.md.)"""
    log2s = np.float32(np.log2(np.float64(np.float32(per_level_scale))))
    with np.errstate(over="ignore"):      # an overflow is inf, refused by grid_levels
        e = np.float32(np.exp2(np.float64(np.float32(np.float32(level) * log2s))))
        return np.float32(np.float32(e * np.float32(base_resolution)) - np.float32(1.0))


class GridLayoutError(ValueError):
    """Levels that float32 cannot lay out (the component check names the node)."""


def grid_levels(dims: int, levels: int, base_resolution: int, per_level_scale: float,
                log2_table_size: int = MAX_LOG2_TABLE, grid: str = "hash") -> list[GridLevel]:
    out, offset = [], 0
    for level in range(levels):
        scale = level_scale(level, per_level_scale, base_resolution)
        if not scale < MAX_SCALE:
            raise GridLayoutError(f"levels: level {level} has scale {float(scale):.4g}, not below 2^24 (float32 "
                                 f"p = scale * x + 0.5 keeps no fraction there): fewer levels, a smaller "
                                 f"base_resolution or per_level_scale")
        resolution = int(np.ceil(scale)) + 1
        full = resolution ** dims
        rows = min(full, MASK // 2)
        rows = -(-rows // 8) * 8
        if grid == "hash":
            rows = min(rows, 1 << log2_table_size)
        dense = resolution <= MAX_DENSE_RESOLUTION[dims] and full <= rows
        out.append(GridLevel(scale, resolution, rows, offset, dense))
        offset += rows
    return out


def table_rows(levels: list[GridLevel]) -> int:
    return levels[-1].offset + levels[-1].rows if levels else 0


def vertex_index(coords: np.ndarray, level: GridLevel, primes: tuple[int, ...]) -> np.ndarray:
    """uint32 coords [..., dims] -> the level-local row (int64), by the rule above."""
    c = np.asarray(coords, np.uint64) & MASK
    dims = c.shape[-1]
    if level.dense:
        index = np.zeros(c.shape[:-1], np.uint64)
        stride = 1
        for d in range(dims):
            index = (index + c[..., d] * np.uint64(stride)) & MASK
            stride *= level.resolution
    else:
        index = np.zeros(c.shape[:-1], np.uint64)
        for d in range(dims):
            index ^= (c[..., d] * np.uint64(primes[d])) & MASK
    return (index % np.uint64(level.rows)).astype(np.int64)
