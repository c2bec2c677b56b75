"""The triangle wave that the triangle_wave encoding (components/encodings/torch_twin.py) and lookup
arrays' triangle coordinates (models/lookup_array.py) share; GLSL's twin is inshade_triangle in
shaders/lib/activations.glsl."""
from __future__ import annotations

import torch


def triangle(t: torch.Tensor) -> torch.Tensor:
    """Non-negative triangle wave, period 2, tri(0)=0, tri(1)=1: identity on [0, 1]."""
    return 1.0 - torch.abs(torch.remainder(t, 2.0) - 1.0)
