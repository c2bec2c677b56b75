"""Torch elementwise ops: activations and the other functions a component computes lane by lane."""
from __future__ import annotations

import numpy as np

from ..lanes import ConvertError, Feat
from ..registry import torch_op
from .common import hard_sigmoid, hard_swish, unary
from .torch_values import floats

# torch names -> the component computing them
for _names, _kind in ((("relu",), "relu"), (("sigmoid",), "sigmoid"), (("tanh",), "tanh"), (("sin",), "sin"),
                      (("cos",), "cos"), (("exp",), "exp"), (("expm1",), "expm1"), (("abs",), "abs"),
                      (("sqrt",), "sqrt"), (("reciprocal",), "reciprocal"), (("silu",), "silu"), (("log",), "log"),
                      (("log2",), "log2"), (("floor",), "floor"), (("ceil",), "ceil"), (("trunc", "fix"), "trunc"),
                      (("frac",), "frac")):
    torch_op(*_names)(unary(_kind))


@torch_op("rsqrt")
def _rsqrt(T, node, f):
    return T.L.unary(T.L.unary(f, "sqrt"), "reciprocal")


@torch_op("square")
def _square(T, node, f):
    return T.L.binary("mul", f, f)


@torch_op("round")
def _round(T, node, f, *args, decimals=0):
    if decimals:
        raise ConvertError(f"round to {decimals} decimals: round to integers is lowered")
    return T.L.unary(f, "round")


@torch_op("leaky_relu")
def _leaky_relu(T, node, f, slope=0.01):
    return T.L.unary(f, "leaky_relu", {"slope": float(slope)})


@torch_op("softplus")
def _softplus(T, node, f, beta=1.0, threshold=20.0):
    return T.L.unary(f, "softplus", {"beta": float(beta), "threshold": float(threshold)})


@torch_op("gelu")
def _gelu(T, node, f, approximate="none"):
    return T.L.unary(f, "gelu", {"approximate": approximate})


@torch_op("elu")
def _elu(T, node, f, alpha=1.0, scale=1.0, input_scale=1.0):
    if input_scale != 1:
        f = T.L.scale(f, input_scale)
    out = T.L.unary(f, "elu", {"alpha": float(alpha)})
    return out if scale == 1 else T.L.affine(out, float(scale), 0.0)


@torch_op("selu")
def _selu(T, node, f):
    out = T.L.unary(f, "elu", {"alpha": 1.6732632423543772848170429916717})
    return T.L.affine(out, np.float32(1.0507009873554804934193349852946), 0.0)


@torch_op("clamp")
def _clamp(T, node, f, lo=None, hi=None):
    if isinstance(lo, Feat) or isinstance(hi, Feat):
        raise ConvertError("clamp bounds must be constants")
    lo, hi = (None if v is None else floats(v) for v in (lo, hi))
    if lo is not None and lo.size > 1 or hi is not None and hi.size > 1:
        raise ConvertError("clamp with tensor bounds: only scalar bounds are lowered")
    params = {k: float(v) for k, v in (("min", lo), ("max", hi)) if v is not None}
    return T.L.unary(f, "clamp", params) if params else f


@torch_op("clamp_min")
def _clamp_min(T, node, f, lo):
    return _clamp(T, node, f, lo, None)


@torch_op("clamp_max")
def _clamp_max(T, node, f, hi):
    return _clamp(T, node, f, None, hi)


@torch_op("hardtanh")
def _hardtanh(T, node, f, lo=-1.0, hi=1.0):
    return T.L.unary(f, "clamp", {"min": float(lo), "max": float(hi)})


@torch_op("relu6")
def _relu6(T, node, f):
    return T.L.unary(f, "clamp", {"min": 0.0, "max": 6.0})


@torch_op("hardsigmoid")
def _hardsigmoid(T, node, f):
    return hard_sigmoid(T.L, f)


@torch_op("hardswish")
def _hardswish(T, node, f):
    return hard_swish(T.L, f)


@torch_op("mish")
def _mish(T, node, f):
    return T.L.binary("mul", f, T.L.unary(T.L.unary(f, "softplus", {"beta": 1.0, "threshold": 20.0}), "tanh"))
