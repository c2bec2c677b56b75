"""Multiresolution grid encodings (instant-NGP's hash grid, tiny-cuda-nn's DenseGrid): the torch twin
of emit.py. The rules (levels, rows, indexing, interpolation) are inshade/grid_layout.py's,
which are tiny-cuda-nn's; integer work is uint32 arithmetic emulated in int64 with masks, so the rows
read are bit-identical to the shader's.

p = scale * x + 0.5 is rounded twice (product, then sum), as GLSL 3.30 / ES 3.00 spell it and as
llvmpipe runs it (also its fma()); tiny-cuda-nn's pos_fract uses fmaf (one rounding). The two differ
by at most one ulp of p (2^-11 at p ~ 2048) where they differ at all, i.e. by ulp(p) times the
level's difference between neighbouring vertices (docs/tcnn.md). Interpolation and summation are float32 in the GLSL order: corner weights
multiplied axis by axis, corners summed in corner order (bit d of the corner number is axis d).
precision "f16": the table is rounded to fp16 in forward (straight-through) and at export; "u8": each
level blends the unit values q / 255 and decodes offset + scale * blend per feature, as the shader
does (models/unorm_lanes.py: the range is the table's at construction, or the bundle's).
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.components import ComponentError, GRID_KINDS, check_node, grid_node_levels, resolve_params
from inshade.components.unorm import decode
from inshade.grid_layout import HASH_PRIMES, MASK, table_rows
from inshade.models.latent_pyramid import _round_fp16
from inshade.models.registry import Component, register
from inshade.models.unorm_lanes import UnormLanes


def level_rows(x: torch.Tensor, level, primes, dims: int):
    """x [M, dims] float32 -> (rows [M, 2^dims] int64 level-local, weights [M, 2^dims] float32)."""
    p = x * torch.tensor(level.scale) + 0.5                # two roundings, as the shader (see above)
    g = torch.floor(p)
    f = p - g
    c = g.long() & MASK                                   # (uint32_t)(int)floor(p)
    rows, weights = [], []
    for corner in range(1 << dims):
        w = torch.ones_like(f[:, 0])
        cc = []
        for d in range(dims):
            bit = (corner >> d) & 1
            w = w * (f[:, d] if bit else 1.0 - f[:, d])
            cc.append((c[:, d] + bit) & MASK)
        index = torch.zeros_like(cc[0])
        if level.dense:
            stride = 1
            for d in range(dims):
                index = (index + cc[d] * stride) & MASK
                stride = stride * level.resolution
        else:
            for d in range(dims):
                index = index ^ ((cc[d] * primes[d]) & MASK)
        rows.append(index % level.rows)
        weights.append(w)
    return torch.stack(rows, -1), torch.stack(weights, -1)


@register
class HashGrid(UnormLanes, Component):
    """`table` [rows, features] (nn.Parameter, U[-init_scale, init_scale] as instant-NGP starts it).
    forward(x [..., dims] in [0, 1]) -> [..., levels * features], level-major."""

    type = "hash_grid"

    def __init__(self, dims: int, levels: int, features: int = 2, log2_table_size: int = 19,
                 base_resolution: int = 16, per_level_scale: float = 2.0, hash: str = "coherent_prime",
                 precision: str = "f16", init_scale: float = 1e-4, seed: int = 0, table=None):
        super().__init__()
        self.dims = int(dims)
        self._p = {"levels": int(levels), "features": int(features), "base_resolution": int(base_resolution),
                   "per_level_scale": float(per_level_scale), "precision": precision,
                   **self._kind_params(log2_table_size, hash)}
        self._p = resolve_params(self.type, self._p)
        check_node(self.type, self._p, self.dims)
        self.levels = grid_node_levels(self.type, self._p, self.dims)
        self.primes = HASH_PRIMES[self._p.get("hash", "coherent_prime")]
        shape = (table_rows(self.levels), self._p["features"])
        if table is None:
            gen = torch.Generator().manual_seed(seed)
            table = (torch.rand(shape, generator=gen) * 2 - 1) * init_scale
        table = torch.as_tensor(np.asarray(table, np.float32))
        if tuple(table.shape) != shape:
            raise ComponentError(f"table: shape {list(table.shape)}, expected {list(shape)}")
        self.table = torch.nn.Parameter(table.clone())
        if precision == "u8":
            self.calibrate()

    def unorm_values(self) -> torch.Tensor:
        return self.table

    def set_precision(self, precision: str) -> None:
        self._p["precision"] = precision

    @staticmethod
    def _kind_params(log2_table_size, hash):
        return {"log2_table_size": int(log2_table_size), "hash": hash}

    def params(self):
        return dict(self._p)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        lead = x.shape[:-1]
        x = x.reshape(-1, self.dims).float()
        precision = self._p["precision"]
        table = {"f16": _round_fp16, "u8": self.unit}.get(precision, lambda t: t)(self.table)
        outs = []
        for level in self.levels:
            rows, w = level_rows(x.detach(), level, self.primes, self.dims)
            vals = table[rows + level.offset]                       # [M, corners, F]
            acc = w[:, 0, None] * vals[:, 0]
            for corner in range(1, rows.shape[1]):
                acc = acc + w[:, corner, None] * vals[:, corner]
            outs.append(self.decode(acc) if precision == "u8" else acc)
        return torch.cat(outs, -1).reshape(*lead, len(self.levels) * self._p["features"])

    def export_tensors(self):
        t = self.table.detach().cpu().float()
        if self._p["precision"] == "u8":
            return {"table": self.codes(t), **self.unorm_range()}
        if self._p["precision"] == "f16":
            t = t.half().float()
        return {"table": np.ascontiguousarray(t.numpy())}

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        if params["precision"] != "u8":
            return cls(in_dim, **params, table=tensors["table"])
        m = cls(in_dim, **params, table=decode(tensors["table"], tensors["scale"], tensors["offset"]))
        m.calibrate(tensors["scale"], tensors["offset"])
        return m


@register
class DenseGrid(HashGrid):
    """tiny-cuda-nn's DenseGrid: the same rules, every level indexed densely."""

    type = "dense_grid"

    def __init__(self, dims: int, levels: int, features: int = 2, base_resolution: int = 16,
                 per_level_scale: float = 2.0, precision: str = "f16", **kw):
        super().__init__(dims, levels, features, base_resolution=base_resolution,
                         per_level_scale=per_level_scale, precision=precision, **kw)

    @staticmethod
    def _kind_params(log2_table_size, hash):
        return {}


assert set(GRID_KINDS) == {HashGrid.type, DenseGrid.type}
