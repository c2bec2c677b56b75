"""Differentiable Indirection arrays (Datta et al. 2023): the torch twin (texel convention and the
lookup itself: models/lookup_array.py)."""
from __future__ import annotations

import math

import numpy as np
import torch

from inshade.models.encodings import triangle
from inshade.models.lookup_array import dequantize, multilinear, quantize
from inshade.models.registry import Component, register

NONLINEARITIES = {
    "none": lambda c, n: c,
    "triangle": lambda c, n: triangle(c),
    "sinusoid": lambda c, n: 0.5 * (1.0 + torch.sin(n * c)),
}


@register
class LookupArray(Component):
    """A d-dimensional array of C-channel cells, F(cells) interpolated multilinearly.

    `nonlinearity` F is the paper's periodic wrap ("triangle", or "sinusoid" (1+sin(n c))/2);
    export bakes F into the cells and quantises them to `bits`.
    """

    type = "lookup_array"

    def __init__(self, resolution, channels: int, bits: int = 32, nonlinearity: str = "none",
                 frequency: float = math.pi, init: str | torch.Tensor = "ramp", baked: str = "none"):
        super().__init__()
        self.resolution = [int(n) for n in resolution]
        self.channels, self.bits = int(channels), int(bits)
        self.nonlinearity, self.frequency, self.baked = nonlinearity, float(frequency), baked
        shape = tuple(reversed(self.resolution)) + (self.channels,)
        if isinstance(init, torch.Tensor):
            cells = init.reshape(shape).float()
        elif init == "ramp":  # identity uv-map, repeated over channels (paper 1.3)
            axes = [torch.linspace(0, 1, n) if n > 1 else torch.zeros(1) for n in self.resolution]
            grid = torch.meshgrid(*reversed(axes), indexing="ij")  # [N_{d-1}..N_0]
            coords = list(reversed(grid))  # coords[k] varies along axis k
            cells = torch.stack([coords[c % len(coords)] for c in range(self.channels)], -1)
        elif init == "zeros":
            cells = torch.zeros(shape)
        else:
            raise ValueError(f"unknown init {init!r}")
        self.cells = torch.nn.Parameter(cells.clone())

    def table(self) -> torch.Tensor:
        return NONLINEARITIES[self.nonlinearity](self.cells, self.frequency)

    def forward(self, x):
        return multilinear(self.table(), x)

    def params(self):
        baked = self.nonlinearity if self.nonlinearity != "none" else self.baked
        return {"resolution": self.resolution, "channels": self.channels, "bits": self.bits, "baked": baked}

    def export_tensors(self):
        table = self.table().detach().cpu().float().numpy()
        stored = getattr(self, "_stored", None)
        if stored is not None and np.array_equal(stored[0], table):
            return dict(stored[1])  # imported and untouched: the same integers, bit for bit
        if self.bits == 32:
            return {"cells": np.ascontiguousarray(table, dtype=np.float32)}
        q, scale, offset = quantize(table, self.bits)
        return {"cells": q, "scale": scale, "offset": offset}

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        cells = tensors["cells"]
        if params["bits"] != 32:
            cells = dequantize(cells, tensors["scale"], tensors["offset"], params["bits"])
        m = cls(params["resolution"], params["channels"], params["bits"], "none",
                init=torch.from_numpy(np.array(cells, dtype=np.float32)), baked=params["baked"])
        if params["bits"] != 32:
            m._stored = (np.array(cells, dtype=np.float32), {k: np.array(v) for k, v in tensors.items()})
        return m
