"""Input encodings: NeRF's frequencies, triangle waves, spherical harmonics: the torch twins."""
from __future__ import annotations

import math

import torch

from inshade.models.encodings import triangle
from inshade.models.registry import REQUIRED, WithParams, register
from inshade.sh import sh_basis


@register
class Frequency(WithParams):
    """NeRF positional encoding: [x] + [sin(2^k pi x) for k] + [cos(2^k pi x) for k]."""

    type = "frequency"
    fields = {"n_freqs": (int, REQUIRED), "include_input": (bool, True)}

    def forward(self, x):
        # 2^k * pi rounded to float32 once, as the shader's literal is.
        scales = [torch.tensor((2.0 ** k) * math.pi, dtype=torch.float32) for k in range(self.n_freqs)]
        parts = [x] if self.include_input else []
        parts += [torch.sin(x * s) for s in scales]
        parts += [torch.cos(x * s) for s in scales]
        return torch.cat(parts, -1)


@register
class TriangleWave(WithParams):
    """[tri(2^k x) for k < n_freqs], each block as wide as the input."""

    type = "triangle_wave"
    fields = {"n_freqs": (int, REQUIRED)}

    def forward(self, x):
        return torch.cat([triangle(x * (2.0 ** k)) for k in range(self.n_freqs)], -1)


@register
class SphericalHarmonics(WithParams):
    """Real SH basis (inshade/sh.py table) of a unit direction, bands l < degree."""

    type = "spherical_harmonics"
    fields = {"degree": (int, REQUIRED)}

    def forward(self, x):
        return sh_basis(x, self.degree, xp=torch)
