"""Elementwise functions, one lane in, one lane out: the bundle-level spec."""
from __future__ import annotations

import numpy as np

from inshade.components.spec import ComponentError, ComponentSpec, Param, finite, finite32, float32, register, same_width


ACTIVATIONS = ("relu", "leaky_relu", "sigmoid", "tanh", "softplus", "sin", "cos", "exp", "expm1", "identity",
               "silu", "gelu", "elu", "abs", "clamp", "erf")
# elementwise too, but defined on part of the line only (x >= 0, x != 0, x > 0; power: x >= 0 for a
# non-integer exponent, x != 0 for a negative one): random MLP generators must not feed them
PARTIAL_ELEMENTWISE = ("sqrt", "reciprocal", "log", "log2", "power")
# elementwise and exact (bit-identical on both sides for the same input), but stepped: at integers
# (half-integers for round) or multiples of the divisor, where a computed argument one ulp across
# moves the output by the whole step; not for random MLPs either
STEPPED_ELEMENTWISE = ("floor", "ceil", "trunc", "round", "frac", "fmod", "remainder")
GELU_FORMS = ("none", "tanh")
ELEMENTWISE = ACTIVATIONS + PARTIAL_ELEMENTWISE + STEPPED_ELEMENTWISE   # every type of this folder

for _name in ("relu", "sigmoid", "tanh", "exp", "expm1", "identity", "silu", "abs", "erf", "sqrt", "reciprocal"):
    register(ComponentSpec(_name, f"elementwise {_name}", {}, out_dim=same_width))
for _name, _doc in (
        ("log", "natural logarithm as torch.log: NaN below 0, -inf at +-0, +inf at +inf"),
        ("log2", "base-2 logarithm as torch.log2: NaN below 0, -inf at +-0, +inf at +inf"),
        ("floor", "largest integer <= x (torch.floor)"),
        ("ceil", "smallest integer >= x (torch.ceil)"),
        ("trunc", "x rounded toward 0 (torch.trunc)"),
        ("round", "x rounded to the nearest integer, halves to even as torch.round: 0.5 -> 0, 1.5 -> 2, -2.5 -> -2"),
        ("frac", "x - trunc(x) as torch.frac: the sign of x (not GLSL's fract, x - floor(x))")):
    register(ComponentSpec(_name, _doc, {}, out_dim=same_width))
_DIVISOR = Param(float, check=lambda v: finite32(v) and abs(float32(v)) >= np.finfo(np.float32).tiny,
                 doc="finite and normal in float32, |divisor| >= 2^-126 (both sides use it rounded to float32; "
                     "torch's fmod of a subnormal divisor is NaN)")
register(ComponentSpec(
    "fmod", "torch.fmod(x, divisor), exact (C's fmod): x - n divisor, n = trunc(x / divisor), the sign of x, "
            "|result| < |divisor|; NaN for an infinite x", {"divisor": _DIVISOR}, out_dim=same_width))
register(ComponentSpec(
    "remainder", "torch.remainder(x, divisor) (Python's %): fmod, plus divisor where that is non-zero and of the "
                 "other sign (one rounding: the result may equal the divisor, as torch's)",
    {"divisor": _DIVISOR}, out_dim=same_width))
register(ComponentSpec(
    "power", "torch.pow(x, exponent), exponent constant: torch's special cases (0, 1, 0.5, -0.5, -1) and C's pow "
             "(x < 0: NaN unless the exponent is an integer, signed for an odd one; x = 0: 0 or +-inf)",
    {"exponent": Param(float, check=finite32, doc="finite in float32 (both sides use it rounded to float32)")},
    out_dim=same_width))
register(ComponentSpec("leaky_relu", "x if x>0 else slope*x",
                        {"slope": Param(float, 0.01, finite)}, out_dim=same_width))
register(ComponentSpec("sin", "sin(omega0 * x), SIREN's activation",
                        {"omega0": Param(float, 1.0, finite)}, out_dim=same_width))
register(ComponentSpec("cos", "cos(omega0 * x)", {"omega0": Param(float, 1.0, finite)}, out_dim=same_width))
register(ComponentSpec(
    "softplus", "log(1 + exp(beta x)) / beta; x where beta x > threshold (absent: no threshold)",
    {"beta": Param(float, 1.0, lambda v: finite(v) and v > 0, "finite and > 0"),
     "threshold": Param(float, None, finite, "finite")}, out_dim=same_width))
register(ComponentSpec("gelu", "x * Phi(x), Phi by erf ('none') or torch's tanh approximation ('tanh')",
                        {"approximate": Param(str, "none", lambda v: v in GELU_FORMS, " or ".join(GELU_FORMS))},
                        out_dim=same_width))
register(ComponentSpec("elu", "x if x > 0 else alpha (exp(x) - 1)", {"alpha": Param(float, 1.0, finite)},
                        out_dim=same_width))
register(ComponentSpec("clamp", "min(max(x, min), max); either bound may be absent",
                        {"min": Param(float, None, finite, "finite"), "max": Param(float, None, finite, "finite")},
                        out_dim=same_width, extra_checks=lambda p, d: _ordered(p)))


def _ordered(p):
    if p["min"] is None and p["max"] is None:
        raise ComponentError("clamp: needs min, max or both")
    if p["min"] is not None and p["max"] is not None and p["min"] > p["max"]:
        raise ComponentError(f"clamp: min {p['min']} > max {p['max']}")
