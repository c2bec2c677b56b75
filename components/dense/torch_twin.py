"""The dense layer: the torch twin (emit.py packs its weights into mat4 blocks)."""
from __future__ import annotations

import numpy as np
import torch

from inshade.models.registry import Component, register


@register
class Dense(Component):
    type = "dense"

    def __init__(self, in_dim: int, out: int, bias: bool = True):
        super().__init__()
        self.linear = torch.nn.Linear(in_dim, out, bias=bias)

    def params(self):
        return {"out": self.linear.out_features, "bias": self.linear.bias is not None}

    def export_tensors(self):
        out = {"weight": self.linear.weight.detach().cpu().float().numpy().copy()}
        if self.linear.bias is not None:
            out["bias"] = self.linear.bias.detach().cpu().float().numpy().copy()
        return out

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        m = cls(in_dim, params["out"], params["bias"])
        with torch.no_grad():
            m.linear.weight.copy_(torch.from_numpy(np.asarray(tensors["weight"])))
            if params["bias"]:
                m.linear.bias.copy_(torch.from_numpy(np.asarray(tensors["bias"])))
        return m

    def forward(self, x):
        return self.linear(x)
