"""UV-free hashed per-triangle feature hierarchy (Walloner 2024): the torch twin (the rules it follows,
and the precisions: models/mesh_features.py)."""
from __future__ import annotations

import numpy as np
import torch

from inshade.components import ComponentError, check_node, resolve_params
from inshade.geometry.mesh_topology import check_tables, mesh_topology
from inshade.models.latent_pyramid import _round_fp16
from inshade.components.unorm import decode
from inshade.models.mesh_features import canonical, hash_index, subvertices
from inshade.models.registry import Component, register
from inshade.models.unorm_lanes import UnormLanes


def _uint32(name: str, a) -> np.ndarray:
    a = np.asarray(a.cpu().numpy() if torch.is_tensor(a) else a)
    if a.dtype.kind not in "iu" or (a.size and (int(a.min()) < 0 or int(a.max()) > 0xFFFFFFFF)):
        raise ComponentError(f"{name}: must hold uint32 values, got {a.dtype}")
    return a.astype(np.uint32)


@register
class MeshFeatures(UnormLanes, Component):
    """`table` [levels * table_size, features] (nn.Parameter, U[-init_scale, init_scale]);
    corners / edges: the owner tables (buffers). forward(x [..., 3] = (triangle id as float,
    t0, t1)) -> [..., levels * features]."""

    type = "mesh_features"

    def __init__(self, levels: int, features: int, table_size: int, corners, edges, precision: str = "f16",
                 init_scale: float = 1e-4, seed: int = 0, table=None):
        super().__init__()
        corners, edges = _uint32("corners", corners), _uint32("edges", edges)
        faces = int(corners.shape[0]) if corners.ndim == 2 else 0
        self.levels, self.features, self.table_size = int(levels), int(features), int(table_size)
        self.precision = precision
        check_node(self.type, resolve_params(self.type, self.params_with(faces)), 3)
        check_tables(corners, edges, faces)
        self.register_buffer("corners", torch.from_numpy(corners.astype(np.int64)))
        self.register_buffer("edges", torch.from_numpy(edges.astype(np.int64)))
        rows = self.levels * self.table_size
        if table is None:
            gen = torch.Generator().manual_seed(seed)
            table = (torch.rand((rows, self.features), generator=gen) * 2 - 1) * init_scale
        table = torch.as_tensor(np.asarray(table, np.float32))
        if tuple(table.shape) != (rows, self.features):
            raise ComponentError(f"table: shape {list(table.shape)}, expected {[rows, self.features]}")
        self.table = torch.nn.Parameter(table.clone())
        self.calibrate()

    def unorm_values(self) -> torch.Tensor:
        return self.table

    @classmethod
    def for_mesh(cls, vertices, faces, levels: int, features: int, table_size: int, **kw) -> "MeshFeatures":
        """Welds the mesh and builds its owner tables (geometry/mesh_topology.py)."""
        topo = mesh_topology(vertices, faces)
        return cls(levels, features, table_size, topo.corners, topo.edges, **kw)

    @property
    def faces(self) -> int:
        return int(self.corners.shape[0])

    def params_with(self, faces: int) -> dict:
        return {"levels": self.levels, "features": self.features, "table_size": self.table_size,
                "faces": faces, "precision": self.precision}

    def params(self):
        return self.params_with(self.faces)

    def rows(self, index: torch.Tensor) -> torch.Tensor:
        """Table rows as the lookup sees them (fp16-rounded for precision f16; for u8 the unit
        values q / 255, straight-through)."""
        r = self.table[index]
        if self.precision == "f16":
            return _round_fp16(r)
        return self.unit(r) if self.precision == "u8" else r

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        lead = x.shape[:-1]
        x = x.reshape(-1, 3).detach().float()
        k = x[:, 0].long()
        if k.numel() and (int(k.min()) < 0 or int(k.max()) >= self.faces):
            raise ValueError(f"mesh_features: triangle id outside 0..{self.faces - 1} "
                             f"(got {int(k.min())}..{int(k.max())})")
        outs = []
        for level in range(self.levels):
            w0, w1, weight = subvertices(x[:, 1], x[:, 2], level)
            w = torch.stack([w0, w1, (1 << level) - w0 - w1], -1)          # [M, 3 sub-vertices, 3]
            kk, c0, c1 = canonical(k[:, None].expand_as(w0), w, self.corners, self.edges, level)
            rows = self.rows(hash_index(kk, c0, c1, level, self.table_size))   # [M, 3, F]
            weight = weight[..., None].to(rows.dtype)
            blend = (weight[:, 0] * rows[:, 0] + weight[:, 1] * rows[:, 1]) + weight[:, 2] * rows[:, 2]
            outs.append(self.decode(blend) if self.precision == "u8" else blend)
        return torch.cat(outs, -1).reshape(*lead, self.levels * self.features)

    def export_tensors(self):
        t = self.table.detach().cpu().float()
        owners = {"corners": self.corners.cpu().numpy().astype(np.uint32),
                  "edges": self.edges.cpu().numpy().astype(np.uint32)}
        if self.precision == "u8":
            return {"table": self.codes(t), **self.unorm_range(), **owners}
        if self.precision == "f16":
            t = t.half().float()
        return {"table": np.ascontiguousarray(t.numpy()), **owners}

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        u8 = params["precision"] == "u8"
        table = decode(tensors["table"], tensors["scale"], tensors["offset"]) if u8 else tensors["table"]
        m = cls(params["levels"], params["features"], params["table_size"], tensors["corners"],
                tensors["edges"], params["precision"], table=table)
        if u8:
            m.calibrate(tensors["scale"], tensors["offset"])
        return m
