"""The residual connection: input [a | b] (2n lanes) -> a + b; GLSL twin in codegen/add.py."""
from __future__ import annotations

import torch

from .registry import Component, register


@register
class Add(Component):
    type = "add"

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        n = x.shape[-1]
        if n < 2 or n % 2:
            raise ValueError(f"add: input must be [a | b], an even width >= 2, got {n}")
        return x[..., :n // 2] + x[..., n // 2:]
