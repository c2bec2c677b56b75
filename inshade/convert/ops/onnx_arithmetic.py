"""ONNX arithmetic: + - * / with constants folded into affine nodes (integers kept integers),
Pow, Mod, the bitwise ops on integer lanes, comparisons and the Where that chooses with them."""
from __future__ import annotations

from ..lanes import ConvertError, Feat, IntFeat
from ..registry import onnx_op
from .common import choose, compare

for _name, _op in (("Greater", "gt"), ("GreaterOrEqual", "ge"), ("Less", "lt"), ("LessOrEqual", "le")):
    onnx_op(_name)(compare(_op))
onnx_op("Where")(choose("Where with a condition that is not a comparison (Greater, Less, ...) of values"))


def _arith(op):
    def lower(O, node, a, b, **_):
        if isinstance(a, IntFeat) or isinstance(b, IntFeat):   # ONNX keeps integers integers
            if op == "div":
                raise ConvertError("Div of integers (integer division) is not lowered: Cast to float first")
            return O.L.int_arithmetic(op, a, b, O.batch)
        return O.L.arithmetic(op, a if isinstance(a, Feat) else O.array(a), b if isinstance(b, Feat) else O.array(b),
                              O.batch)
    return lower


for _name, _op in (("Add", "add"), ("Sub", "sub"), ("Mul", "mul"), ("Div", "div")):
    onnx_op(_name, takes_ints=True)(_arith(_op))


@onnx_op("Pow")
def _pow(O, node, x, e, **_):
    if isinstance(e, Feat):
        if isinstance(x, Feat):
            raise ConvertError("Pow of a computed base to a computed exponent (a constant base or exponent is "
                               "lowered)")
        return O.L.base_power(O.array(x), e)
    return O.L.power(x, O.array(e))


@onnx_op("Mod", takes_ints=True)
def _mod(O, node, a, b, fmod=0, **_):
    if isinstance(a, IntFeat) and not fmod:
        return O.L.int_arithmetic("remainder", a, O.const(b, "Mod divisor"), O.batch)
    if isinstance(b, Feat) or not isinstance(a, Feat):
        raise ConvertError("Mod of a computed value by a constant divisor is lowered")
    if not fmod:
        raise ConvertError("Mod with fmod = 0 is integer modulo; float values need fmod = 1")
    return O.L.modulo(a, O.array(b), "fmod")


def _int_op(op):
    def lower(O, node, a, b, direction=None, **_):
        if not (isinstance(a, IntFeat) or isinstance(b, IntFeat)):
            raise ConvertError("an integer operation on values that are not integers")
        if op == "shl" and direction != b"LEFT" and direction != "LEFT":
            raise ConvertError("BitShift RIGHT needs the integer's high bits, which a 32-bit lane does not keep")
        return O.L.int_arithmetic(op, a, b, O.batch)
    return lower


for _name, _op in (("BitwiseXor", "xor"), ("BitwiseAnd", "and"), ("BitwiseOr", "or"), ("BitShift", "shl")):
    onnx_op(_name, takes_ints=True)(_int_op(_op))
