"""Operations on the feature axis that an imported network needs besides layers and activations:
per-lane affine maps (folded constants, BatchNorm in eval mode), lane selection (slices, splits,
permutations, broadcasts), reductions and LayerNorm. GLSL twins in codegen/feature_ops.py."""
from __future__ import annotations

import numpy as np
import torch

from .registry import Component, register


def _tensor(a) -> torch.Tensor:
    return torch.as_tensor(np.asarray(a, np.float32))


@register
class Affine(Component):
    """y = x * scale + offset, per lane."""

    type = "affine"

    def __init__(self, scale, offset):
        super().__init__()
        self.register_buffer("scale", _tensor(scale).reshape(-1))
        self.register_buffer("offset", _tensor(offset).reshape(-1))

    def export_tensors(self):
        return {"scale": self.scale.cpu().numpy().copy(), "offset": self.offset.cpu().numpy().copy()}

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        return cls(tensors["scale"], tensors["offset"])

    def forward(self, x):
        return x * self.scale + self.offset


@register
class Select(Component):
    """y = x[lanes]: any lanes, in any order, repeats allowed."""

    type = "select"

    def __init__(self, lanes):
        super().__init__()
        self.lanes = [int(i) for i in lanes]
        self.register_buffer("index", torch.tensor(self.lanes, dtype=torch.long), persistent=False)

    def params(self):
        return {"lanes": list(self.lanes)}

    def forward(self, x):
        return x.index_select(-1, self.index.to(x.device))


REDUCE_OPS = ("sum", "mean", "norm", "max", "min")


@register
class Reduce(Component):
    """The input split into ``groups`` equal runs of lanes, each reduced to one lane."""

    type = "reduce"

    def __init__(self, op: str, groups: int = 1):
        super().__init__()
        self.op, self.groups = op, int(groups)

    def params(self):
        return {"op": self.op, "groups": self.groups}

    def forward(self, x):
        g = x.reshape(*x.shape[:-1], self.groups, x.shape[-1] // self.groups)
        if self.op == "norm":
            return torch.linalg.vector_norm(g, dim=-1)
        if self.op in ("max", "min"):
            return getattr(torch, f"a{self.op}")(g, dim=-1)
        return getattr(torch, self.op)(g, dim=-1)


@register
class LayerNorm(Component):
    """torch.nn.LayerNorm over each of ``groups`` equal runs of lanes: (x - mean) / sqrt(var + eps)
    (biased variance), then * weight + bias (per lane of a run) when ``affine``."""

    type = "layer_norm"

    def __init__(self, size: int, eps: float = 1e-5, groups: int = 1, weight=None, bias=None):
        super().__init__()
        self.size, self.eps, self.groups = int(size), float(eps), int(groups)
        self.affine = weight is not None
        if self.affine:
            self.register_buffer("weight", _tensor(weight).reshape(-1))
            self.register_buffer("bias", _tensor(bias).reshape(-1))

    def params(self):
        return {"eps": self.eps, "groups": self.groups, "affine": self.affine}

    def export_tensors(self):
        return {"weight": self.weight.cpu().numpy().copy(), "bias": self.bias.cpu().numpy().copy()} if self.affine else {}

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        return cls(in_dim // params["groups"], params["eps"], params["groups"],
                   tensors.get("weight"), tensors.get("bias"))

    def forward(self, x):
        g = x.reshape(*x.shape[:-1], self.groups, self.size)
        w, b = (self.weight, self.bias) if self.affine else (None, None)
        return torch.nn.functional.layer_norm(g, (self.size,), w, b, self.eps).reshape(x.shape)


COMPARE = {"gt": torch.gt, "ge": torch.ge, "lt": torch.lt, "le": torch.le}


@register
class Where(Component):
    """[a | b | x | y] -> where(a op b, x, y), lane by lane."""

    type = "where"

    def __init__(self, op: str):
        super().__init__()
        self.op = op

    def params(self):
        return {"op": self.op}

    def forward(self, v):
        a, b, x, y = v.chunk(4, dim=-1)
        return torch.where(COMPARE[self.op](a, b), x, y)
