"""Torch arithmetic: + - * / with constants folded into affine nodes, integer arithmetic on integer
lanes, powers, modulo, atan2, comparisons and the where that chooses with them."""
from __future__ import annotations

import torch

from ..lanes import ConvertError, Feat, IntFeat
from ..registry import torch_op
from .common import choose, compare, negate
from .torch_values import floats, ints, int_result, map_ints

for _op in ("gt", "ge", "lt", "le"):
    torch_op(_op)(compare(_op))
torch_op("neg")(negate)
torch_op("where")(choose("where with a condition that is not a comparison (gt, ge, lt, le) of values"))


def _arith(op):
    def lower(T, node, a, b, alpha=1, **_):
        if isinstance(a, IntFeat) or isinstance(b, IntFeat):
            return _int_or_float_arith(T, node, op, a, b, alpha)
        if op in ("add", "sub") and alpha != 1:
            b = _arith("mul")(T, node, b, alpha)
        return T.L.arithmetic(op, a if isinstance(a, Feat) else floats(a), b if isinstance(b, Feat) else floats(b),
                              T.batch)
    return lower


for _op in ("add", "sub", "mul"):
    torch_op(_op, takes_ints=True)(_arith(_op))
torch_op("div", "true_divide")(_arith("div"))


def _int_or_float_arith(T, node, op, a, b, alpha=1):
    """An integer operand: integer arithmetic where torch's result is an integer, else the float
    path with the integer as the float it was cast from."""
    if not int_result(node):
        a, b = map_ints((a, b), T.L.int_to_float)
        return _arith(op)(T, node, a, b, alpha)
    if alpha != 1:
        b = T.L.int_arithmetic("mul", b if isinstance(b, Feat) else ints(b), ints(alpha), T.batch)
    return T.L.int_arithmetic(op, a if isinstance(a, Feat) else ints(a), b if isinstance(b, Feat) else ints(b),
                              T.batch)


def _bitwise(op):
    def lower(T, node, a, b):
        if not (isinstance(a, IntFeat) or isinstance(b, IntFeat)):
            raise ConvertError(f"bitwise {op} of float values")
        return _int_or_float_arith(T, node, op, a, b)
    return lower


for _name, _op in (("bitwise_xor", "xor"), ("bitwise_and", "and"), ("bitwise_or", "or"),
                   ("bitwise_left_shift", "shl"), ("__lshift__", "shl")):
    torch_op(_name, takes_ints=True)(_bitwise(_op))


@torch_op("rsub", takes_ints=True)
def _rsub(T, node, a, b, alpha=1):
    return _arith("sub")(T, node, b, _arith("mul")(T, node, a, alpha) if alpha != 1 else a)


def _like(value):
    def lower(T, node, f, *args, **kwargs):
        return torch.full(T.out_shape(node), value(args), dtype=torch.float32)
    return lower


torch_op("ones_like")(_like(lambda a: 1.0))
torch_op("zeros_like")(_like(lambda a: 0.0))
torch_op("full_like")(_like(lambda a: float(a[0])))


@torch_op("pow")
def _pow(T, node, f, exponent):
    if isinstance(exponent, Feat):
        if isinstance(f, Feat):
            raise ConvertError("a computed value raised to a computed power (a constant base or exponent is lowered)")
        return T.L.base_power(floats(f), exponent)
    return T.L.power(f, floats(exponent))


def _modulo(kind):
    def lower(T, node, a, b):
        if isinstance(a, IntFeat) and kind == "remainder" and int_result(node):
            return T.L.int_arithmetic("remainder", a, ints(b) if not isinstance(b, Feat) else b, T.batch)
        if isinstance(a, IntFeat):
            raise ConvertError(f"{kind} of an integer: torch.remainder (Python's %) by a power of two is lowered")
        if isinstance(b, Feat) or not isinstance(a, Feat):
            raise ConvertError(f"{kind} of a computed value by a constant divisor is lowered")
        return T.L.modulo(a, floats(b), kind)
    return lower


torch_op("fmod")(_modulo("fmod"))
torch_op("remainder", takes_ints=True)(_modulo("remainder"))


@torch_op("atan2", "arctan2")
def _atan2(T, node, a, b):
    return T.L.atan2(a if isinstance(a, Feat) else floats(a), b if isinstance(b, Feat) else floats(b), T.batch)
