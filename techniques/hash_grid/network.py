"""The instant-NGP network as a bundle graph: a multiresolution hash encoding (components/grids/torch_twin.py
HashGrid, tiny-cuda-nn's rules) into a small ReLU MLP, sized to a byte budget; the MLP-only network
it is compared with at equal bytes; and the optimiser with instant-NGP's settings.

Sizing (Müller et al. 2022, §3): ``levels`` levels of ``features`` features, the coarsest
``base_resolution`` vertices a side and the per-level scale ``b = exp(ln(N_max / N_min) / (L - 1))``
chosen so that the finest level has ``finest`` vertices a side (the target's resolution). The
table size ``2^T`` per level is the largest whose fp16 table plus the fp32 MLP fits the budget
(levels that fit densely keep fewer rows: inshade/grid_layout.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from inshade.components.elementwise import torch_twin as _act
from inshade.components.encodings import torch_twin as _enc
from inshade.components.grids.torch_twin import HashGrid
from inshade.grid_layout import MAX_LOG2_TABLE, grid_levels, table_rows
from inshade.models.fit_loop import adam
from inshade.models.graph import GraphModule

FP16_BYTES, FP32_BYTES = 2, 4
ARCHES = ("hash_grid", "mlp")


class HashGridError(ValueError):
    """A setting the hash-grid trainer cannot use."""


@dataclass(frozen=True)
class GridShape:
    """The encoding's parameters (HashGrid's, tiny-cuda-nn's names)."""
    dims: int
    levels: int
    features: int
    log2_table_size: int
    base_resolution: int
    per_level_scale: float

    def rows(self) -> int:
        return table_rows(grid_levels(self.dims, self.levels, self.base_resolution, self.per_level_scale,
                                      self.log2_table_size))

    def table_bytes(self) -> int:
        """The fp16 table's bytes (what the RG16F texture holds)."""
        return self.rows() * self.features * FP16_BYTES

    def finest_resolution(self) -> int:
        return grid_levels(self.dims, self.levels, self.base_resolution, self.per_level_scale,
                           self.log2_table_size)[-1].resolution


def per_level_scale(finest: int, base_resolution: int, levels: int) -> float:
    """instant-NGP's b: the finest of ``levels`` levels has ``finest`` vertices a side."""
    if levels < 2:
        return 1.0
    return math.exp(math.log(finest / base_resolution) / (levels - 1))


def mlp_bytes(in_dim: int, width: int, depth: int, out_dim: int) -> int:
    """fp32 bytes of ``depth`` hidden dense layers of ``width`` and the output layer (with biases)."""
    params, fan_in = 0, in_dim
    for _ in range(depth):
        params += fan_in * width + width
        fan_in = width
    return (params + fan_in * out_dim + out_dim) * FP32_BYTES


def grid_shape(dims: int, *, levels: int, features: int, base_resolution: int, finest: int,
               budget_bytes: int, width: int, depth: int, out_dim: int,
               log2_table_size: int | None = None) -> GridShape:
    """The encoding for a budget: ``log2_table_size`` as given, else the largest within the budget."""
    b = per_level_scale(finest, base_resolution, levels)
    rest = mlp_bytes(levels * features, width, depth, out_dim)
    if log2_table_size is not None:
        return GridShape(dims, levels, features, int(log2_table_size), base_resolution, b)
    for t in range(MAX_LOG2_TABLE, 2, -1):
        shape = GridShape(dims, levels, features, t, base_resolution, b)
        if shape.table_bytes() + rest <= budget_bytes:
            return shape
    raise HashGridError(f"--budget-kb {budget_bytes / 1024:g}: the MLP alone takes {rest} bytes; no table fits")


def add_mlp(g: GraphModule, src: str, width: int, depth: int, out_dim: int, prefix: str = "l") -> str:
    """(dense width -> relu) * depth -> dense out_dim, after ``src``; returns the last node."""
    for i in range(depth):
        src = g.dense(f"{prefix}{i}", src, width)
        src = g.add(f"a{i}", _act.ReLU(), src)
    return g.dense(f"{prefix}{depth}", src, out_dim)


def add_hash_grid(g: GraphModule, src: str, shape: GridShape, seed: int = 0) -> str:
    """The encoding node ``grid`` (fp16 table, tiny-cuda-nn's coherent prime hash, instant-NGP's
    U[-1e-4, 1e-4] start)."""
    return g.add("grid", HashGrid(shape.dims, shape.levels, shape.features, shape.log2_table_size,
                                  shape.base_resolution, shape.per_level_scale, precision="f16", seed=seed), src)


def baseline_width(in_dim: int, depth: int, out_dim: int, budget_bytes: int) -> int:
    """The widest MLP (a multiple of 4: mat4 blocks) of ``depth`` hidden layers within ``budget_bytes``."""
    width = 4
    while mlp_bytes(in_dim, width + 4, depth, out_dim) <= budget_bytes:
        width += 4
    return width


def add_frequency_mlp(g: GraphModule, src: str, n_freqs: int, depth: int, out_dim: int, budget_bytes: int) -> str:
    """The MLP-only network of ``budget_bytes``: NeRF's frequency encoding (input kept) into a ReLU
    MLP as wide as the budget allows."""
    enc = g.add("enc", _enc.Frequency(n_freqs, include_input=True), src)
    width = baseline_width(g.dim(enc), depth, out_dim, budget_bytes)
    return add_mlp(g, enc, width, depth, out_dim)


def network_bytes(g: GraphModule) -> int:
    """What the bundle's tensors take as the shader reads them: grid tables at fp16 (u8 codes: 1 byte),
    the rest fp32."""
    total = 0
    for name, p in g.named_parameters():
        table = name.endswith(".table")
        u8 = table and g.nodes[name.split(".")[-2]].params()["precision"] == "u8"
        total += p.numel() * (1 if u8 else FP16_BYTES if table else FP32_BYTES)
    return total


def optimizer(g: GraphModule, *, grid_lr: float, mlp_lr: float, grid_eps: float, mlp_eps: float,
              mlp_l2: float, betas=(0.9, 0.99)):
    """Adam with instant-NGP's split: the tables at ``grid_lr`` / ``grid_eps`` without weight decay,
    the MLP (and any other trainable weights) at ``mlp_lr`` / ``mlp_eps`` with L2 ``mlp_l2``.
    Frozen parameters (requires_grad False) are left out."""
    tables = [p for n, p in g.named_parameters() if n.endswith(".table") and p.requires_grad]
    rest = [p for n, p in g.named_parameters() if not n.endswith(".table") and p.requires_grad]
    groups = [{"params": rest, "lr": mlp_lr, "eps": mlp_eps, "weight_decay": mlp_l2}]
    if tables:
        groups.insert(0, {"params": tables, "lr": grid_lr, "eps": grid_eps, "weight_decay": 0.0})
    return adam(groups, betas=betas)
