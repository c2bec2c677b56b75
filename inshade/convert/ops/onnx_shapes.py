"""ONNX layout ops (Concat, Slice, Split, Reshape, Gather, ...): only the lane arrays change. Shapes
and axes are the whole tensor's: ``O.axis`` maps an ONNX axis onto the lowered tensor's."""
from __future__ import annotations

import numpy as np

from ..lanes import ConvertError, Feat, IntFeat
from ..layout import expand, permute, reshape, slice_axis, squeeze, take, unsqueeze
from ..registry import onnx_op
from .common import concat_floats, split_at


@onnx_op("Concat", takes_ints=True)
def _concat(O, node, *ins, axis, **_):
    feats = [O.L.resolve(v) for v in ins if isinstance(v, Feat)]
    like = feats[0]
    if isinstance(like, IntFeat):
        parts = [O.L.int_operand(v, like, O.batch) for v in ins if isinstance(v, Feat) or np.size(v)]
        return like.moved(np.concatenate([p.lanes for p in parts], O.axis(like, axis)))
    return concat_floats(O, like, ins, O.axis(like, axis))


@onnx_op("Slice", takes_ints=True)
def _slice(O, node, f, starts, ends, axes=None, steps=None, **_):
    starts, ends = O.ints(starts, "Slice starts"), O.ints(ends, "Slice ends")
    axes = O.ints(axes, "Slice axes") if axes is not None else list(range(len(starts)))
    steps = O.ints(steps, "Slice steps") if steps is not None else [1] * len(starts)
    for s, e, a, st in zip(starts, ends, axes, steps):
        a = O.axis(f, a)
        n = O.batch if a == f.batch else f.shape[a]
        s, e = _clip_index(s, n, st), _clip_index(e, n, st)
        if a == f.batch:
            if s == 0 and e >= n and st == 1:
                continue
            raise ConvertError("slices the batch axis (rows of the batch are pixels: each is computed alone)")
        f = slice_axis(f, a, s, e if e >= 0 else None, st, O.batch)
    return f


def _clip_index(i: int, n: int, step: int) -> int:
    """An ONNX Slice bound clamped as the spec says ([0, n] forwards, [-1, n - 1] backwards)."""
    i = i + n if i < 0 else i
    return int(min(max(i, 0), n)) if step > 0 else int(min(max(i, -1), n - 1))


@onnx_op("Split", takes_ints=True)
def _split(O, node, f, split=None, *, axis=0, num_outputs=0, **_):
    axis = O.axis(f, axis)
    if axis == f.batch:
        raise ConvertError("splits the batch axis")
    n = f.shape[axis]
    if split is not None:   # an input since opset 13, an attribute before
        sizes = O.ints(split, "Split split")
    else:
        parts = int(num_outputs) or len(node.output)
        size = -(-n // parts)
        sizes = [min(size, n - k * size) for k in range(parts)]
    return split_at(f, axis, sizes, O.batch)


def listed_axes(O, axes, name: str) -> list[int]:
    """The axes of Squeeze, Unsqueeze, Reduce* (an input since opset 13, 18 for most Reduce*; an
    attribute before): none when not given."""
    return O.ints(axes, f"{name} axes") if axes is not None else []


@onnx_op("Squeeze", takes_ints=True, whole_shape=True)
def _squeeze(O, node, f, axes=None, **_):
    return squeeze(f, listed_axes(O, axes, "Squeeze") or None)


@onnx_op("Unsqueeze", takes_ints=True, whole_shape=True)
def _unsqueeze(O, node, f, axes=None, **_):
    axes = listed_axes(O, axes, "Unsqueeze")
    rank = f.rank + len(axes)
    for a in sorted(x % rank for x in axes):
        f = unsqueeze(f, a)
    return f


@onnx_op("Reshape", takes_ints=True, whole_shape=True)
def _reshape(O, node, f, target, allowzero=0, **_):
    target = O.ints(target, "Reshape shape")
    full = O.full_shape(f)
    shape = [full[i] if (t == 0 and not int(allowzero)) else t for i, t in enumerate(target)]
    if -1 in shape:
        known = int(np.prod([s for s in shape if s != -1]))
        shape[shape.index(-1)] = int(np.prod(full)) // max(known, 1)
    return reshape(f, shape, O.batch)


@onnx_op("Flatten", takes_ints=True, whole_shape=True)
def _flatten(O, node, f, axis=1, **_):
    full = O.full_shape(f)
    axis = int(axis)
    axis = axis + f.rank if axis < 0 else axis   # ONNX: in [-r, r]
    return reshape(f, [int(np.prod(full[:axis])), int(np.prod(full[axis:]))], O.batch)


@onnx_op("Transpose", takes_ints=True, whole_shape=True)
def _transpose(O, node, f, perm=None, **_):
    return permute(f, perm if perm is not None else list(reversed(range(f.rank))))


@onnx_op("Gather", takes_ints=True)
def _gather(O, node, f, idx, axis=0, **_):
    if isinstance(idx, IntFeat):
        if isinstance(f, Feat) or axis != 0:
            raise ConvertError("Gather at computed indices: a constant table along axis 0 is lowered")
        return O.L.gather(np.asarray(f, np.float32), idx)
    indices = np.asarray(O.const(idx, "Gather indices")).astype(np.int64)
    axis = O.axis(f, axis)
    n = f.shape[axis]
    return take(f, axis, np.where(indices < 0, indices + n, indices))


@onnx_op("GatherND", takes_ints=True)
def _gather_nd(O, node, f, idx, batch_dims=0, **_):
    """GatherND of a constant table at computed indices [..., 1] (how torch.onnx writes table[idx])."""
    if (not isinstance(idx, IntFeat) or isinstance(f, Feat) or batch_dims or idx.shape[-1] != 1
            or idx.batch == idx.rank - 1):
        raise ConvertError("GatherND: a constant table read at computed indices [..., 1] (batch_dims 0) is lowered")
    return O.L.gather(np.asarray(f, np.float32), squeeze(idx, [idx.rank - 1]))


@onnx_op("Expand", takes_ints=True, whole_shape=True)
def _expand(O, node, f, target, **_):
    target = O.ints(target, "Expand shape")
    full = O.full_shape(f)
    rank = max(len(target), f.rank)
    a = [1] * (rank - len(full)) + full
    b = [1] * (rank - len(target)) + target
    return expand(f, [x if y == 1 else y for x, y in zip(a, b)])


@onnx_op("Shape", takes_ints=True, whole_shape=True)
def _shape(O, node, f, start=0, end=None, **_):
    return np.asarray(O.full_shape(f), np.int64)[start:end]
