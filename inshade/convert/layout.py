"""Layout operations (shared by the importers): only the lane array changes, nothing is emitted.
And grid_sample of a constant grid, as a lookup array."""
from __future__ import annotations

import numpy as np

from .lanes import ConvertError, Feat


def reshape(f: Feat, shape, batch_size: int) -> Feat:
    """``f`` viewed as ``shape`` (the full shape: ``batch_size`` on its batch axis). The batch
    axis must keep the elements before it, else rows would mix."""
    before = int(np.prod(f.shape[:f.batch]))
    picks = [a for a, n in enumerate(shape) if n == batch_size and int(np.prod(shape[:a])) == before]
    if not picks or len(picks) > 1 and batch_size != 1:
        raise ConvertError(f"reshape to {list(shape)} merges or splits the batch axis (one pixel's values "
                           "would mix with another's)")
    b = picks[0]
    lanes = f.lanes.reshape([1 if a == b else n for a, n in enumerate(shape)])
    return f.moved(lanes, b)


def permute(f: Feat, dims) -> Feat:
    dims = [d % f.rank for d in dims]
    return f.moved(np.transpose(f.lanes, dims), dims.index(f.batch))


def unsqueeze(f: Feat, dim: int) -> Feat:
    dim = dim % (f.rank + 1)
    return f.moved(np.expand_dims(f.lanes, dim), f.batch + (dim <= f.batch))


def squeeze(f: Feat, dims=None) -> Feat:
    """Size-1 axes removed (``dims``, or every one but the batch axis)."""
    if dims is None:
        dims = [a for a in range(f.rank) if f.shape[a] == 1 and a != f.batch]
    dims = [d % f.rank for d in ([dims] if isinstance(dims, int) else dims)]
    dims = [d for d in dims if f.shape[d] == 1 and d != f.batch]
    lanes = np.squeeze(f.lanes, tuple(dims)) if dims else f.lanes
    return f.moved(lanes, f.batch - sum(d < f.batch for d in dims))


def slice_axis(f: Feat, dim: int, start, end, step, batch_size: int) -> Feat:
    dim = dim % f.rank
    if dim == f.batch:
        if (start in (None, 0)) and (end is None or end >= batch_size) and step in (None, 1):
            return f
        raise ConvertError("slices the batch axis (rows of the batch are pixels: each is computed alone)")
    index = [slice(None)] * f.rank
    index[dim] = slice(start, end, step)
    return f.moved(f.lanes[tuple(index)])


def take(f: Feat, dim: int, index) -> Feat:
    """Elements at constant integer ``index`` (an int drops the axis) along a non-batch axis."""
    dim = dim % f.rank
    if dim == f.batch:
        raise ConvertError("indexes the batch axis (rows of the batch are pixels: each is computed alone)")
    lanes = np.take(f.lanes, index, axis=dim)
    return f.moved(lanes, f.batch - (dim < f.batch and np.ndim(index) == 0))


def expand(f: Feat, shape) -> Feat:
    """``f`` broadcast to the full ``shape`` (new leading axes allowed)."""
    lead = len(shape) - f.rank
    batch = f.batch + lead
    target = [1 if a == batch else n for a, n in enumerate(shape)]
    return f.moved(np.broadcast_to(f.lanes.reshape((1,) * lead + f.shape), target), batch)


def grid_cells(grid: np.ndarray, zeros: bool, align_corners: bool):
    """(cells [N_{d-1}..N_0, C], per-axis coordinate scale s) such that the lookup array at
    u = s g + 1/2 samples what grid_sample samples at g: the unnormalised coordinate is
    (g + 1) / 2 (N - 1) (align_corners) or ((g + 1) N - 1) / 2, clipped to [0, N - 1] (border);
    for zeros the cells get a ring of zeros and the coordinate shifts by one cell."""
    if grid.ndim not in (4, 5) or grid.shape[0] != 1:
        raise ConvertError(f"grid_sample: grid of shape {list(grid.shape)}; expected [1, C, H, W] or [1, C, D, H, W]")
    cells = np.moveaxis(grid[0], 0, -1).astype(np.float32)    # [(D,) H, W, C]
    d = cells.ndim - 1
    if zeros:
        cells = np.pad(cells, [(1, 1)] * d + [(0, 0)])
    scale = []
    for n in (grid.shape[-1 - k] for k in range(d)):          # N_0 = W, N_1 = H, N_2 = D
        if zeros:
            scale.append((n - 1) / (2 * (n + 1)) if align_corners else n / (2 * (n + 1)))
        else:
            scale.append(0.5 if align_corners else (n / (2 * (n - 1)) if n > 1 else 0.0))
    return cells, scale


def grid_sample(L, grid: np.ndarray, coords: Feat, zeros: bool, align_corners: bool) -> Feat:
    """grid_sample (bilinear) of a constant grid [1, C, (D,) H, W] at computed coordinates
    [1, (Do,) Ho, Wo, d] whose batch axis is one of the spatial ones; out [1, C, (Do,) Ho, Wo]."""
    if coords.batch == 0:
        raise ConvertError("grid_sample with the batch on the grid's first axis: sample one shared grid with "
                           "coordinates shaped [1, ..., batch, ..., 2]")
    cells, scale = grid_cells(grid, zeros, align_corners)
    if coords.shape[-1] != len(scale):
        raise ConvertError(f"grid_sample: {coords.shape[-1]} coordinates for a {len(scale)}D grid")
    u = L.affine(coords, np.asarray(scale, np.float32), np.float32(0.5))
    lanes = np.moveaxis(L.lookup(u, cells), -1, 1)    # [1, (Do,) Ho, Wo, C] -> [1, C, (Do,) Ho, Wo]
    return Feat(lanes, coords.batch + 1)
