"""Elementwise functions, one lane in, one lane out (activations, logarithms, rounding, fmod / remainder,
power): the torch twins. Most are one torch function of the value and the node's parameters, made by
``_twin``; the rest are classes."""
from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from inshade.models.registry import REQUIRED, WithParams, register


class _Elementwise(WithParams):
    """fn(x, *the parameters, in the order of ``fields``)."""

    fn = staticmethod(lambda x: x)

    def forward(self, x):
        return self.fn(x, *[getattr(self, name) for name in self.fields])


def _twin(name: str, type_name: str, fn=None, doc: str | None = None, fields: dict | None = None,
          base: type = _Elementwise) -> type:
    """A registered twin: ``base`` with ``fn`` and ``fields`` (WithParams.fields), each where given."""
    attrs = {"type": type_name, "__module__": __name__, "__qualname__": name, "__doc__": doc}
    attrs.update({} if fn is None else {"fn": staticmethod(fn)}, **({} if fields is None else {"fields": fields}))
    return register(type(name, (base,), attrs))


def _float32(v: float) -> float:
    """A parameter as the float32 the shader's literal holds (torch rounds a divisor so too; an
    exponent it would keep in double, a difference of ~1e-9 |log x| relative)."""
    return float(np.float32(v))


def _stable_softplus(x):
    """The stable form the shader uses too: max(x, 0) + log1p(exp(-|x|))."""
    return torch.clamp_min(x, 0) + torch.log1p(torch.exp(-x.abs()))


class _Periodic(WithParams):
    fields = {"omega0": (float, 1.0)}

    def forward(self, x):
        return self.fn(self.omega0 * x)


ReLU = _twin("ReLU", "relu", torch.relu)
Sigmoid = _twin("Sigmoid", "sigmoid", torch.sigmoid)
Tanh = _twin("Tanh", "tanh", torch.tanh)


@register
class Softplus(WithParams):
    """softplus(x) = log(1 + exp(beta x)) / beta; with ``threshold`` (torch.nn.Softplus's), x where
    beta x > threshold. Without one (the default, and bundles written before these parameters)
    the stable form everywhere."""

    type = "softplus"
    fields = {"beta": (float, 1.0), "threshold": (float, None)}

    def params(self):
        return {"beta": self.beta, **({"threshold": self.threshold} if self.threshold is not None else {})}

    def forward(self, x):
        if self.threshold is None:
            return _stable_softplus(x) if self.beta == 1.0 else _stable_softplus(x * self.beta) / self.beta
        return F.softplus(x, self.beta, self.threshold)


Exp = _twin("Exp", "exp", torch.exp)
Identity = _twin("Identity", "identity")
LeakyReLU = _twin("LeakyReLU", "leaky_relu", F.leaky_relu, fields={"slope": (float, 0.01)})
Sin = _twin("Sin", "sin", torch.sin, "SIREN's activation sin(omega0 * x).", base=_Periodic)
Cos = _twin("Cos", "cos", torch.cos, "cos(omega0 * x).", base=_Periodic)
Expm1 = _twin("Expm1", "expm1", torch.expm1, "exp(x) - 1: maps a decoder's log(1 + f) back to f.")
Abs = _twin("Abs", "abs", torch.abs)
Sqrt = _twin("Sqrt", "sqrt", torch.sqrt)
Reciprocal = _twin("Reciprocal", "reciprocal", torch.reciprocal,
                   "1 / x (a constant divided by a value: the constant is a following affine scale).")
Erf = _twin("Erf", "erf", torch.erf, "The error function (ONNX graphs spell GELU with it).")
SiLU = _twin("SiLU", "silu", F.silu, "x * sigmoid(x), as x / (1 + exp(-x)).")
GELU = _twin("GELU", "gelu", lambda x, approximate: F.gelu(x, approximate=approximate),
             'x * Phi(x): ``approximate`` "none" (erf) or "tanh", as torch.nn.GELU.',
             {"approximate": (str, "none")})
ELU = _twin("ELU", "elu", F.elu, "x if x > 0 else alpha (exp(x) - 1).", {"alpha": (float, 1.0)})


@register
class Clamp(WithParams):
    """clamp(x, min, max); either bound may be absent (None)."""

    type = "clamp"
    fields = {"min": (float, None), "max": (float, None)}   # torch's names

    def params(self):
        return {k: v for k, v in (("min", self.min), ("max", self.max)) if v is not None}

    def forward(self, x):
        return torch.clamp(x, self.min, self.max)


Log = _twin("Log", "log", torch.log)
Log2 = _twin("Log2", "log2", torch.log2)
Floor = _twin("Floor", "floor", torch.floor)
Ceil = _twin("Ceil", "ceil", torch.ceil)
Trunc = _twin("Trunc", "trunc", torch.trunc)
Round = _twin("Round", "round", torch.round, "Halves to even (torch.round's only mode without `decimals`).")
Frac = _twin("Frac", "frac", torch.frac, "x - trunc(x): the sign of x.")
_DIVISOR = {"divisor": (_float32, REQUIRED)}
Fmod = _twin("Fmod", "fmod", torch.fmod, "C's fmod by a constant: the sign of x.", _DIVISOR)
Remainder = _twin("Remainder", "remainder", torch.remainder, "Python's % by a constant: the sign of the divisor.",
                  _DIVISOR)
Power = _twin("Power", "power", torch.pow, "x ** exponent for a constant exponent (torch.pow(x, exponent)).",
              {"exponent": (_float32, REQUIRED)})
