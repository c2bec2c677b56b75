"""Torch layout ops (view, permute, slice, cat, index, ...): only the lane arrays change. And the
ops that change nothing a shader computes (copies, casts between float types, eval-mode dropout)."""
from __future__ import annotations

import math

import numpy as np
import torch

from ..lanes import ConvertError, Feat, IntFeat
from ..layout import expand, permute, reshape, slice_axis, squeeze, take, unsqueeze
from ..registry import torch_op
from .common import concat_floats, identity, split_at
from .torch_values import INT_DTYPES, floats, ints, int_result, map_ints

torch_op("contiguous", "clone", "alias", "detach", takes_ints=True)(identity)
torch_op("type_as")(identity)


@torch_op("view", "reshape", "_unsafe_view", "flatten", "unflatten", takes_ints=True)
def _reshape(T, node, f, *_):
    return reshape(f, T.out_shape(node), T.batch)


@torch_op("permute", takes_ints=True)
def _permute(T, node, f, dims):
    return permute(f, dims)


@torch_op("transpose", takes_ints=True)
def _transpose(T, node, f, a=0, b=1):
    dims = list(range(f.rank))
    a, b = a % f.rank, b % f.rank
    dims[a], dims[b] = dims[b], dims[a]
    return permute(f, dims)


@torch_op("t", takes_ints=True)
def _t(T, node, f):
    return permute(f, [1, 0]) if f.rank == 2 else f


@torch_op("unsqueeze", takes_ints=True)
def _unsqueeze(T, node, f, dim):
    return unsqueeze(f, dim)


@torch_op("squeeze", takes_ints=True)
def _squeeze(T, node, f, dims=None):
    return squeeze(f, dims)


@torch_op("expand", takes_ints=True)
def _expand(T, node, f, sizes, *_):
    return expand(f, T.out_shape(node))


@torch_op("expand_as", takes_ints=True)
def _expand_as(T, node, f, other):
    return expand(f, T.out_shape(node))


@torch_op("slice", takes_ints=True)
def _slice(T, node, f, dim=0, start=None, end=None, step=1):
    return slice_axis(f, dim, start, end, step, T.batch)


@torch_op("select", takes_ints=True)
def _select(T, node, f, dim, index):
    return take(f, dim, index)


@torch_op("narrow", takes_ints=True)
def _narrow(T, node, f, dim, start, length):
    return slice_axis(f, dim, start, start + length, 1, T.batch)


@torch_op("split", "split_with_sizes", takes_ints=True)
def _split(T, node, f, sizes, dim=0):
    dim = dim % f.rank
    n = f.shape[dim]
    if isinstance(sizes, int):
        sizes = [min(sizes, n - s) for s in range(0, n, sizes)]
    return split_at(f, dim, sizes, T.batch)


@torch_op("chunk", takes_ints=True)
def _chunk(T, node, f, chunks, dim=0):
    n = f.shape[dim % f.rank]
    return _split(T, node, f, math.ceil(n / chunks), dim)


@torch_op("unbind", takes_ints=True)
def _unbind(T, node, f, dim=0):
    return tuple(take(f, dim, i) for i in range(f.shape[dim % f.rank]))


@torch_op("cat", "concat", takes_ints=True)
def _cat(T, node, tensors, dim=0):
    feats = [t for t in tensors if isinstance(t, Feat)]
    if any(isinstance(t, IntFeat) for t in feats):
        if not int_result(node):
            return _cat(T, node, map_ints(list(tensors), T.L.int_to_float), dim)
        like = next(t for t in feats if isinstance(t, IntFeat))
        parts = [T.L.int_operand(t if isinstance(t, IntFeat) else ints(t), like, T.batch) for t in tensors]
        if any(p.batch != like.batch for p in parts):
            raise ConvertError("concatenates tensors whose batch axes differ")
        return like.moved(np.concatenate([p.lanes for p in parts], dim % like.rank))
    like = T.L.resolve(feats[0])
    return concat_floats(T, like, tensors, dim % like.rank)


@torch_op("stack", takes_ints=True)
def _stack(T, node, tensors, dim=0):
    feats = [t for t in tensors if isinstance(t, Feat)]
    rank = feats[0].rank + 1
    dim = dim % rank
    return _cat(T, node, [unsqueeze(t, dim) if isinstance(t, Feat) else torch.as_tensor(t).unsqueeze(dim)
                          for t in tensors], dim)


@torch_op("index", takes_ints=True)
def _index(T, node, f, indices):
    """x[..., idx] with constant integer indices on one non-batch axis, or table[idx] with a
    computed integer index into a constant table."""
    picks = [(a, i) for a, i in enumerate(indices) if i is not None]
    if len(picks) == 1 and picks[0][0] == 0 and isinstance(picks[0][1], IntFeat) and not isinstance(f, Feat):
        return T.L.gather(floats(f), picks[0][1])
    if any(isinstance(i, IntFeat) for _, i in picks):
        raise ConvertError("indexing with a computed integer: a constant table's first axis, table[idx], is lowered")
    if len(picks) != 1 or isinstance(picks[0][1], Feat):
        raise ConvertError("indexing: only one constant integer index tensor on one non-batch axis is lowered")
    axis, idx = picks[0]
    if axis == f.batch:
        raise ConvertError("indexes the batch axis")
    idx = torch.as_tensor(idx)
    if idx.dtype == torch.bool:
        idx = idx.nonzero().reshape(-1)
    return _index_select(T, node, f, axis, idx)


@torch_op("index_select", takes_ints=True)
def _index_select(T, node, f, dim, idx):
    return take(f, dim, np.asarray(torch.as_tensor(idx).cpu().numpy()).astype(np.int64))


@torch_op("repeat", takes_ints=True)
def _repeat(T, node, f, repeats):
    reps = list(repeats)
    lead = len(reps) - f.rank
    lanes = f.lanes.reshape((1,) * lead + f.shape)
    batch = f.batch + lead
    if reps[batch] != 1:
        raise ConvertError("repeats the batch axis")
    return f.moved(np.tile(lanes, reps), batch)


@torch_op("flip", takes_ints=True)
def _flip(T, node, f, dims):
    dims = [d % f.rank for d in dims]
    if f.batch in dims:
        raise ConvertError("flips the batch axis")
    return f.moved(np.flip(f.lanes, dims))


@torch_op("_to_copy", "to", takes_ints=True)
def _to_copy(T, node, f, *args, dtype=None, **kwargs):
    dtype = dtype or next((a for a in args if isinstance(a, torch.dtype)), None)
    if dtype in INT_DTYPES:
        return T.L.to_int(f)
    if dtype is not None and dtype not in (torch.float32, torch.float16, torch.float64):
        raise ConvertError(f"converts a computed value to {dtype} (shader values are float32 or integer lanes "
                           f"of {', '.join(str(d) for d in INT_DTYPES)})")
    return T.L.int_to_float(f) if isinstance(f, IntFeat) else f


@torch_op("dropout", "feature_dropout", "alpha_dropout")
def _dropout(T, node, f, p=0.5, train=False, *args):
    if train:
        raise ConvertError("dropout in train mode is random: call module.eval() before exporting")
    return f


@torch_op("_assert_tensor_metadata", takes_ints=True)
def _no_op(T, node, *args, **kwargs):
    """Trace-time assertions torch.export records (shapes, dtypes): nothing to compute."""
    return None
