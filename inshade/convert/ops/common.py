"""Lowerings the torch and ONNX tables share: elementwise components, comparisons kept until a
choice uses them, and the pieces of concatenation, splitting and einsum that do not depend on
how the source names its arguments."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lanes import ConvertError, Feat, const_against
from ..layout import slice_axis


@dataclass(frozen=True)
class Condition:
    """A comparison of values, kept until a where chooses with it (a shader has no boolean
    tensors: the comparison and the choice are one ``where`` node)."""
    op: str
    a: object
    b: object


def unary(kind: str, **fixed):
    """The elementwise component ``kind`` (with ``fixed`` params) of the first input."""
    def lower(walk, node, f, *_, **__):
        return walk.L.unary(f, kind, dict(fixed))
    return lower


def compare(op: str):
    def lower(walk, node, a, b):
        return Condition(op, a, b)
    return lower


def identity(walk, node, f, *_, **__):
    return f


def choose(refusal: str):
    """where(cond, x, y): cond a comparison, or a constant mask; ``refusal`` for any other."""
    def lower(walk, node, cond, x, y):
        if isinstance(cond, Condition):
            return walk.L.where(cond.op, cond.a, cond.b, x, y)
        if not isinstance(cond, Feat):   # a constant mask
            return walk.L.where("gt", walk.array(cond), np.float32(0.5), x, y)
        raise ConvertError(refusal)
    return lower


def hard_sigmoid(L, f: Feat, alpha=1 / 6, beta=0.5) -> Feat:
    return L.unary(L.affine(f, np.float32(alpha), np.float32(beta)), "clamp", {"min": 0.0, "max": 1.0})


def hard_swish(L, f: Feat) -> Feat:
    return L.binary("mul", f, hard_sigmoid(L, f))


def split_at(f: Feat, axis: int, sizes, batch_size: int) -> tuple:
    """``f`` cut along ``axis`` into parts of ``sizes``."""
    bounds = np.cumsum([0, *sizes])
    return tuple(slice_axis(f, axis, int(a), int(b), 1, batch_size) for a, b in zip(bounds[:-1], bounds[1:]))


def concat_floats(walk, like: Feat, tensors, axis: int) -> Feat:
    """Float tensors and constants side by side along a non-batch ``axis``; ``like`` (resolved)
    gives the batch axis, and constants become lanes shaped against it."""
    if axis == like.batch:
        raise ConvertError("concatenates along the batch axis")
    parts = []
    for t in tensors:
        if isinstance(t, Feat):
            t = walk.L.resolve(t)
            if t.batch != like.batch:
                raise ConvertError("concatenates tensors whose batch axes differ")
            parts.append(t.lanes)
        else:
            c = const_against(walk.array(t), like, walk.batch)
            if c.size:
                parts.append(walk.L.constant(like, c).lanes)
    return Feat(np.concatenate(parts, axis), like.batch)


def einsum_of_one(walk, op: str, operands, contract) -> Feat:
    """An einsum of one computed value with constants: linear in it, so one dense layer.
    ``contract(k, basis)``: the einsum with ``basis`` (float64) in place of operand k."""
    feats = [i for i, t in enumerate(operands) if isinstance(t, Feat)]
    if len(feats) != 1:
        raise ConvertError(f"{op} of several computed values (an {op} of one value with constants is lowered)")
    k = feats[0]
    return walk.L.linear_map(operands[k], lambda basis: contract(k, basis))


def negate(walk, node, f, *_, **__):
    return walk.L.affine(f, -1.0, 0.0)
