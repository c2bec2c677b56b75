"""Elementwise operations between two branches: input [a | b] (2n lanes) -> a op b (n lanes), for
op in add (residual connections), sub, mul, div, atan2 (torch.atan2(a, b)). GLSL twin in codegen/binary.py."""
from __future__ import annotations

import torch

from .registry import Component, register

OPS = {"add": torch.add, "sub": torch.sub, "mul": torch.mul, "div": torch.div, "atan2": torch.atan2}


class _Binary(Component):
    def forward(self, x: torch.Tensor) -> torch.Tensor:
        n = x.shape[-1]
        if n < 2 or n % 2:
            raise ValueError(f"{self.type}: input must be [a | b], an even width >= 2, got {n}")
        return OPS[self.type](x[..., :n // 2], x[..., n // 2:])


def _make(op: str) -> type:
    return register(type(op.capitalize(), (_Binary,), {"type": op, "__doc__": f"{op}(a, b) of the halves [a | b]"}))


Add, Sub, Mul, Div, Atan2 = (_make(op) for op in OPS)
