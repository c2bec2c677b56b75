"""UV-free hashed per-triangle feature hierarchy (Walloner 2024): the torch
twin of codegen/mesh_features.py and shaders/lib/mesh_features.glsl.

A surface point is (triangle k, barycentrics t0, t1); t2 = 1 - t0 - t1; t_i belongs to face
vertex i (the face's index order). Per level l (R = 2^l), in float32:

    a0 = R*t0; a1 = R*t1                          (R*t is exact)
    i = clamp(floor(a0), 0, R-1); j = clamp(floor(a1), 0, R-1-i)
    f0 = a0 - i; f1 = a1 - j
    upright = (i + j == R-1) || (f0 + f1 <= 1.0)
    upright: sub-vertices (W0,W1) = (i,j), (i+1,j), (i,j+1); weights ((1-f0)-f1, f0, f1)
    rotated: (i+1,j+1), (i,j+1), (i+1,j); weights ((f0+f1)-1, 1-f0, 1-f1)
    W2 = R - W0 - W1

This is the thesis's sub-triangle rule written with two coordinates: equal to it inside
sub-triangles, and continuous on their boundaries (where a 3-floor form can name sub-vertices
off the grid). A sub-vertex (k, W) is canonicalised so every face sharing it names it alike:

    some W_s == R (first s): c = corners[k, s]; k' = c >> 2; W' = R at slot c & 3, 0 elsewhere
    else some W_s == 0 (first s): e = edges[k, s]; k' = e >> 4; a = (e >> 2) & 3; b = e & 3;
                                  W'[a] = W[(s+1)%3], W'[b] = W[(s+2)%3], W'[3-a-b] = 0
    else k' = k, W' = W

(tables from geometry/mesh_topology.py), then hashed with uint32 wrap-around arithmetic:

    h = (2654435761 * k') ^ W'0 ^ (805459861 * W'1) ^ (1094488767 * l)
    index = l * T + (h & (T - 1))

(1094488767 = the thesis's 5389456063 mod 2^32: notes §2.6). Level output =
((w0 * f[index0]) + w1 * f[index1]) + w2 * f[index2]; the output concatenates levels 0..L-1.
Barycentric gradients are not propagated (t is detached); gradients reach `table`.
precision "f16": the table is rounded to fp16 in forward (straight-through) and at export.
precision "u8": per feature lane c an affine 8-bit code, value = offset[c] + scale[c] * q / 255
(q = clamp(rint((table - offset) / scale * 255), 0, 255)); forward blends the unit values q / 255
(straight-through: gradients reach `table` as if unquantised) and applies offset + scale * blend
per level, the order the shader uses (unorm8 texels, the affine decode after the blend: it
commutes with the convex blend). The range (buffers `scale`, `offset`) is set by `calibrate()`
(per-lane min/max of the table: on construction and by `from_node` from the bundle's tensors);
export writes q with that range, so a quantisation-aware fit exports what it trained on.
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.components import ComponentError, check_node, resolve_params
from inshade.geometry.mesh_topology import check_tables, mesh_topology

from .latent_pyramid import _round_fp16
from .registry import Component, register

PRIME_K, PRIME_W1, PRIME_L = 2654435761, 805459861, 1094488767
_MASK = 0xFFFFFFFF


def subvertices(t0: torch.Tensor, t1: torch.Tensor, level: int):
    """float32 t0, t1 [...] -> (W0 [..., 3], W1 [..., 3]) int64 sub-vertex coordinates and
    weights [..., 3] float32, in the order the rule lists them."""
    r = float(1 << level)
    a0, a1 = t0.float() * r, t1.float() * r
    i = torch.clamp(torch.floor(a0), 0.0, r - 1.0)
    j = torch.minimum(torch.clamp(torch.floor(a1), min=0.0), (r - 1.0) - i)
    f0, f1 = a0 - i, a1 - j
    upright = (i + j == r - 1.0) | (f0 + f1 <= 1.0)
    i, j = i.long(), j.long()
    w0 = torch.where(upright[..., None], torch.stack([i, i + 1, i], -1), torch.stack([i + 1, i, i + 1], -1))
    w1 = torch.where(upright[..., None], torch.stack([j, j, j + 1], -1), torch.stack([j + 1, j + 1, j], -1))
    weights = torch.where(upright[..., None], torch.stack([(1.0 - f0) - f1, f0, f1], -1),
                          torch.stack([(f0 + f1) - 1.0, 1.0 - f0, 1.0 - f1], -1))
    return w0, w1, weights


def _first(mask: torch.Tensor) -> torch.Tensor:
    """Index of the first True along the last axis (0 where none)."""
    return torch.argmax(mask.to(torch.int8), dim=-1)


def canonical(k: torch.Tensor, w: torch.Tensor, corners: torch.Tensor, edges: torch.Tensor, level: int):
    """k [...] int64, w [..., 3] int64 (W0, W1, W2) -> (k', W'0, W'1) int64 [...] each.
    corners, edges: int64 [faces, 3] (the uint32 tables widened)."""
    r = 1 << level
    s_r = _first(w == r)
    c = corners[k, s_r]
    kc, slot = c >> 2, c & 3
    wc0, wc1 = torch.where(slot == 0, r, 0), torch.where(slot == 1, r, 0)

    s_0 = _first(w == 0)
    e = edges[k, s_0]
    ke, a, b = e >> 4, (e >> 2) & 3, e & 3
    wj = w.gather(-1, ((s_0 + 1) % 3)[..., None])[..., 0]
    wm = w.gather(-1, ((s_0 + 2) % 3)[..., None])[..., 0]
    zero = torch.zeros_like(wj)
    we0 = torch.where(a == 0, wj, torch.where(b == 0, wm, zero))
    we1 = torch.where(a == 1, wj, torch.where(b == 1, wm, zero))

    on_r, on_0 = (w == r).any(-1), (w == 0).any(-1)
    k2 = torch.where(on_r, kc, torch.where(on_0, ke, k))
    w0 = torch.where(on_r, wc0, torch.where(on_0, we0, w[..., 0]))
    w1 = torch.where(on_r, wc1, torch.where(on_0, we1, w[..., 1]))
    return k2, w0, w1


def hash_value(k: torch.Tensor, w0: torch.Tensor, w1: torch.Tensor, level: int) -> torch.Tensor:
    """The full 32-bit h of a canonical sub-vertex (uint32 arithmetic emulated in int64 with masks)."""
    return ((PRIME_K * k) & _MASK) ^ w0 ^ ((PRIME_W1 * w1) & _MASK) ^ ((PRIME_L * level) & _MASK)


def hash_index(k: torch.Tensor, w0: torch.Tensor, w1: torch.Tensor, level: int, table_size: int) -> torch.Tensor:
    """int64 row of the feature table: level * T + (h & (T - 1))."""
    return level * table_size + (hash_value(k, w0, w1, level) & (table_size - 1))


U8_LEVELS = 255


def quantize_u8(table: np.ndarray, scale: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """[rows, F] float -> uint8 q = clamp(rint((table - offset) / scale * 255), 0, 255) per lane."""
    u = (np.asarray(table, np.float32) - offset) / scale
    return np.clip(np.rint(u * np.float32(U8_LEVELS)), 0, U8_LEVELS).astype(np.uint8)


def dequantize_u8(q: np.ndarray, scale: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """uint8 q [rows, F] -> float32 offset + scale * (q / 255)."""
    return (offset + scale * (q.astype(np.float32) / np.float32(U8_LEVELS))).astype(np.float32)


def lane_range(table: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-lane (scale, offset) covering the table: offset = min, scale = max - min (1 when equal)."""
    t = np.asarray(table, np.float32).reshape(-1, np.shape(table)[-1])
    lo, hi = t.min(0), t.max(0)
    return np.where(hi > lo, hi - lo, 1.0).astype(np.float32), lo.astype(np.float32)


def _uint32(name: str, a) -> np.ndarray:
    a = np.asarray(a.cpu().numpy() if torch.is_tensor(a) else a)
    if a.dtype.kind not in "iu" or (a.size and (int(a.min()) < 0 or int(a.max()) > _MASK)):
        raise ComponentError(f"{name}: must hold uint32 values, got {a.dtype}")
    return a.astype(np.uint32)


@register
class MeshFeatures(Component):
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
        self.register_buffer("scale", torch.ones(self.features))
        self.register_buffer("offset", torch.zeros(self.features))
        self.calibrate()

    def calibrate(self, scale=None, offset=None) -> None:
        """Set the u8 range per lane: given (scale, offset), else the table's min/max."""
        if scale is None:
            scale, offset = lane_range(self.table.detach().cpu().numpy())
        scale, offset = np.asarray(scale, np.float32), np.asarray(offset, np.float32)
        if scale.shape != (self.features,) or offset.shape != (self.features,):
            raise ComponentError(f"scale, offset: shape [{self.features}] each, got {list(scale.shape)}, "
                                 f"{list(offset.shape)}")
        if not (np.isfinite(scale).all() and np.isfinite(offset).all() and (scale > 0).all()):
            raise ComponentError("scale: must be finite and > 0 per lane, offset finite")
        self.scale.copy_(torch.from_numpy(scale))
        self.offset.copy_(torch.from_numpy(offset))

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
        if self.precision == "u8":
            u = (r - self.offset) / self.scale
            q = torch.clamp(torch.round(u * U8_LEVELS), 0, U8_LEVELS) / U8_LEVELS
            return u + (q - u).detach() if r.requires_grad else q   # q itself when nothing trains
        return r

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
            outs.append(self.offset + self.scale * blend if self.precision == "u8" else blend)
        return torch.cat(outs, -1).reshape(*lead, self.levels * self.features)

    def export_tensors(self):
        t = self.table.detach().cpu().float()
        owners = {"corners": self.corners.cpu().numpy().astype(np.uint32),
                  "edges": self.edges.cpu().numpy().astype(np.uint32)}
        if self.precision == "u8":
            scale, offset = self.scale.cpu().numpy().copy(), self.offset.cpu().numpy().copy()
            stored = getattr(self, "_stored", None)
            if stored is not None and np.array_equal(stored[0], t.numpy()) \
                    and np.array_equal(stored[1], scale) and np.array_equal(stored[2], offset):
                q = stored[3]      # loaded and untouched: the same integers, bit for bit
            else:
                q = quantize_u8(t.numpy(), scale, offset)
            return {"table": np.ascontiguousarray(q), "scale": scale, "offset": offset, **owners}
        if self.precision == "f16":
            t = t.half().float()
        return {"table": np.ascontiguousarray(t.numpy()), **owners}

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        table = tensors["table"]
        if params["precision"] == "u8":
            q = np.asarray(table, np.uint8)
            scale, offset = np.asarray(tensors["scale"], np.float32), np.asarray(tensors["offset"], np.float32)
            table = dequantize_u8(q, scale, offset)
        m = cls(params["levels"], params["features"], params["table_size"], tensors["corners"],
                tensors["edges"], params["precision"], table=table)
        if params["precision"] == "u8":
            m.calibrate(scale, offset)
            m._stored = (table, scale, offset, q.copy())
        return m
