"""Elementwise activations and ops (logarithms, rounding, fmod / remainder, power); their GLSL twins
are in codegen/activations.py."""
from __future__ import annotations

import numpy as np
import torch

from .registry import Component, register


class _Elementwise(Component):
    fn = staticmethod(lambda x: x)

    def forward(self, x):
        return self.fn(x)


@register
class ReLU(_Elementwise):
    type = "relu"
    fn = staticmethod(torch.relu)


@register
class Sigmoid(_Elementwise):
    type = "sigmoid"
    fn = staticmethod(torch.sigmoid)


@register
class Tanh(_Elementwise):
    type = "tanh"
    fn = staticmethod(torch.tanh)


def _stable_softplus(x):
    """The stable form the shader uses too: max(x, 0) + log1p(exp(-|x|))."""
    return torch.clamp_min(x, 0) + torch.log1p(torch.exp(-x.abs()))


@register
class Softplus(Component):
    """softplus(x) = log(1 + exp(beta x)) / beta; with ``threshold`` (torch.nn.Softplus's), x where
    beta x > threshold. Without one (the default, and bundles written before these parameters)
    the stable form everywhere."""

    type = "softplus"

    def __init__(self, beta: float = 1.0, threshold: float | None = None):
        super().__init__()
        self.beta, self.threshold = float(beta), None if threshold is None else float(threshold)

    def params(self):
        return {"beta": self.beta, **({"threshold": self.threshold} if self.threshold is not None else {})}

    def forward(self, x):
        if self.threshold is None:
            return _stable_softplus(x) if self.beta == 1.0 else _stable_softplus(x * self.beta) / self.beta
        return torch.nn.functional.softplus(x, self.beta, self.threshold)


@register
class Exp(_Elementwise):
    type = "exp"
    fn = staticmethod(torch.exp)


@register
class Identity(_Elementwise):
    type = "identity"


@register
class LeakyReLU(Component):
    type = "leaky_relu"

    def __init__(self, slope: float = 0.01):
        super().__init__()
        self.slope = float(slope)

    def params(self):
        return {"slope": self.slope}

    def forward(self, x):
        return torch.nn.functional.leaky_relu(x, self.slope)


class _Periodic(Component):
    fn = staticmethod(torch.sin)

    def __init__(self, omega0: float = 1.0):
        super().__init__()
        self.omega0 = float(omega0)

    def params(self):
        return {"omega0": self.omega0}

    def forward(self, x):
        return self.fn(self.omega0 * x)


@register
class Sin(_Periodic):
    """SIREN's activation sin(omega0 * x)."""

    type = "sin"


@register
class Cos(_Periodic):
    """cos(omega0 * x)."""

    type = "cos"
    fn = staticmethod(torch.cos)


@register
class Expm1(_Elementwise):
    """exp(x) - 1: maps a decoder's log(1 + f) back to f."""

    type = "expm1"
    fn = staticmethod(torch.expm1)


@register
class Abs(_Elementwise):
    type = "abs"
    fn = staticmethod(torch.abs)


@register
class Sqrt(_Elementwise):
    type = "sqrt"
    fn = staticmethod(torch.sqrt)


@register
class Reciprocal(_Elementwise):
    """1 / x (a constant divided by a value: the constant is a following affine scale)."""

    type = "reciprocal"
    fn = staticmethod(torch.reciprocal)


@register
class Erf(_Elementwise):
    """The error function (ONNX graphs spell GELU with it)."""

    type = "erf"
    fn = staticmethod(torch.erf)


@register
class SiLU(_Elementwise):
    """x * sigmoid(x), as x / (1 + exp(-x))."""

    type = "silu"
    fn = staticmethod(torch.nn.functional.silu)


@register
class GELU(Component):
    """x * Phi(x): ``approximate`` "none" (erf) or "tanh", as torch.nn.GELU."""

    type = "gelu"

    def __init__(self, approximate: str = "none"):
        super().__init__()
        self.approximate = approximate

    def params(self):
        return {"approximate": self.approximate}

    def forward(self, x):
        return torch.nn.functional.gelu(x, approximate=self.approximate)


@register
class ELU(Component):
    """x if x > 0 else alpha (exp(x) - 1)."""

    type = "elu"

    def __init__(self, alpha: float = 1.0):
        super().__init__()
        self.alpha = float(alpha)

    def params(self):
        return {"alpha": self.alpha}

    def forward(self, x):
        return torch.nn.functional.elu(x, self.alpha)


@register
class Clamp(Component):
    """clamp(x, min, max); either bound may be absent (None)."""

    type = "clamp"

    def __init__(self, min: float | None = None, max: float | None = None):  # noqa: A002  (torch's names)
        super().__init__()
        self.min, self.max = (None if v is None else float(v) for v in (min, max))

    def params(self):
        return {k: v for k, v in (("min", self.min), ("max", self.max)) if v is not None}

    def forward(self, x):
        return torch.clamp(x, self.min, self.max)


@register
class Log(_Elementwise):
    type = "log"
    fn = staticmethod(torch.log)


@register
class Log2(_Elementwise):
    type = "log2"
    fn = staticmethod(torch.log2)


@register
class Floor(_Elementwise):
    type = "floor"
    fn = staticmethod(torch.floor)


@register
class Ceil(_Elementwise):
    type = "ceil"
    fn = staticmethod(torch.ceil)


@register
class Trunc(_Elementwise):
    type = "trunc"
    fn = staticmethod(torch.trunc)


@register
class Round(_Elementwise):
    """Halves to even (torch.round's only mode without `decimals`)."""

    type = "round"
    fn = staticmethod(torch.round)


@register
class Frac(_Elementwise):
    """x - trunc(x): the sign of x."""

    type = "frac"
    fn = staticmethod(torch.frac)


def _float32(v: float) -> float:
    """A parameter as the float32 the shader's literal holds (torch rounds a divisor so too; an
    exponent it would keep in double, a difference of ~1e-9 |log x| relative)."""
    return float(np.float32(v))


class _WithDivisor(Component):
    fn = staticmethod(torch.fmod)

    def __init__(self, divisor: float):
        super().__init__()
        self.divisor = _float32(divisor)

    def params(self):
        return {"divisor": self.divisor}

    def forward(self, x):
        return self.fn(x, self.divisor)


@register
class Fmod(_WithDivisor):
    """C's fmod by a constant: the sign of x."""

    type = "fmod"


@register
class Remainder(_WithDivisor):
    """Python's % by a constant: the sign of the divisor."""

    type = "remainder"
    fn = staticmethod(torch.remainder)


@register
class Power(Component):
    """x ** exponent for a constant exponent (torch.pow(x, exponent))."""

    type = "power"

    def __init__(self, exponent: float):
        super().__init__()
        self.exponent = _float32(exponent)

    def params(self):
        return {"exponent": self.exponent}

    def forward(self, x):
        return torch.pow(x, self.exponent)
