"""The dense layer: the torch twin (emit.py packs its weights into mat4 blocks)."""
from __future__ import annotations

import numpy as np
import torch

from inshade.models.registry import Component, register


@register
class Dense(Component):
    type = "dense"

    def __init__(self, in_dim: int, out: int, bias: bool = True, precision: str = "f32", weight_scale=None):
        super().__init__()
        self.linear = torch.nn.Linear(in_dim, out, bias=bias)
        # a quantized layer's storage (inshade/quantize.py): its weights are the dequantized values
        self.precision, self.weight_scale = precision, weight_scale

    def params(self):
        return {"out": self.linear.out_features, "bias": self.linear.bias is not None,
                **({"precision": self.precision} if self.precision != "f32" else {})}

    def export_tensors(self):
        out = {"weight": self.linear.weight.detach().cpu().float().numpy().copy()}
        if self.linear.bias is not None:
            out["bias"] = self.linear.bias.detach().cpu().float().numpy().copy()
        if self.precision == "i8":
            out["weight_scale"] = np.array(self.weight_scale, np.float32)
        return out

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        precision = params.get("precision", "f32")
        m = cls(in_dim, params["out"], params["bias"], precision,
                tensors["weight_scale"] if precision == "i8" else None)
        with torch.no_grad():
            m.linear.weight.copy_(torch.from_numpy(np.array(tensors["weight"], np.float32)))
            if params["bias"]:
                m.linear.bias.copy_(torch.from_numpy(np.array(tensors["bias"], np.float32)))
        return m

    def forward(self, x):
        return self.linear(x)
