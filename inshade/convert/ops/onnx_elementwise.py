"""ONNX elementwise ops: activations and the other functions a component computes lane by lane,
Clip, and the ops that change nothing a shader computes (Identity, inference Dropout, Cast)."""
from __future__ import annotations

import numpy as np

from ..lanes import ConvertError, IntFeat
from ..registry import onnx_op
from .common import hard_sigmoid, hard_swish, identity, negate, unary

INT_CASTS = (6, 7)      # Cast to INT32, INT64: integer lanes
FLOAT_CASTS = (1, 11)   # float, double (a shader computes both in float32)

for _name, _kind in (("Relu", "relu"), ("Sigmoid", "sigmoid"), ("Tanh", "tanh"), ("Softplus", "softplus"),
                     ("Erf", "erf"), ("Sin", "sin"), ("Cos", "cos"), ("Exp", "exp"), ("Abs", "abs"),
                     ("Sqrt", "sqrt"), ("Reciprocal", "reciprocal"), ("Log", "log"), ("Floor", "floor"),
                     ("Ceil", "ceil"), ("Round", "round")):
    onnx_op(_name)(unary(_kind))
onnx_op("Neg")(negate)
onnx_op("Identity", takes_ints=True)(identity)


def text(value, default: str) -> str:
    """A string attribute (onnx gives bytes)."""
    value = default if value is None else value
    return value.decode() if isinstance(value, bytes) else value


@onnx_op("LeakyRelu")
def _leaky_relu(O, node, x, alpha=0.01, **_):
    return O.L.unary(x, "leaky_relu", {"slope": float(alpha)})


@onnx_op("Elu")
def _elu(O, node, x, alpha=1.0, **_):
    return O.L.unary(x, "elu", {"alpha": float(alpha)})


@onnx_op("Selu")
def _selu(O, node, x, alpha=1.67326319217681884765625, gamma=1.05070102214813232421875, **_):
    out = O.L.unary(x, "elu", {"alpha": float(alpha)})
    return O.L.affine(out, float(gamma), 0.0)


@onnx_op("Gelu")
def _gelu(O, node, x, approximate=None, **_):
    return O.L.unary(x, "gelu", {"approximate": text(approximate, "none")})


@onnx_op("HardSigmoid")
def _hard_sigmoid(O, node, x, alpha=0.2, beta=0.5, **_):
    return hard_sigmoid(O.L, x, alpha, beta)


@onnx_op("HardSwish")
def _hard_swish(O, node, x, **_):
    return hard_swish(O.L, x)


@onnx_op("Mish")
def _mish(O, node, x, **_):
    return O.L.binary("mul", x, O.L.unary(O.L.unary(x, "softplus"), "tanh"))


@onnx_op("Clip")
def _clip(O, node, x, *bounds, **attrs):
    lo = bounds[0] if len(bounds) > 0 else attrs.get("min")
    hi = bounds[1] if len(bounds) > 1 else attrs.get("max")
    lo, hi = (None if v is None else float(np.asarray(O.const(v, f"Clip {k}")).reshape(()))
              for k, v in (("min", lo), ("max", hi)))
    return O.L.clamp(x, lo, hi)


@onnx_op("Dropout")
def _dropout(O, node, x, ratio=None, training_mode=None, **_):
    if training_mode is not None and bool(np.asarray(O.const(training_mode, "training_mode"))):
        raise ConvertError("Dropout in training mode is random")
    return x, None


@onnx_op("Cast", takes_ints=True)
def _cast(O, node, x, to=None, **_):
    if to in INT_CASTS:
        return O.L.to_int(x)
    if isinstance(x, IntFeat) and to in FLOAT_CASTS:
        return O.L.int_to_float(x)
    if to not in FLOAT_CASTS:
        name = O.helper.tensor_dtype_to_string(to).removeprefix("TensorProto.")
        raise ConvertError(f"Cast to {name}: shader values are float32 (rounding to {name} is not lowered)")
    return x
