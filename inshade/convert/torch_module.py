"""A user's torch module -> bundle: capture with torch.export (torch.fx + make_fx where export
cannot), then lower each ATen op onto components (lowering.py).

The module is traced at a batch of ``TRACE_BATCH`` rows (a prime no feature axis is likely to
share), so the batch axis of every tensor is the one of that size; the user's example rows are
kept for the parity check. Operations whose inputs are all constants (parameters, buffers,
literals, their transposes and products) are evaluated by torch itself and stay constants.
"""
from __future__ import annotations

import contextlib
import logging
import math
import operator
import os
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from .lowering import (ConvertError, Feat, IntFeat, Lowering, const_against, expand, grid_sample, permute, reshape, slice_axis,
                       squeeze, take, unsqueeze)

TRACE_BATCH = 97


class LeadingAxes(torch.nn.Module):
    """``module`` called on rows: each input [N, F] posed as [1, .., 1, N, F] (``lead`` batch axes),
    each output's leading axes flattened back to rows (the parity check feeds and compares rows)."""

    def __init__(self, module, lead: int):
        super().__init__()
        self.module, self.lead = module, lead

    def forward(self, *xs):
        out = self.module(*[x.reshape(*(1,) * (self.lead - 1), *x.shape) for x in xs])
        return torch.utils._pytree.tree_map(lambda t: t.reshape(-1, *t.shape[self.lead:]), out)


# --- capture ---------------------------------------------------------------------------------

@contextlib.contextmanager
def _quiet_torch():
    """torch.export logs graphs and hints on failures; the user gets one line from us instead."""
    logger = logging.getLogger("torch")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(level)


def _user_frame(tb) -> str:
    """'file:line' of the innermost frame outside torch and inshade in a traceback, or ''."""
    torch_root = str(Path(torch.__file__).parent)
    ours = str(Path(__file__).resolve().parents[1])
    for frame in reversed(traceback.extract_tb(tb)):
        f = str(Path(frame.filename).resolve()) if os.path.exists(frame.filename) else frame.filename
        if not f.startswith((torch_root, ours)) and "<" not in frame.filename:
            return f"{_short(frame.filename)}:{frame.lineno}"
    return ""


def _short(path: str) -> str:
    try:
        return os.path.relpath(path)
    except ValueError:
        return path
    # (a relative path when under the working folder, else as given)


def capture(module: torch.nn.Module, args: tuple):
    """(graph module, {placeholder name: constant tensor}, [user input placeholder names])."""
    with _quiet_torch():
        try:
            ep = torch.export.export(module, args, strict=False)
        except Exception as exc:   # torch.export raises many types; each becomes one line below
            first = _classify(exc)
            if first is not None:
                raise ConvertError(first) from None
            return _capture_fx(module, args, exc)
    consts, user = {}, []
    sig = ep.graph_signature
    state = {**ep.state_dict, **ep.constants}
    for spec in sig.input_specs:
        name = spec.arg.name
        if spec.kind.name == "USER_INPUT":
            user.append(name)
        else:
            consts[name] = state[spec.target]
    return ep.graph_module, consts, user


def _classify(exc) -> str | None:
    """A refusal line for capture failures that no other tracer could fix, else None."""
    text = f"{type(exc).__name__}: {exc}"
    where = _user_frame(exc.__traceback__)
    if "data-dependent" in text or "DataDependent" in text:
        return (f"{where + ': ' if where else ''}data-dependent control flow (a Python `if`, loop or index on a "
                "tensor's value): a shader runs one program for every pixel; use torch.where-style arithmetic")
    return None


def _capture_fx(module, args, export_error):
    """torch.fx + make_fx: for modules torch.export cannot capture (symbolic tracing refuses data-
    dependent control flow too, so the ATen graph it yields is the one every input takes)."""
    from torch.fx.experimental.proxy_tensor import make_fx

    try:
        traced = torch.fx.symbolic_trace(module)
        gm = make_fx(traced, tracing_mode="fake")(*args)
    except Exception as exc:
        first = _classify(exc) or _classify(export_error)
        if first is not None:
            raise ConvertError(first) from None
        where = _user_frame(export_error.__traceback__)
        reason = str(export_error).strip().splitlines()[0][:200] if str(export_error).strip() else type(export_error).__name__
        raise ConvertError(f"{where + ': ' if where else ''}cannot capture the module's graph "
                           f"(torch.export: {reason}; torch.fx: {str(exc).strip().splitlines()[0][:120]})") from None
    consts, user = {}, []
    for node in gm.graph.nodes:
        if node.op == "placeholder":
            user.append(node.name)
        elif node.op == "get_attr":
            consts[node.name] = getattr(gm, node.target)
    return gm, consts, user


# --- lowering ----------------------------------------------------------------------------

def _op_name(target) -> str:
    """aten.sort.default -> 'sort'."""
    name = getattr(target, "__name__", str(target))
    if hasattr(target, "_schema"):
        name = target._schema.name.split("::")[-1]
    return name.split(".")[0]


def _where(node) -> str:
    """'file:line: module.path' of an FX node, as much as the trace recorded."""
    parts = []
    trace = node.meta.get("stack_trace") or ""
    files = [line.strip() for line in trace.splitlines() if line.strip().startswith("File ")]
    if files:
        last = files[-1]   # File "/x/model.py", line 42, in forward
        try:
            path = last.split('"')[1]
            lineno = last.split("line ")[1].split(",")[0]
            parts.append(f"{_short(path)}:{lineno}")
        except IndexError:
            pass
    stack = node.meta.get("nn_module_stack") or {}
    if stack:
        path = list(stack.values())[-1][0]
        if path:
            parts.append(path)
    return ": ".join(parts)


class TorchLowering:
    """Walks an ATen graph and drives a ``Lowering``."""

    def __init__(self, lowering: Lowering, consts: dict, batch: int):
        self.L, self.consts, self.batch = lowering, consts, batch

    def run(self, gm, user_inputs: list[str], input_specs: list[tuple[str, tuple, str]]):
        """``input_specs``: (port name, shape of one row, semantic[, batch axes]) per user input; an
        input of several batch axes was traced as [1, .., 1, TRACE_BATCH, *row]."""
        env = {}
        feeds = dict(zip(user_inputs, input_specs))
        outputs = None
        for node in gm.graph.nodes:
            if node.op == "placeholder":
                if node.name in feeds:
                    name, row, semantic, *lead = feeds[node.name]
                    lead = lead[0] if lead else 1
                    shape = [None] * lead + list(row) if lead > 1 else None
                    f = self.L.input(name, int(np.prod(row)), semantic, shape=shape)
                    env[node] = Feat(f.lanes.reshape((1,) * lead + tuple(row)), lead - 1)
                else:
                    env[node] = self.consts[node.name]
            elif node.op == "get_attr":
                env[node] = self.consts.get(node.name, getattr(gm, node.target, None))
            elif node.op == "call_function":
                env[node] = self._call(node, env)
            elif node.op == "output":
                outputs = torch.fx.node.map_arg(node.args[0], lambda n: env[n])
        return outputs

    def _call(self, node, env):
        args = torch.fx.node.map_arg(node.args, lambda n: env[n])
        kwargs = torch.fx.node.map_arg(node.kwargs, lambda n: env[n])
        name = _op_name(node.target)
        if node.target is operator.getitem:
            return args[0][args[1]]
        if not _has_feat((args, kwargs)):
            try:
                return node.target(*args, **kwargs)   # constants only: torch computes it
            except Exception as exc:
                raise ConvertError(f"{_where(node)}: torch.{name} on constants failed ({exc})") from None
        handler = HANDLERS.get(name)
        where = _where(node)
        if handler is None:
            raise ConvertError(f"{where + ': ' if where else ''}torch.{name} has no shader lowering "
                               "(see inshade convert --ops)")
        try:
            if name not in INT_HANDLERS:   # an integer meets a float op: the float it was cast from
                args, kwargs = _map_ints((args, kwargs), self.L.int_to_float)
            return handler(self, node, *args, **kwargs)
        except ConvertError as exc:
            raise ConvertError(f"{where + ': ' if where else ''}torch.{name}: {exc}") from None

    # shapes from the trace: the batch axis is the one of TRACE_BATCH rows
    def out_shape(self, node) -> tuple[int, ...]:
        val = node.meta.get("val")
        if val is None or not hasattr(val, "shape"):
            raise ConvertError("the trace recorded no shape")
        return tuple(int(s) for s in val.shape)


@dataclass(frozen=True)
class Condition:
    """A comparison of values, kept until a torch.where chooses with it (a shader has no boolean
    tensors: the comparison and the choice are one ``where`` node)."""
    op: str
    a: object
    b: object


def _compare(op):
    def lower(T, node, a, b):
        return Condition(op, a, b)
    return lower


def _where_op(T, node, cond, x, y):
    if isinstance(cond, Condition):
        return T.L.where(cond.op, cond.a, cond.b, x, y)
    if not isinstance(cond, Feat):   # a constant mask
        return T.L.where("gt", _np(cond).astype(np.float32), np.float32(0.5), x, y)
    raise ConvertError("where with a condition that is not a comparison (gt, ge, lt, le) of values")


def _has_feat(obj) -> bool:
    if isinstance(obj, (Feat, Condition)):
        return True
    if isinstance(obj, (list, tuple)):
        return any(_has_feat(o) for o in obj)
    if isinstance(obj, dict):
        return any(_has_feat(o) for o in obj.values())
    return False


def _map_ints(obj, fn):
    if isinstance(obj, IntFeat):
        return fn(obj)
    if isinstance(obj, (list, tuple)):
        return type(obj)(_map_ints(o, fn) for o in obj)
    if isinstance(obj, dict):
        return {k: _map_ints(v, fn) for k, v in obj.items()}
    return obj


def _int_result(node) -> bool:
    """The traced op's result is an integer tensor (torch's type promotion decided it)."""
    val = node.meta.get("val")
    dtype = getattr(val, "dtype", None)
    return dtype is not None and not dtype.is_floating_point and dtype != torch.bool


def _ints(c) -> np.ndarray:
    if isinstance(c, torch.Tensor):
        return c.detach().cpu().numpy()
    return np.asarray(c)


def _np(c) -> np.ndarray:
    if isinstance(c, torch.Tensor):
        return c.detach().cpu().to(torch.float32).numpy()
    return np.asarray(c, np.float32)


def _is_const(x) -> bool:
    return not isinstance(x, Feat)


# --- layout: only the lane arrays change ---------------------------------------------------

def _reshape(T, node, f, *_):
    return reshape(f, T.out_shape(node), T.batch)


def _permute(T, node, f, dims):
    return permute(f, dims)


def _transpose(T, node, f, a=0, b=1):
    dims = list(range(f.rank))
    a, b = a % f.rank, b % f.rank
    dims[a], dims[b] = dims[b], dims[a]
    return permute(f, dims)


def _t(T, node, f):
    return permute(f, [1, 0]) if f.rank == 2 else f


def _unsqueeze(T, node, f, dim):
    return unsqueeze(f, dim)


def _squeeze(T, node, f, dims=None):
    return squeeze(f, dims)


def _expand(T, node, f, sizes, *_):
    return expand(f, T.out_shape(node))


def _slice(T, node, f, dim=0, start=None, end=None, step=1):
    return slice_axis(f, dim, start, end, step, T.batch)


def _select(T, node, f, dim, index):
    return take(f, dim, index)


def _narrow(T, node, f, dim, start, length):
    return slice_axis(f, dim, start, start + length, 1, T.batch)


def _split(T, node, f, sizes, dim=0):
    dim = dim % f.rank
    n = f.shape[dim]
    if isinstance(sizes, int):
        sizes = [min(sizes, n - s) for s in range(0, n, sizes)]
    bounds = np.cumsum([0, *sizes])
    return tuple(slice_axis(f, dim, int(a), int(b), 1, T.batch) for a, b in zip(bounds[:-1], bounds[1:]))


def _chunk(T, node, f, chunks, dim=0):
    n = f.shape[dim % f.rank]
    return _split(T, node, f, math.ceil(n / chunks), dim)


def _unbind(T, node, f, dim=0):
    return tuple(take(f, dim, i) for i in range(f.shape[dim % f.rank]))


def _cat(T, node, tensors, dim=0):
    feats = [t for t in tensors if isinstance(t, Feat)]
    if any(isinstance(t, IntFeat) for t in feats):
        if not _int_result(node):
            return _cat(T, node, _map_ints(list(tensors), T.L.int_to_float), dim)
        like = next(t for t in feats if isinstance(t, IntFeat))
        parts = [T.L.int_operand(t if isinstance(t, IntFeat) else _ints(t), like, T.batch) for t in tensors]
        if any(p.batch != like.batch for p in parts):
            raise ConvertError("concatenates tensors whose batch axes differ")
        return like.moved(np.concatenate([p.lanes for p in parts], dim % like.rank))
    like = T.L.resolve(feats[0])
    rank = like.rank
    dim = dim % rank
    if dim == like.batch:
        raise ConvertError("concatenates along the batch axis")
    parts = []
    for t in tensors:
        if isinstance(t, Feat):
            t = T.L.resolve(t)
            if t.batch != like.batch:
                raise ConvertError("concatenates tensors whose batch axes differ")
            parts.append(t.lanes)
        else:
            c = const_against(_np(t), like, T.batch)
            if c.size:
                parts.append(T.L.constant(like, c).lanes)
    return Feat(np.concatenate(parts, dim), like.batch)


def _stack(T, node, tensors, dim=0):
    feats = [t for t in tensors if isinstance(t, Feat)]
    rank = feats[0].rank + 1
    dim = dim % rank
    return _cat(T, node, [unsqueeze(t, dim) if isinstance(t, Feat) else torch.as_tensor(t).unsqueeze(dim)
                          for t in tensors], dim)


def _flatten(T, node, f, *_):
    return _reshape(T, node, f)


def _index(T, node, f, indices):
    """x[..., idx] with constant integer indices on one non-batch axis, or table[idx] with a
    computed integer index into a constant table."""
    picks = [(a, i) for a, i in enumerate(indices) if i is not None]
    if len(picks) == 1 and picks[0][0] == 0 and isinstance(picks[0][1], IntFeat) and not isinstance(f, Feat):
        return T.L.gather(_np(f), picks[0][1])
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


def _index_select(T, node, f, dim, idx):
    return take(f, dim, np.asarray(torch.as_tensor(idx).cpu().numpy()).astype(np.int64))


def _repeat(T, node, f, repeats):
    reps = list(repeats)
    lead = len(reps) - f.rank
    lanes = f.lanes.reshape((1,) * lead + f.shape)
    batch = f.batch + lead
    if reps[batch] != 1:
        raise ConvertError("repeats the batch axis")
    return f.moved(np.tile(lanes, reps), batch)


def _flip(T, node, f, dims):
    dims = [d % f.rank for d in dims]
    if f.batch in dims:
        raise ConvertError("flips the batch axis")
    return f.moved(np.flip(f.lanes, dims))


def _identity(T, node, f, *args, **kwargs):
    return f


def _to_copy(T, node, f, *args, dtype=None, **kwargs):
    dtype = dtype or next((a for a in args if isinstance(a, torch.dtype)), None)
    if dtype in INT_DTYPES:
        return T.L.to_int(f)
    if dtype is not None and dtype not in (torch.float32, torch.float16, torch.float64):
        raise ConvertError(f"converts a computed value to {dtype} (shader values are float32 or integer lanes "
                           f"of {', '.join(str(d) for d in INT_DTYPES)})")
    return T.L.int_to_float(f) if isinstance(f, IntFeat) else f


def _dropout(T, node, f, p=0.5, train=False, *args):
    if train:
        raise ConvertError("dropout in train mode is random: call module.eval() before exporting")
    return f


# --- arithmetic --------------------------------------------------------------------------

def _arith(op):
    def lower(T, node, a, b, alpha=1, **_):
        if isinstance(a, IntFeat) or isinstance(b, IntFeat):
            return _int_or_float_arith(T, node, op, a, b, alpha)
        if op in ("add", "sub") and alpha != 1:
            b = _arith("mul")(T, node, b, alpha)
        return T.L.arithmetic(op, a if isinstance(a, Feat) else _np(a), b if isinstance(b, Feat) else _np(b), T.batch)
    return lower


def _int_or_float_arith(T, node, op, a, b, alpha=1):
    """An integer operand: integer arithmetic where torch's result is an integer, else the float
    path with the integer as the float it was cast from."""
    if not _int_result(node):
        a, b = _map_ints((a, b), T.L.int_to_float)
        return _arith(op)(T, node, a, b, alpha)
    if alpha != 1:
        b = T.L.int_arithmetic("mul", b if isinstance(b, Feat) else _ints(b), _ints(alpha), T.batch)
    return T.L.int_arithmetic(op, a if isinstance(a, Feat) else _ints(a), b if isinstance(b, Feat) else _ints(b),
                              T.batch)


def _bitwise(op):
    def lower(T, node, a, b):
        if not (isinstance(a, IntFeat) or isinstance(b, IntFeat)):
            raise ConvertError(f"bitwise {op} of float values")
        return _int_or_float_arith(T, node, op, a, b)
    return lower


def _embedding(T, node, weight, indices, *_):
    if isinstance(weight, Feat) or not isinstance(indices, IntFeat):
        raise ConvertError("embedding: a learned table (a parameter) read at computed integer indices is lowered")
    return T.L.gather(_np(weight), indices)


def _like(value):
    def lower(T, node, f, *args, **kwargs):
        return torch.full(T.out_shape(node), value(args), dtype=torch.float32)
    return lower


def _rsub(T, node, a, b, alpha=1):
    return _arith("sub")(T, node, b, _arith("mul")(T, node, a, alpha) if alpha != 1 else a)


def _neg(T, node, f):
    return T.L.affine(f, -1.0, 0.0)


def _pow(T, node, f, exponent):
    if isinstance(exponent, Feat):
        if isinstance(f, Feat):
            raise ConvertError("a computed value raised to a computed power (a constant base or exponent is lowered)")
        return T.L.base_power(_np(f), exponent)
    return T.L.power(f, _np(exponent))


def _round(T, node, f, *args, decimals=0):
    if decimals:
        raise ConvertError(f"round to {decimals} decimals: round to integers is lowered")
    return T.L.unary(f, "round")


def _modulo(kind):
    def lower(T, node, a, b):
        if isinstance(a, IntFeat) and kind == "remainder" and _int_result(node):
            return T.L.int_arithmetic("remainder", a, _ints(b) if not isinstance(b, Feat) else b, T.batch)
        if isinstance(a, IntFeat):
            raise ConvertError(f"{kind} of an integer: torch.remainder (Python's %) by a power of two is lowered")
        if isinstance(b, Feat) or not isinstance(a, Feat):
            raise ConvertError(f"{kind} of a computed value by a constant divisor is lowered")
        return T.L.modulo(a, _np(b), kind)
    return lower


def _atan2(T, node, a, b):
    return T.L.atan2(a if isinstance(a, Feat) else _np(a), b if isinstance(b, Feat) else _np(b), T.batch)


def _unary(kind, **fixed):
    def lower(T, node, f, *args, **kwargs):
        return T.L.unary(f, kind, dict(fixed))
    return lower


def _rsqrt(T, node, f):
    return T.L.unary(T.L.unary(f, "sqrt"), "reciprocal")


def _square(T, node, f):
    return T.L.binary("mul", f, f)


def _leaky_relu(T, node, f, slope=0.01):
    return T.L.unary(f, "leaky_relu", {"slope": float(slope)})


def _softplus(T, node, f, beta=1.0, threshold=20.0):
    return T.L.unary(f, "softplus", {"beta": float(beta), "threshold": float(threshold)})


def _gelu(T, node, f, approximate="none"):
    return T.L.unary(f, "gelu", {"approximate": approximate})


def _elu(T, node, f, alpha=1.0, scale=1.0, input_scale=1.0):
    if input_scale != 1:
        f = T.L.scale(f, input_scale)
    out = T.L.unary(f, "elu", {"alpha": float(alpha)})
    return out if scale == 1 else T.L.affine(out, float(scale), 0.0)


def _clamp(T, node, f, lo=None, hi=None):
    if isinstance(lo, Feat) or isinstance(hi, Feat):
        raise ConvertError("clamp bounds must be constants")
    lo, hi = (None if v is None else _np(v) for v in (lo, hi))
    if lo is not None and lo.size > 1 or hi is not None and hi.size > 1:
        raise ConvertError("clamp with tensor bounds: only scalar bounds are lowered")
    params = {k: float(v) for k, v in (("min", lo), ("max", hi)) if v is not None}
    return T.L.unary(f, "clamp", params) if params else f


def _hardtanh(T, node, f, lo=-1.0, hi=1.0):
    return T.L.unary(f, "clamp", {"min": float(lo), "max": float(hi)})


def _relu6(T, node, f):
    return T.L.unary(f, "clamp", {"min": 0.0, "max": 6.0})


def _hardsigmoid(T, node, f):
    return T.L.unary(T.L.affine(f, np.float32(1 / 6), 0.5), "clamp", {"min": 0.0, "max": 1.0})


def _hardswish(T, node, f):
    return T.L.binary("mul", f, _hardsigmoid(T, node, f))


def _mish(T, node, f):
    return T.L.binary("mul", f, T.L.unary(T.L.unary(f, "softplus", {"beta": 1.0, "threshold": 20.0}), "tanh"))


# --- layers ------------------------------------------------------------------------------

def _linear(T, node, f, weight, bias=None):
    if isinstance(weight, Feat) or isinstance(bias, Feat):
        raise ConvertError("a linear layer whose weights are computed from the input (only constant weights "
                           "are lowered)")
    return T.L.dense(f, _np(weight), None if bias is None else _np(bias))


def _mm(T, node, a, b):
    if isinstance(a, Feat) and _is_const(b):
        w = _np(b)
        if w.ndim == 1:
            return squeeze(T.L.dense(a, w.reshape(1, -1), None), -1)
        return T.L.dense(a, w.T, None)
    if _is_const(a) and isinstance(b, Feat) and b.rank == 2 and b.batch == 1:
        return T.L.dense(b, _np(a), None)
    raise ConvertError("a product of two computed values, or a constant on the wrong side: inshade lowers "
                       "x @ W and W @ x with constant W")


def _addmm(T, node, bias, a, b, beta=1, alpha=1):
    if beta != 1 or alpha != 1:
        raise ConvertError("addmm with beta or alpha other than 1")
    if isinstance(bias, Feat):
        return T.L.binary("add", _mm(T, node, a, b), bias)
    out = _mm(T, node, a, b)
    return T.L.affine(out, 1.0, _np(bias))


def _layer_norm(T, node, f, shape, weight=None, bias=None, eps=1e-5, *args):
    return T.L.layer_norm(f, len(shape), None if weight is None else _np(weight),
                          None if bias is None else _np(bias), eps)


def _native_layer_norm(T, node, f, shape, weight, bias, eps):
    return (_layer_norm(T, node, f, shape, weight, bias, eps), None, None)


def _batch_norm(T, node, f, weight, bias, mean, var, training, momentum, eps, *args):
    if training:
        raise ConvertError("BatchNorm in train mode normalises over the batch (it mixes pixels): call "
                           "module.eval() before exporting")
    return _bn_eval(T, f, weight, bias, mean, var, eps)


def _bn_eval(T, f, weight, bias, mean, var, eps):
    return T.L.batch_norm(f, None if weight is None else _np(weight), None if bias is None else _np(bias),
                          _np(mean), _np(var), eps)


def _bn_no_training(T, node, f, weight, bias, mean, var, momentum, eps):
    return (_bn_eval(T, f, weight, bias, mean, var, eps), None, None)


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


def _vector_norm(T, node, f, ord=2, dims=None, keepdim=False, *_, dtype=None):
    if float(ord) != 2:
        raise ConvertError(f"norm of order {ord}: the 2-norm is lowered")
    return _reduce("norm")(T, node, f, dims, keepdim)


def _norm(T, node, f, p=2, dims=None, keepdim=False, *_, dtype=None):
    return _vector_norm(T, node, f, 2 if p is None else p, dims, keepdim)


def _linalg_norm(T, node, f, ord=None, dims=None, keepdim=False, *_, dtype=None):
    """torch.linalg.norm: the vector 2-norm (ord None over one axis, or 'fro' over two)."""
    if ord not in (None, 2, 2.0, "fro") or ord == 2 and isinstance(dims, (list, tuple)) and len(dims) == 2:
        raise ConvertError(f"linalg.norm of order {ord!r}: the 2-norm of vectors (and 'fro') is lowered")
    return _reduce("norm")(T, node, f, dims, keepdim)


def _expand_as(T, node, f, other):
    return expand(f, T.out_shape(node))


def _einsum(T, node, equation, tensors, *_):
    """An einsum of one computed value with constants: linear in it, so one dense layer."""
    feats = [i for i, t in enumerate(tensors) if isinstance(t, Feat)]
    if len(feats) != 1:
        raise ConvertError("einsum of several computed values (an einsum of one value with constants is lowered)")
    k = feats[0]

    def apply(basis):
        operands = [torch.from_numpy(basis) if i == k else torch.as_tensor(t).detach().to(torch.float64)
                    for i, t in enumerate(tensors)]
        return torch.einsum(equation, *operands).numpy()
    return T.L.linear_map(tensors[k], apply)


def _no_op(T, node, *args, **kwargs):
    """Trace-time assertions torch.export records (shapes, dtypes): nothing to compute."""
    return None


def _selu(T, node, f):
    out = T.L.unary(f, "elu", {"alpha": 1.6732632423543772848170429916717})
    return T.L.affine(out, np.float32(1.0507009873554804934193349852946), 0.0)


def _softmax(T, node, f, dim, *_):
    return T.L.softmax(f, dim)


def _grid_sample(T, node, grid, coords, mode=0, padding=0, align_corners=False):
    """F.grid_sample of a constant feature grid [1, C, (D,) H, W] at computed coordinates."""
    if isinstance(grid, Feat) or not isinstance(coords, Feat):
        raise ConvertError("grid_sample: the grid must be a constant (a parameter) and the coordinates computed")
    if mode != 0:
        raise ConvertError(f"grid_sample mode {['bilinear', 'nearest', 'bicubic'][mode]}: bilinear is lowered")
    if padding not in (0, 1):
        raise ConvertError("grid_sample padding_mode 'reflection': 'zeros' and 'border' are lowered")
    return grid_sample(T.L, _np(grid), coords, padding == 0, bool(align_corners))


HANDLERS = {
    # layout
    "view": _reshape, "reshape": _reshape, "_unsafe_view": _reshape, "flatten": _flatten, "unflatten": _reshape,
    "permute": _permute, "transpose": _transpose, "t": _t, "unsqueeze": _unsqueeze, "squeeze": _squeeze,
    "expand": _expand, "slice": _slice, "select": _select, "narrow": _narrow, "split": _split,
    "split_with_sizes": _split, "chunk": _chunk, "unbind": _unbind, "cat": _cat, "concat": _cat, "stack": _stack,
    "index": _index, "index_select": _index_select, "repeat": _repeat, "flip": _flip,
    "contiguous": _identity, "clone": _identity, "alias": _identity, "detach": _identity, "_to_copy": _to_copy,
    "to": _to_copy, "type_as": _identity, "dropout": _dropout, "feature_dropout": _dropout, "alpha_dropout": _dropout,
    # arithmetic
    "add": _arith("add"), "sub": _arith("sub"), "mul": _arith("mul"), "div": _arith("div"), "rsub": _rsub,
    "true_divide": _arith("div"), "neg": _neg, "ones_like": _like(lambda a: 1.0), "zeros_like": _like(lambda a: 0.0),
    "full_like": _like(lambda a: float(a[0])), "pow": _pow, "square": _square, "rsqrt": _rsqrt,
    # activations
    "relu": _unary("relu"), "sigmoid": _unary("sigmoid"), "tanh": _unary("tanh"), "sin": _unary("sin"),
    "cos": _unary("cos"), "exp": _unary("exp"), "expm1": _unary("expm1"), "abs": _unary("abs"),
    "sqrt": _unary("sqrt"), "reciprocal": _unary("reciprocal"), "silu": _unary("silu"),
    "leaky_relu": _leaky_relu, "softplus": _softplus, "gelu": _gelu, "elu": _elu, "clamp": _clamp,
    "clamp_min": lambda T, n, f, lo: _clamp(T, n, f, lo, None), "clamp_max": lambda T, n, f, hi: _clamp(T, n, f, None, hi),
    "hardtanh": _hardtanh, "relu6": _relu6, "hardsigmoid": _hardsigmoid, "hardswish": _hardswish, "mish": _mish,
    # layers, normalisation, reductions, lookups
    "linear": _linear, "mm": _mm, "matmul": _mm, "addmm": _addmm,
    "layer_norm": _layer_norm, "native_layer_norm": _native_layer_norm, "batch_norm": _batch_norm,
    "_native_batch_norm_legit_no_training": _bn_no_training, "native_batch_norm": _native_batch_norm,
    "sum": _reduce("sum"), "mean": _reduce("mean"), "amax": _reduce("max"), "amin": _reduce("min"),
    "linalg_vector_norm": _vector_norm, "norm": _norm, "linalg_norm": _linalg_norm, "softmax": _softmax,
    "_softmax": _softmax, "expand_as": _expand_as, "einsum": _einsum,
    "log": _unary("log"), "log2": _unary("log2"), "floor": _unary("floor"), "ceil": _unary("ceil"),
    "trunc": _unary("trunc"), "fix": _unary("trunc"), "frac": _unary("frac"), "round": _round,
    "fmod": _modulo("fmod"), "remainder": _modulo("remainder"), "atan2": _atan2, "arctan2": _atan2, "_assert_tensor_metadata": _no_op, "selu": _selu,
    "gt": _compare("gt"), "ge": _compare("ge"), "lt": _compare("lt"), "le": _compare("le"), "where": _where_op,
    "grid_sampler": _grid_sample, "grid_sampler_2d": _grid_sample, "grid_sampler_3d": _grid_sample,
    # integer lanes
    "bitwise_xor": _bitwise("xor"), "bitwise_and": _bitwise("and"), "bitwise_or": _bitwise("or"),
    "bitwise_left_shift": _bitwise("shl"), "__lshift__": _bitwise("shl"), "embedding": _embedding,
}
INT_DTYPES = (torch.int32, torch.int64)
# handlers that take integer tensors as they are (layout, casts, integer arithmetic, table reads)
INT_HANDLERS = {
    "view", "reshape", "_unsafe_view", "flatten", "unflatten", "permute", "transpose", "t", "unsqueeze", "squeeze",
    "expand", "slice", "select", "narrow", "split", "split_with_sizes", "chunk", "unbind", "cat", "concat", "stack",
    "index", "index_select", "repeat", "flip", "contiguous", "clone", "alias", "detach", "_to_copy", "to",
    "add", "sub", "mul", "rsub", "remainder", "bitwise_xor", "bitwise_and", "bitwise_or", "bitwise_left_shift",
    "__lshift__", "embedding", "_assert_tensor_metadata", "expand_as",
}
