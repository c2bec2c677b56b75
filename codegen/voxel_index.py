"""Cell -> slot indexes of sparse multi-scale voxels (component sparse_voxels, param ``index``);
numpy only. Every index answers the same question, P_voxel_slot(scale, cell) = slot + 1 of the
voxel at that cell (0 = empty, outside the grid or the scale range), so the choice changes memory
and fetch count, never an image.

- ``dense``: ONE R32UI 3D texture, a mip chain: level L = scale scale_max - L, 2^scale texels per
  axis, texel (i, j, k) = cell (i, j, k) holding slot + 1. One fetch; (2^s)^3 texels per scale.
- ``bricks``: two R32UI tables in rows of 2^n texels (texture_rows.row_layout). Scale s is cut into
  bricks of B^3 cells (B = param ``brick``: 2, 4 or 8), m_s = max(1, 2^s / B) bricks per axis.
  ``top`` holds one texel per brick of every scale, scale_min first: brick (bi, bj, bk) = cell >> log2 B
  of scale s at top_offset[s - scale_min] + (bk m_s + bj) m_s + bi, holding row + 1 of its brick in
  ``bricks`` (0: no voxel in it). ``bricks`` holds B^3 texels per occupied brick: cell (i, j, k) at
  row B^3 + ((k & (B-1)) B + (j & (B-1))) B + (i & (B-1)), holding slot + 1 (0: empty). Two
  dependent fetches; memory grows with the occupied bricks, not with the grid.

Both are built here from ``cells``, so every non-zero entry points at a row < N.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import ir
from .glsl import TextureResource
from .limits import LimitError, limit, source
from .texture_rows import row_layout, rows_data

INDEXES = ("dense", "bricks")
BRICK_SIDES = (2, 4, 8)
TEXEL_BYTES = 4   # R32UI


def index_grid(cells: np.ndarray, scale_min: int, scale_max: int) -> list[np.ndarray]:
    """The dense grid's levels, finest first: level L is [n, n, n, 1] uint32 (n = 2^(scale_max - L)),
    indexed [k, j, i], holding slot + 1 (0 = empty)."""
    cells = np.asarray(cells, np.int64)
    levels = []
    for scale in range(scale_max, scale_min - 1, -1):
        n = 1 << scale
        grid = np.zeros((n, n, n, 1), np.uint32)
        rows = np.flatnonzero(cells[:, 0] == scale)
        grid[cells[rows, 3], cells[rows, 2], cells[rows, 1], 0] = (rows + 1).astype(np.uint32)
        levels.append(grid)
    return levels


@dataclass(frozen=True)
class BrickIndex:
    """The two tables of the ``bricks`` index (module docstring): ``top`` uint32 [T], ``bricks``
    uint32 [R * B^3], ``offsets`` (top_offset per scale, scale_min first), ``brick`` B."""
    top: np.ndarray
    bricks: np.ndarray
    offsets: tuple
    brick: int
    scale_min: int
    scale_max: int

    @property
    def log2b(self) -> int:
        return self.brick.bit_length() - 1

    @property
    def nbytes(self) -> int:
        return TEXEL_BYTES * (self.top.size + self.bricks.size)


def _check_brick(brick) -> int:
    if isinstance(brick, bool) or brick not in BRICK_SIDES:
        raise ValueError(f"brick: must be one of {list(BRICK_SIDES)}, got {brick!r}")
    return int(brick)


def bricks_per_axis(scale: int, brick: int) -> int:
    return max(1, (1 << scale) // brick)


def _brick_keys(cells: np.ndarray, scale: int, brick: int) -> tuple[np.ndarray, np.ndarray]:
    """(rows of the scale's cells, their brick key (bk m + bj) m + bi)."""
    rows = np.flatnonzero(cells[:, 0] == scale)
    m = bricks_per_axis(scale, brick)
    b = cells[rows, 1:4] // brick
    return rows, (b[:, 2] * m + b[:, 1]) * m + b[:, 0]


def brick_index(cells: np.ndarray, scale_min: int, scale_max: int, brick: int) -> BrickIndex:
    """The ``bricks`` index of `cells` [N, 4] (scale, i, j, k)."""
    brick = _check_brick(brick)
    cells = np.asarray(cells, np.int64)
    b3 = brick ** 3
    tops, blocks, offsets, offset, first = [], [], [], 0, 0
    for scale in range(scale_min, scale_max + 1):
        m = bricks_per_axis(scale, brick)
        rows, key = _brick_keys(cells, scale, brick)
        uniq, which = np.unique(key, return_inverse=True)
        top = np.zeros(m ** 3, np.uint32)
        top[uniq] = first + np.arange(1, len(uniq) + 1, dtype=np.uint32)
        block = np.zeros((len(uniq), b3), np.uint32)
        local = cells[rows, 1:4] & (brick - 1)
        block[which, (local[:, 2] * brick + local[:, 1]) * brick + local[:, 0]] = (rows + 1).astype(np.uint32)
        tops.append(top)
        blocks.append(block.reshape(-1))
        offsets.append(offset)
        offset += m ** 3
        first += len(uniq)
    return BrickIndex(np.concatenate(tops), np.concatenate(blocks), tuple(offsets), brick, scale_min, scale_max)


def brick_slot(index: BrickIndex, scale, cell) -> np.ndarray:
    """slot + 1 (0 = empty) of cells [K, 3] (i, j, k) at `scale` (an int or [K]): the lookup the
    GLSL function runs, in numpy (out of the grid or the scale range: 0)."""
    cell = np.asarray(cell, np.int64).reshape(-1, 3)
    scale = np.broadcast_to(np.asarray(scale, np.int64), cell.shape[:1])
    out = np.zeros(len(cell), np.uint32)
    n = np.left_shift(1, np.clip(scale, 0, 62))
    ok = (scale >= index.scale_min) & (scale <= index.scale_max) & (cell >= 0).all(1) & (cell < n[:, None]).all(1)
    s, c = scale[ok], cell[ok]
    m = np.maximum(n[ok] >> index.log2b, 1)
    b = c >> index.log2b
    offsets = np.asarray(index.offsets, np.int64)
    top = index.top[offsets[s - index.scale_min] + (b[:, 2] * m + b[:, 1]) * m + b[:, 0]].astype(np.int64)
    local = c & (index.brick - 1)
    lane = (local[:, 2] * index.brick + local[:, 1]) * index.brick + local[:, 0]
    slot = np.where(top > 0, index.bricks[np.maximum(top - 1, 0) * index.brick ** 3 + lane], 0)
    out[ok] = slot
    return out


def dense_bytes(scale_min: int, scale_max: int) -> int:
    """Bytes of the dense grid's mip chain: (2^s)^3 R32UI texels for each scale."""
    return TEXEL_BYTES * sum(1 << (3 * s) for s in range(scale_min, scale_max + 1))


def brick_bytes(cells: np.ndarray, scale_min: int, scale_max: int, brick: int) -> int:
    """Bytes of the ``bricks`` tables (before row padding), without building them."""
    brick = _check_brick(brick)
    cells = np.asarray(cells, np.int64)
    texels = 0
    for scale in range(scale_min, scale_max + 1):
        texels += bricks_per_axis(scale, brick) ** 3 + len(np.unique(_brick_keys(cells, scale, brick)[1])) * brick ** 3
    return TEXEL_BYTES * texels


def best_brick(cells: np.ndarray, scale_min: int, scale_max: int) -> int:
    """The brick side of BRICK_SIDES with the fewest index bytes for these cells (ties: the larger
    side, which has the smaller top table)."""
    return min(BRICK_SIDES[::-1], key=lambda b: brick_bytes(cells, scale_min, scale_max, b))


def index_bytes(cells: np.ndarray, params: dict) -> int:
    """Index bytes of a sparse_voxels node's params (``index``, ``brick``, scale range)."""
    kind = params.get("index", "dense")
    if kind == "dense":
        return dense_bytes(params["scale_min"], params["scale_max"])
    return brick_bytes(cells, params["scale_min"], params["scale_max"], params.get("brick", 4))


# --- lowered code (components/sparse_voxels/sparse_voxels.glsl and its other languages) --------------

def _in_range(up: str) -> tuple:
    """The arguments every index's lookup ends with: the query and the node's scale range."""
    return ir.Var("scale"), ir.Var("cell"), ir.Var(f"{up}_SCALE_MIN"), ir.Var(f"{up}_SCALE_MAX")


def emit_dense(ctx, node, cells, up: str):
    """(resources, module-level declarations, the lookup P_voxel_slot returns, plan text) of the dense grid."""
    p = node.params
    smin, smax = p["scale_min"], p["scale_max"]
    cap3 = limit(ctx.limits, "GL_MAX_3D_TEXTURE_SIZE")
    if (1 << smax) > cap3:
        raise LimitError(f"node {node.id}: the index grid of scale {smax} is {1 << smax}^3 texels; "
                         f"GL_MAX_3D_TEXTURE_SIZE is {cap3} ({source(ctx.limits, 'GL_MAX_3D_TEXTURE_SIZE')})")
    grid = ctx.name(node.id, "grid")
    chain = index_grid(cells, smin, smax)
    decls = [ir.Texture(grid, f"{node.id}: slot + 1 per cell (0 = empty); mip level L = scale {smax} - L",
                        dims=3, integer=True)]
    lookup = ir.Call("sv_slot_dense", (ir.TextureArg(grid), *_in_range(up)), "uint")
    plan = f"R32UI 3D index grid {1 << smax}^3 with {smax - smin + 1} levels"
    return [TextureResource(grid, chain[0], "u4", mips=tuple(chain[1:]))], decls, lookup, plan


def emit_bricks(ctx, node, cells, up: str):
    """(resources, module-level declarations, the lookup P_voxel_slot returns, plan text) of the
    two-level brick index."""
    p = node.params
    index = brick_index(cells, p["scale_min"], p["scale_max"], p["brick"])
    b, lb = index.brick, index.log2b
    top, bricks = ctx.name(node.id, "top"), ctx.name(node.id, "bricks")
    top_log2w, top_rows = row_layout(node.id, f"brick index top table ({index.top.size} bricks)", index.top.size,
                                     ctx.limits)
    brk_log2w, brk_rows = row_layout(node.id, f"brick index ({index.bricks.size // b ** 3} bricks of {b}^3)",
                                     max(index.bricks.size, 1), ctx.limits)
    bricks_data = index.bricks if index.bricks.size else np.zeros(1, np.uint32)
    resources = [TextureResource(top, rows_data(index.top[:, None], top_log2w, top_rows), "u4"),
                 TextureResource(bricks, rows_data(bricks_data[:, None], brk_log2w, brk_rows), "u4")]
    offsets = f"{up}_BRICK_TOP_OFFSET"
    decls = [ir.Texture(top, f"{node.id}: brick row + 1 per {b}^3 brick of each scale (0 = none)", integer=True),
             ir.Texture(bricks, f"{node.id}: slot + 1 per cell of each occupied brick (0 = empty)", integer=True),
             ir.ConstArray("uint", offsets, tuple(ir.Int(f"{o}u") for o in index.offsets))]
    # the scale's first brick in the top table (clamped: a scale outside the range reads none)
    scale = ir.Call("clamp", (ir.Int(f"scale - {up}_SCALE_MIN"), ir.Int("0"), ir.Int(str(len(index.offsets) - 1))),
                    "int")
    lookup = ir.Call("sv_slot_bricks", (ir.TextureArg(top), ir.Int(str(top_log2w)), ir.TextureArg(bricks),
                                        ir.Int(str(brk_log2w)), ir.Int(str(lb)), ir.Index(ir.Var(offsets), scale),
                                        *_in_range(up)), "uint")
    plan = (f"R32UI brick index: top {index.top.size} texels + {index.bricks.size // b ** 3} bricks of {b}^3 "
            f"(rows of {1 << top_log2w} / {1 << brk_log2w})")
    return resources, decls, lookup, plan


EMIT = {"dense": emit_dense, "bricks": emit_bricks}
