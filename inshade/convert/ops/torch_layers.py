"""Torch layers: products with constant weights (linear, matmul, einsum), normalisations,
reductions and softmax, and reads of constant tables (embedding, grid_sample)."""
from __future__ import annotations

import torch

from ..lanes import ConvertError, Feat, IntFeat
from ..layout import grid_sample, squeeze
from ..registry import torch_op
from .common import einsum_of_one
from .torch_values import floats


def _optional(c):
    return None if c is None else floats(c)


@torch_op("linear")
def _linear(T, node, f, weight, bias=None):
    if isinstance(weight, Feat) or isinstance(bias, Feat):
        raise ConvertError("a linear layer whose weights are computed from the input (only constant weights "
                           "are lowered)")
    return T.L.dense(f, floats(weight), _optional(bias))


@torch_op("mm", "matmul")
def _mm(T, node, a, b):
    if isinstance(a, Feat) and not isinstance(b, Feat):
        w = floats(b)
        if w.ndim == 1:
            return squeeze(T.L.dense(a, w.reshape(1, -1), None), -1)
        return T.L.dense(a, w.T, None)
    if not isinstance(a, Feat) and isinstance(b, Feat) and b.rank == 2 and b.batch == 1:
        return T.L.dense(b, floats(a), None)
    raise ConvertError("a product of two computed values, or a constant on the wrong side: inshade lowers "
                       "x @ W and W @ x with constant W")


@torch_op("addmm")
def _addmm(T, node, bias, a, b, beta=1, alpha=1):
    if beta != 1 or alpha != 1:
        raise ConvertError("addmm with beta or alpha other than 1")
    if isinstance(bias, Feat):
        return T.L.binary("add", _mm(T, node, a, b), bias)
    out = _mm(T, node, a, b)
    return T.L.affine(out, 1.0, floats(bias))


@torch_op("einsum")
def _einsum(T, node, equation, tensors, *_):
    def contract(k, basis):
        operands = [torch.from_numpy(basis) if i == k else torch.as_tensor(t).detach().to(torch.float64)
                    for i, t in enumerate(tensors)]
        return torch.einsum(equation, *operands).numpy()
    return einsum_of_one(T, "einsum", tensors, contract)


@torch_op("layer_norm")
def _layer_norm(T, node, f, shape, weight=None, bias=None, eps=1e-5, *args):
    return T.L.layer_norm(f, len(shape), _optional(weight), _optional(bias), eps)


@torch_op("native_layer_norm")
def _native_layer_norm(T, node, f, shape, weight, bias, eps):
    return (_layer_norm(T, node, f, shape, weight, bias, eps), None, None)


@torch_op("batch_norm")
def _batch_norm(T, node, f, weight, bias, mean, var, training, momentum, eps, *args):
    if training:
        raise ConvertError("BatchNorm in train mode normalises over the batch (it mixes pixels): call "
                           "module.eval() before exporting")
    return _bn_eval(T, f, weight, bias, mean, var, eps)


def _bn_eval(T, f, weight, bias, mean, var, eps):
    return T.L.batch_norm(f, _optional(weight), _optional(bias), floats(mean), floats(var), eps)


@torch_op("_native_batch_norm_legit_no_training")
def _bn_no_training(T, node, f, weight, bias, mean, var, momentum, eps):
    return (_bn_eval(T, f, weight, bias, mean, var, eps), None, None)


@torch_op("native_batch_norm")
def _native_batch_norm(T, node, f, weight, bias, mean, var, training, momentum, eps):
    if training:
        return _batch_norm(T, node, f, weight, bias, mean, var, True, momentum, eps)
    return _bn_no_training(T, node, f, weight, bias, mean, var, momentum, eps)


def _reduce(op):
    def lower(T, node, f, dims=None, keepdim=False, *_, dtype=None):
        if dims is None or dims == []:
            dims = list(range(f.rank))
        return T.L.reduce(f, op, [dims] if isinstance(dims, int) else dims, keepdim)
    return lower


for _name, _op in (("sum", "sum"), ("mean", "mean"), ("amax", "max"), ("amin", "min")):
    torch_op(_name)(_reduce(_op))


@torch_op("linalg_vector_norm")
def _vector_norm(T, node, f, ord=2, dims=None, keepdim=False, *_, dtype=None):
    if float(ord) != 2:
        raise ConvertError(f"norm of order {ord}: the 2-norm is lowered")
    return _reduce("norm")(T, node, f, dims, keepdim)


@torch_op("norm")
def _norm(T, node, f, p=2, dims=None, keepdim=False, *_, dtype=None):
    return _vector_norm(T, node, f, 2 if p is None else p, dims, keepdim)


@torch_op("linalg_norm")
def _linalg_norm(T, node, f, ord=None, dims=None, keepdim=False, *_, dtype=None):
    """torch.linalg.norm: the vector 2-norm (ord None over one axis, or 'fro' over two)."""
    if ord not in (None, 2, 2.0, "fro") or ord == 2 and isinstance(dims, (list, tuple)) and len(dims) == 2:
        raise ConvertError(f"linalg.norm of order {ord!r}: the 2-norm of vectors (and 'fro') is lowered")
    return _reduce("norm")(T, node, f, dims, keepdim)


@torch_op("softmax", "_softmax")
def _softmax(T, node, f, dim, *_):
    return T.L.softmax(f, dim)


@torch_op("grid_sampler", "grid_sampler_2d", "grid_sampler_3d")
def _grid_sample(T, node, grid, coords, mode=0, padding=0, align_corners=False):
    """F.grid_sample of a constant feature grid [1, C, (D,) H, W] at computed coordinates."""
    if isinstance(grid, Feat) or not isinstance(coords, Feat):
        raise ConvertError("grid_sample: the grid must be a constant (a parameter) and the coordinates computed")
    if mode != 0:
        raise ConvertError(f"grid_sample mode {['bilinear', 'nearest', 'bicubic'][mode]}: bilinear is lowered")
    if padding not in (0, 1):
        raise ConvertError("grid_sample padding_mode 'reflection': 'zeros' and 'border' are lowered")
    return grid_sample(T.L, floats(grid), coords, padding == 0, bool(align_corners))


@torch_op("embedding", takes_ints=True)
def _embedding(T, node, weight, indices, *_):
    if isinstance(weight, Feat) or not isinstance(indices, IntFeat):
        raise ConvertError("embedding: a learned table (a parameter) read at computed integer indices is lowered")
    return T.L.gather(floats(weight), indices)
