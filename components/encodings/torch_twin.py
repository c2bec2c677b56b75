"""Input encodings: NeRF's frequencies, triangle waves, spherical harmonics: the torch twins."""
from __future__ import annotations

import math

import torch

from inshade.models.encodings import triangle
from inshade.models.registry import Component, register
from inshade.sh import sh_basis


@register
class Frequency(Component):
    """NeRF positional encoding: [x] + [sin(2^k pi x) for k] + [cos(2^k pi x) for k]."""

    type = "frequency"

    def __init__(self, n_freqs: int, include_input: bool = True):
        super().__init__()
        self.n_freqs, self.include_input = int(n_freqs), bool(include_input)

    def params(self):
        return {"n_freqs": self.n_freqs, "include_input": self.include_input}

    def forward(self, x):
        # 2^k * pi rounded to float32 once, as the shader's literal is.
        scales = [torch.tensor((2.0 ** k) * math.pi, dtype=torch.float32) for k in range(self.n_freqs)]
        parts = [x] if self.include_input else []
        parts += [torch.sin(x * s) for s in scales]
        parts += [torch.cos(x * s) for s in scales]
        return torch.cat(parts, -1)


@register
class TriangleWave(Component):
    """[tri(2^k x) for k < n_freqs], each block as wide as the input."""

    type = "triangle_wave"

    def __init__(self, n_freqs: int):
        super().__init__()
        self.n_freqs = int(n_freqs)

    def params(self):
        return {"n_freqs": self.n_freqs}

    def forward(self, x):
        return torch.cat([triangle(x * (2.0 ** k)) for k in range(self.n_freqs)], -1)


@register
class SphericalHarmonics(Component):
    """Real SH basis (inshade/sh.py table) of a unit direction, bands l < degree."""

    type = "spherical_harmonics"

    def __init__(self, degree: int):
        super().__init__()
        self.degree = int(degree)

    def params(self):
        return {"degree": self.degree}

    def forward(self, x):
        return sh_basis(x, self.degree, xp=torch)
