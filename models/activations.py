"""Elementwise activations; their GLSL twins are in codegen/activations.py."""
from __future__ import annotations

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


@register
class Softplus(_Elementwise):
    type = "softplus"
    # The stable form the shader uses too: max(x, 0) + log1p(exp(-|x|)).
    fn = staticmethod(lambda x: torch.clamp_min(x, 0) + torch.log1p(torch.exp(-x.abs())))


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


@register
class Sin(Component):
    """SIREN's activation sin(omega0 * x)."""

    type = "sin"

    def __init__(self, omega0: float = 1.0):
        super().__init__()
        self.omega0 = float(omega0)

    def params(self):
        return {"omega0": self.omega0}

    def forward(self, x):
        return torch.sin(self.omega0 * x)


@register
class Expm1(_Elementwise):
    """exp(x) - 1: maps a decoder's log(1 + f) back to f."""

    type = "expm1"
    fn = staticmethod(torch.expm1)
