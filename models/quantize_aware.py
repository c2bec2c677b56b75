"""The quantizer in the loop: a fit's last steps see every dense layer's weights as a precision stores
them (inshade/quantize.py: f16 rounds weights and biases to float16; i8 rounds each weight row to int8
codes times max |w| / 127), so the network learns around the rounding before it is exported at that
precision. Straight through (Bengio et al. 2013): the forward pass uses the rounded values, the
gradient reaches the float weights unchanged. At i8 the tables with a u8 form (grids, latent
pyramids, sparse voxels, mesh features: models/unorm_lanes.py) take it on entry, their range
calibrated then, and keep it: the export writes the codes the loop saw.

    with quantizer_in_loop(model, "i8"):
        fit(...)                                  # a few hundred steps at a low rate
    bundle = quantized(model.export(...), "i8")   # the very values the loop saw
"""
from __future__ import annotations

import contextlib

import torch
from torch.nn.utils import parametrize

from inshade.components.spec import I8_MAX
from inshade.models.unorm_lanes import UnormLanes

U8_FROM = ("f32", "f16")   # the table precisions i8 codes to u8 (inshade/quantize.py)


def rounded(w: torch.Tensor, precision: str, part: str = "weight") -> torch.Tensor:
    """``w`` as ``precision`` stores it (float32 values; inshade/quantize.py's arithmetic in torch)."""
    if precision == "f16":
        return w.to(torch.float16).to(w.dtype)
    if precision == "i8" and part == "weight":
        peak = w.detach().abs().amax(dim=1, keepdim=True)
        scale = torch.where(peak > 0, peak / I8_MAX, torch.ones_like(peak))
        return torch.clamp(torch.round(w / scale), -I8_MAX, I8_MAX) * scale
    return w   # i8 keeps its biases float32


class _StraightThrough(torch.nn.Module):
    def __init__(self, precision: str, part: str):
        super().__init__()
        self.precision, self.part = precision, part

    def forward(self, w: torch.Tensor) -> torch.Tensor:
        return w + (rounded(w, self.precision, self.part) - w).detach()


def u8_tables(module: torch.nn.Module) -> list:
    """``module``'s table components that have a u8 form and are not in it yet."""
    return [m for m in module.modules()
            if isinstance(m, UnormLanes) and m.params()["precision"] in U8_FROM]


def dense_layers(module: torch.nn.Module) -> list[torch.nn.Linear]:
    """The torch layers of ``module``'s dense components (components/dense/torch_twin.py)."""
    return [m.linear for m in module.modules() if getattr(m, "type", None) == "dense"]


@contextlib.contextmanager
def quantizer_in_loop(module: torch.nn.Module, precision: str):
    """Inside, ``module``'s dense layers compute with their weights (and f16 biases) rounded to
    ``precision``, straight through; the float weights go on training and are left in place after.
    At i8 the tables take their u8 form for good (see above)."""
    layers = dense_layers(module)
    if precision == "i8":
        for table in u8_tables(module):
            table.to_u8()
    parts = ["weight"] + (["bias"] if precision == "f16" else [])
    done = []
    try:
        for layer in layers:
            for part in parts:
                if getattr(layer, part, None) is not None:
                    parametrize.register_parametrization(layer, part, _StraightThrough(precision, part))
                    done.append((layer, part))
        yield layers
    finally:
        for layer, part in done:
            parametrize.remove_parametrizations(layer, part, leave_parametrized=False)
