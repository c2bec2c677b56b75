"""Where a port's rows sit in the arrays a user holds (numpy only).

A shader computes one row per pixel. An exporter often writes tensors of other ranks: ``[1, N, F]``,
``[H, W, F]``, ``[3, 4, 5]``. A port's ``shape`` (bundle.json) is its full tensor shape with
``null`` on the batch axes, e.g. ``[null, 5]`` (plain rows, the default), ``[1, null, 5]``,
``[null, null, 3]`` (an image as H x W rows) or ``[3, null, 5]`` (the middle axis is the batch,
each row holds 3 x 5 lanes). Rows are the batch axes flattened in order, each row the remaining
axes flattened in order (C order both).
"""
from __future__ import annotations

import numpy as np


class LayoutError(ValueError):
    """An array that does not fit a port's shape; the message is one line."""


def port_shape(port) -> list:
    """The port's full shape, ``None`` on the batch axes (plain ``[None, dim]`` when it has none)."""
    shape = getattr(port, "shape", None)
    return list(shape) if shape else [None, port.dim]


def batch_axes(shape) -> list[int]:
    return [a for a, n in enumerate(shape) if n is None]


def to_rows(array: np.ndarray, shape, what: str) -> tuple[np.ndarray, tuple]:
    """(rows [B, row lanes], the batch axes' sizes) of ``array`` laid out as ``shape``."""
    a = np.asarray(array)
    axes = batch_axes(shape)
    fixed = [n for n in shape if n is not None]
    if a.ndim != len(shape) or any(a.shape[i] != n for i, n in enumerate(shape) if n is not None):
        want = "[" + ", ".join("*" if n is None else str(n) for n in shape) + "]"
        raise LayoutError(f"{what}: shape {list(a.shape)}; expected {want} (* = any: the batch)")
    rest = [i for i in range(a.ndim) if i not in axes]
    sizes = tuple(a.shape[i] for i in axes)
    return np.transpose(a, axes + rest).reshape(int(np.prod(sizes, dtype=np.int64)), int(np.prod(fixed))), sizes


def from_rows(rows: np.ndarray, shape, sizes: tuple) -> np.ndarray:
    """The inverse of ``to_rows``: rows [B, lanes] back to ``shape`` with the batch axes ``sizes``."""
    axes = batch_axes(shape)
    rest = [i for i in range(len(shape)) if i not in axes]
    moved = np.asarray(rows).reshape(*sizes, *(shape[i] for i in rest))
    return np.transpose(moved, np.argsort(axes + rest))


def check_shape(shape, dim: int) -> str | None:
    """Why ``shape`` is not a valid port shape of ``dim`` lanes, or None."""
    if not isinstance(shape, list) or not shape:
        return "must be a non-empty list"
    if not any(n is None for n in shape):
        return "needs at least one null (a batch axis)"
    if any(n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 1) for n in shape):
        return "sizes must be positive ints or null"
    lanes = int(np.prod([n for n in shape if n is not None]))
    if lanes != dim:
        return f"its non-batch axes hold {lanes} lanes, the port {dim}"
    return None
