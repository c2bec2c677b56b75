"""What the torch lowerings read their arguments with: constants as numpy, integer tensors, and
the dtypes torch's trace recorded."""
from __future__ import annotations

import numpy as np
import torch

from ..lanes import IntFeat

INT_DTYPES = (torch.int32, torch.int64)


def floats(c) -> np.ndarray:
    """A constant (tensor, number, list) as float32 numpy."""
    if isinstance(c, torch.Tensor):
        return c.detach().cpu().to(torch.float32).numpy()
    return np.asarray(c, np.float32)


def ints(c) -> np.ndarray:
    """A constant as numpy in its own (integer) dtype."""
    if isinstance(c, torch.Tensor):
        return c.detach().cpu().numpy()
    return np.asarray(c)


def map_ints(obj, fn):
    """``obj`` (nested lists, tuples, dicts) with every integer tensor replaced by ``fn`` of it."""
    if isinstance(obj, IntFeat):
        return fn(obj)
    if isinstance(obj, (list, tuple)):
        return type(obj)(map_ints(o, fn) for o in obj)
    if isinstance(obj, dict):
        return {k: map_ints(v, fn) for k, v in obj.items()}
    return obj


def int_result(node) -> bool:
    """The traced op's result is an integer tensor (torch's type promotion decided it)."""
    val = node.meta.get("val")
    dtype = getattr(val, "dtype", None)
    return dtype is not None and not dtype.is_floating_point and dtype != torch.bool
