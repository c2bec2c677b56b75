"""Rows of a learned table at computed integer indices (nn.Embedding / gather, a hash encoding's
table read): a uint32 program over the input lanes, then a row per index. GLSL twin in
codegen/int_gather.py; the component's rules in inshade/components.py."""
from __future__ import annotations

import numpy as np
import torch

from .registry import Component, register

MASK = 0xFFFFFFFF
# every result is reduced modulo 2^32 in int64, as GLSL's uint arithmetic wraps
OPS = {
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
                vals.append(OPS[op](vals[args[0]], vals[args[1]]))
        rows = self.table.shape[0]
        out = []
        for k in self.indices:
            idx = vals[k]
            inside = idx < rows
            row = self.table[torch.where(inside, idx, torch.zeros_like(idx))]
            out.append(row * inside.unsqueeze(-1).to(row.dtype))
        return torch.cat(out, -1)
