"""Tensors as lanes: what a lowering computes with. Every tensor the network computes is a ``Feat``:
its shape with the batch axis held at size 1, and for each element the *lane* that holds it (one
float of a bundle value, numbered globally). Integer tensors (``IntFeat``) hold entries of the
lowering's uint32 program instead. Numpy only."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


class Float64Unavailable(Exception):
    """A source cannot be evaluated in float64 (the message says why): the check then judges by the
    1e-5 rule alone."""


class ConvertError(ValueError):
    """A network (or a part of it) that cannot become a bundle; the message is one line."""


@dataclass(frozen=True)
class Feat:
    """A computed tensor: ``lanes`` has the tensor's shape with the batch axis (``batch``) at size 1;
    ``pending`` is a scalar multiply not yet emitted (sin / cos take it as their omega0)."""
    lanes: np.ndarray
    batch: int
    pending: float | None = None

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(self.lanes.shape)

    @property
    def rank(self) -> int:
        return self.lanes.ndim

    def moved(self, lanes: np.ndarray, batch: int | None = None) -> "Feat":
        """The same kind of tensor over rearranged lanes (layout operations)."""
        return replace(self, lanes=lanes, batch=self.batch if batch is None else batch)


@dataclass(frozen=True)
class IntFeat(Feat):
    """An integer tensor: ``lanes`` holds entries of the lowering's uint32 program
    (``Lowering.int_program``), not float lanes. Integers become bundle values only where a table
    is read at them (``gather``, one ``int_gather`` node) or a cast value is used as a float again."""



def const_against(c, f: Feat, batch_size: int, dtype=np.float32) -> np.ndarray:
    """A constant combined with ``f``. Graphs often build one as wide as the batch (ones_like(x),
    torch.ones(x.shape[0], 1)): such a constant is one row, if every row is the same."""
    a = np.asarray(c, dtype)
    if a.ndim == f.rank and a.shape[f.batch] == batch_size and batch_size > 1:
        first = np.take(a, [0], axis=f.batch)
        if not np.array_equal(np.broadcast_to(first, a.shape), a):
            raise ConvertError("a constant that differs from row to row of the batch (one pixel's value would "
                               "depend on its index in the batch)")
        a = first
    return a


def constant_in(a: np.ndarray, batch: int, rank: int) -> np.ndarray:
    """A constant broadcast against a rank-``rank`` tensor must not vary along its batch axis."""
    full = a.reshape((1,) * (rank - a.ndim) + a.shape)
    if full.shape[batch] != 1:
        raise ConvertError(f"a constant of shape {list(a.shape)} varies along the batch axis (one pixel's value "
                           "would depend on its index in the batch)")
    return full



def shape_text(shape) -> str:
    return "[" + ", ".join("*" if n is None else str(n) for n in shape) + "]"
