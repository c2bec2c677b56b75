"""toy_softsign: the torch twin, computed by a custom torch op so that ``inshade.export`` sees the
op (and lowers it through lowering.py) instead of the arithmetic inside it."""
from __future__ import annotations

import torch

from inshade.models.registry import WithParams, register


@torch.library.custom_op("inshade_toy::toy_softsign", mutates_args=())
def softsign(x: torch.Tensor, scale: float) -> torch.Tensor:
    return x / (scale + x.abs())


@softsign.register_fake
def _(x, scale):
    return torch.empty_like(x)


@register
class ToySoftsign(WithParams):
    type = "toy_softsign"
    fields = {"scale": (float, 1.0)}

    def forward(self, x):
        return softsign(x, self.scale)
