"""toy_softsign: what the torch twin's custom op becomes when inshade.export captures a module."""
from __future__ import annotations

from inshade.convert.registry import torch_op


@torch_op("toy_softsign")
def _toy_softsign(walk, node, f, scale):
    return walk.L.unary(f, "toy_softsign", {"scale": float(scale)})
