"""ONNX layers: products with constant weights (Gemm, MatMul, Einsum), normalisations, reductions
and Softmax, and GridSample of a constant grid."""
from __future__ import annotations

import numpy as np

from ..lanes import ConvertError, Feat
from ..layout import grid_sample, permute, squeeze
from ..registry import onnx_op
from .common import einsum_of_one
from .onnx_elementwise import text
from .onnx_shapes import listed_axes


@onnx_op("Gemm", whole_shape=True)
def _gemm(O, node, a, b, c=None, transA=0, transB=0, alpha=1.0, beta=1.0, **_):
    if not isinstance(a, Feat) or isinstance(b, Feat) or isinstance(c, Feat):
        raise ConvertError("Gemm of a computed A with constant B and C is lowered")
    if transA:
        a = permute(a, [1, 0])
    w = O.array(b)
    w = w if transB else w.T
    alpha, beta = float(alpha), float(beta)
    if alpha != 1.0:
        w = (w * np.float32(alpha)).astype(np.float32)
    bias = None if c is None else (O.array(c) * np.float32(beta)).reshape(-1)
    if bias is not None and bias.size not in (1, w.shape[0]):
        raise ConvertError(f"Gemm: C of {bias.size} values for {w.shape[0]} outputs (a per-row C mixes the batch)")
    return O.L.dense(a, w, bias)


@onnx_op("MatMul")
def _matmul(O, node, a, b, **_):
    if isinstance(a, Feat) and not isinstance(b, Feat):
        w = O.array(b)
        if w.ndim == 1:
            return squeeze(O.L.dense(a, w.reshape(1, -1), None), -1)
        if w.ndim != 2:
            raise ConvertError(f"MatMul by a constant of rank {w.ndim}")
        return O.L.dense(a, w.T, None)
    if not isinstance(a, Feat) and isinstance(b, Feat) and b.rank == 2 and b.batch == 1:
        return O.L.dense(b, O.array(a), None)
    raise ConvertError("MatMul of two computed values (only products with a constant are lowered)")


@onnx_op("Einsum", whole_shape=True)
def _einsum(O, node, *ins, equation, **_):
    equation = text(equation, "")

    def contract(k, basis):
        return np.einsum(equation, *[basis if i == k else np.asarray(v, np.float64) for i, v in enumerate(ins)])
    return einsum_of_one(O, "Einsum", ins, contract)


@onnx_op("LayerNormalization")
def _layer_norm(O, node, f, scale=None, bias=None, axis=-1, epsilon=1e-5, **_):
    axis = O.axis(f, axis)
    scale = O.const(scale, "LayerNormalization Scale") if scale is not None else None
    bias = O.const(bias, "LayerNormalization B") if bias is not None else None
    return O.L.layer_norm(f, f.rank - axis, scale, bias, float(epsilon)), None, None


@onnx_op("BatchNormalization", whole_shape=True)
def _batch_norm(O, node, f, *stats, epsilon=1e-5, training_mode=0, **_):
    if training_mode:
        raise ConvertError("BatchNormalization in training mode normalises over the batch (it mixes pixels)")
    scale, bias, mean, var = (np.asarray(O.const(v, "BatchNormalization parameters"), np.float64) for v in stats[:4])
    return O.L.batch_norm(f, scale, bias, mean, var, float(epsilon))


@onnx_op("GridSample", whole_shape=True)
def _grid_sample(O, node, grid, coords, mode=None, padding_mode=None, align_corners=0, **_):
    if isinstance(grid, Feat) or not isinstance(coords, Feat):
        raise ConvertError("GridSample of a constant X at computed coordinates is lowered")
    mode, padding = text(mode, "bilinear"), text(padding_mode, "zeros")
    if mode not in ("bilinear", "linear"):
        raise ConvertError(f"GridSample mode {mode!r}: bilinear is lowered")
    if padding not in ("zeros", "border"):
        raise ConvertError(f"GridSample padding_mode {padding!r}: 'zeros' and 'border' are lowered")
    return grid_sample(O.L, O.array(grid), coords, padding == "zeros", bool(align_corners))


def _reduce(op):
    def lower(O, node, f, axes=None, keepdims=1, noop_with_empty_axes=0, **_):
        axes = listed_axes(O, axes, "Reduce")
        if not axes:
            if noop_with_empty_axes:
                return f
            axes = list(range(f.rank + O.pose.merged - 1))
        return O.L.reduce(f, op, [O.axis(f, a) for a in axes], bool(keepdims))
    return lower


for _name, _op in (("ReduceSum", "sum"), ("ReduceMean", "mean"), ("ReduceMax", "max"), ("ReduceMin", "min"),
                   ("ReduceL2", "norm")):
    onnx_op(_name)(_reduce(_op))


@onnx_op("Softmax")
def _softmax(O, node, f, axis=-1, **_):
    return O.L.softmax(f, O.axis(f, axis))
