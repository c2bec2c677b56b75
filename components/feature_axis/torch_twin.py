"""The feature axis of an imported network: the torch twins of per-lane affine maps (folded constants,
BatchNorm in eval mode), lane selection (slices, splits, permutations, broadcasts), reductions,
LayerNorm and comparisons; of two branches combined lane by lane (add for residual connections, sub,
mul, div, atan2); and of rows of a learned table at computed integer indices (int_gather). GLSL
twins in emit.py; the components' rules in spec.py."""
from __future__ import annotations

import numpy as np
import torch

from inshade.models.registry import Component, register


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


# --- two branches: input [a | b] (2n lanes) -> a op b (n lanes) ------------------------------

BINARY_OPS = {"add": torch.add, "sub": torch.sub, "mul": torch.mul, "div": torch.div, "atan2": torch.atan2}


class _Binary(Component):
    def forward(self, x: torch.Tensor) -> torch.Tensor:
        n = x.shape[-1]
        if n < 2 or n % 2:
            raise ValueError(f"{self.type}: input must be [a | b], an even width >= 2, got {n}")
        return BINARY_OPS[self.type](x[..., :n // 2], x[..., n // 2:])


def _make(op: str) -> type:
    return register(type(op.capitalize(), (_Binary,), {"type": op, "__doc__": f"{op}(a, b) of the halves [a | b]"}))


Add, Sub, Mul, Div, Atan2 = (_make(op) for op in BINARY_OPS)


# --- int_gather: a uint32 program over the input lanes, then a table row per index -----------

MASK = 0xFFFFFFFF
# every result is reduced modulo 2^32 in int64, as GLSL's uint arithmetic wraps
INT_OPS = {
    "add": lambda a, b: (a + b) & MASK,
    "sub": lambda a, b: (a - b) & MASK,
    "mul": lambda a, b: ((a * (b & 0xFFFF)) + (((a * (b >> 16)) & 0xFFFF) << 16)) & MASK,
    "xor": lambda a, b: a ^ b,
    "and": lambda a, b: a & b,
    "or": lambda a, b: a | b,
}


@register
class IntGather(Component):
    type = "int_gather"

    def __init__(self, program: list, indices: list, rows: int, features: int, table=None):
        super().__init__()
        self.program, self.indices = [list(op) for op in program], list(indices)
        t = torch.zeros(rows, features) if table is None else torch.as_tensor(np.asarray(table, np.float32))
        self.table = torch.nn.Parameter(t.clone())

    def params(self) -> dict:
        rows, features = self.table.shape
        return {"program": self.program, "indices": self.indices, "rows": int(rows), "features": int(features)}

    def export_tensors(self) -> dict[str, np.ndarray]:
        return {"table": self.table.detach().cpu().numpy().astype(np.float32)}

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        return cls(**params, table=tensors["table"])

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        vals = []
        for op, *args in self.program:
            if op == "lane":   # float -> int as torch casts (toward 0), as a uint32 bit pattern
                vals.append(torch.trunc(x[..., args[0]]).to(torch.int64) & MASK)
            elif op == "const":
                vals.append(torch.full(x.shape[:-1], args[0], dtype=torch.int64, device=x.device))
            elif op == "shl":
                vals.append((vals[args[0]] << args[1]) & MASK)
            else:
                vals.append(INT_OPS[op](vals[args[0]], vals[args[1]]))
        rows = self.table.shape[0]
        out = []
        for k in self.indices:
            idx = vals[k]
            inside = idx < rows
            row = self.table[torch.where(inside, idx, torch.zeros_like(idx))]
            out.append(row * inside.unsqueeze(-1).to(row.dtype))
        return torch.cat(out, -1)
