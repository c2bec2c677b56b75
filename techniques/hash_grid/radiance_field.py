"""The hash-grid radiance field (instant-NGP's NeRF, Mueller et al. 2022): its networks as bundle
graphs, the MLP-only baseline, the occupancy grid, and the bytes each holds.

The bundle convention (what a reader of instant-ngp snapshots writes too)
--------------------------------------------------------------------------
An asset is two bundles of kind ``hash_grid_radiance_field`` (scene.json names them):

1. The field, prefix ``hgrf`` (the folder itself):
     inputs   x [3]  position in the box, [0, 1]^3 (world p -> x = (p - aabb.min) / side)
              d [3]  the ray's unit direction (world = box axes: the box is a scaled, shifted cube),
                     as is: not instant-NGP's (d + 1) / 2
     outputs  density [1]  >= 0; extinction per box unit = density x render.sigma_scale
              rgb [3]      linear RGB in [0, 1]
   The graph (instant-NGP's NeRF network, no biases like tiny-cuda-nn's fully fused MLPs; width 64
   and two colour layers as instant-NGP, the trainer's ``width`` and ``depth``):
     x -> hash_grid (3D, L levels x F features) -> dense width, relu -> dense 16 = "geo"
     geo lane 0 -> clamp(max 15) -> exp = density
     d -> spherical_harmonics (degree 4: 16 lanes)
     [geo (16), sh (16)] -> (dense width, relu) x depth -> dense 3 -> sigmoid = rgb
   Only the ports and ``render`` are the contract: any graph with them is marched the same way.
   Density activation: exp, as instant-NGP (empty space goes to zero fast, and the network moves the
   density over orders of magnitude with bounded lanes), of the lane clamped at 15: instant-NGP's
   truncated exp bounds the gradient; the clamp bounds the value too, so neither training nor the
   shader can overflow (exp(15) x sigma_scale x step already makes a sample opaque).
   ``render`` (the march's settings; radiance_field_render.py checks each field):
     aabb [[x0, y0, z0], [x1, y1, z1]] (a cube, world units), step (dt in box units),
     max_steps, background [r, g, b] (linear), sigma_scale, occupancy_resolution (G).

2. The occupancy grid, prefix ``hgocc`` (subfolder ``occupancy``): input x [3], output occupancy [1];
   one 3D ``lookup_array`` node of G^3 cells, 8-bit, values 0 or 1. Cell c = (i, j, k) covers
   [c / G, (c + 1) / G] of the box; node c of the array is that cell's bit (so the array is read at
   x = c / (G - 1), exactly on node c, and tested > 0.5). 1: the field may have density there, the
   march evaluates it; 0: empty, the march skips the cell. instant-NGP's density bitfield, at the
   cascade that covers the box, is such a grid (here stored [k, j, i], x fastest).

scene.json draws them with passes/radiance_field_hash_grid.frag (radiance_field_render.py): networks
``.`` (hgrf) and ``occupancy`` (hgocc), and a texture ``u_hgrf_reference``, the ground truth at the
scene's camera as an 8-bit sRGB image, for the reference, split and error views.

The march (radiance_field_march.py, lib/radiance_field_march.glsl): samples at t0 + (i + 0.5) dt
from the box entry t0, alpha = 1 - exp(-density sigma_scale dt), composited front to back until the
transmittance falls under 1e-4, then the background; unoccupied cells are stepped over.

Bytes count what a GPU holds: hash tables at their precision (f16: 2 bytes a value), dense weights
as float32, the occupancy grid one byte a cell (reported apart: both networks need one).
"""
from __future__ import annotations

import math

import numpy as np
import torch

from inshade.components.dense.torch_twin import Dense
from inshade.components.elementwise.torch_twin import Clamp, Exp, ReLU, Sigmoid
from inshade.components.encodings.torch_twin import SphericalHarmonics
from inshade.components.feature_axis.torch_twin import Select
from inshade.components.lookup_array.torch_twin import LookupArray
from inshade.grid_layout import MAX_LOG2_TABLE
from inshade.models.graph import GraphModule

from .network import FP32_BYTES, GridShape, HashGridError, add_frequency_mlp, add_hash_grid, per_level_scale
from .radiance_field_render import KIND

GEO = 16            # the density network's output lanes (lane 0: density before exp)
SH_DEGREE = 4       # direction encoding: bands l < 4, 16 lanes
DENSITY_CLAMP = 15.0


def _dense(n_in: int, n_out: int, gen: torch.Generator) -> Dense:
    """A bias-free layer (tiny-cuda-nn's), He-uniform (ReLU networks)."""
    layer = Dense(n_in, n_out, bias=False)
    bound = math.sqrt(6.0 / n_in)
    with torch.no_grad():
        layer.linear.weight.copy_((torch.rand(n_out, n_in, generator=gen) * 2 - 1) * bound)
    return layer


def _heads(g: GraphModule, geo: str, width: int, depth: int, seed: int) -> None:
    """density and rgb from the 16 geometry lanes and the direction (both networks have them)."""
    gen = torch.Generator().manual_seed(seed + 1)
    g.add("density_lane", Select([0]), geo)
    g.add("density_clamp", Clamp(max=DENSITY_CLAMP), "density_lane")
    g.add("density", Exp(), "density_clamp")
    g.add("sh", SphericalHarmonics(SH_DEGREE), "d")
    src, n_in = [geo, "sh"], GEO + SH_DEGREE ** 2
    for k in range(depth):
        g.add(f"rgb{k}", _dense(n_in, width, gen), src)
        src, n_in = g.add(f"rgb{k}_relu", ReLU(), f"rgb{k}"), width
    g.add(f"rgb{depth}", _dense(n_in, 3, gen), src)
    g.add("rgb", Sigmoid(), f"rgb{depth}")
    g.output("density", "density", "density")
    g.output("rgb", "rgb", "rgb")


def heads_bytes(width: int, depth: int) -> int:
    """float32 bytes of the colour network (bias-free)."""
    fan_in, params = GEO + SH_DEGREE ** 2, 0
    for _ in range(depth):
        params, fan_in = params + fan_in * width, width
    return (params + fan_in * 3) * FP32_BYTES


def mlp_bytes(levels: int, features: int, width: int, depth: int) -> int:
    """float32 bytes of the field's two MLPs (density: one hidden layer; colour: ``depth``)."""
    return (levels * features * width + width * GEO) * FP32_BYTES + heads_bytes(width, depth)


def grid_shape(s) -> GridShape:
    """The field's encoding: ``log2_table_size`` as given, else the largest whose fp16 table and
    the MLPs fit ``budget_kb``."""
    b = per_level_scale(s.finest, s.base_resolution, s.levels)
    if s.log2_table_size is not None:
        return GridShape(3, s.levels, s.features, int(s.log2_table_size), s.base_resolution, b)
    budget, rest = int(s.budget_kb * 1024), mlp_bytes(s.levels, s.features, s.width, s.depth)
    for t in range(MAX_LOG2_TABLE, 2, -1):
        shape = GridShape(3, s.levels, s.features, t, s.base_resolution, b)
        if shape.table_bytes() + rest <= budget:
            return shape
    raise HashGridError(f"--budget-kb {s.budget_kb:g}: the MLPs alone take {rest} bytes; no table fits")


def _inputs() -> GraphModule:
    return GraphModule([("x", 3, "position"), ("d", 3, "direction")])


def field_graph(shape: GridShape, width: int, depth: int, seed: int = 0) -> GraphModule:
    """The hash-grid field (module docstring): the table U[-1e-4, 1e-4] as instant-NGP starts it."""
    g = _inputs()
    add_hash_grid(g, "x", shape, seed)
    gen = torch.Generator().manual_seed(seed)
    g.add("geo0", _dense(shape.levels * shape.features, width, gen), "grid")
    g.add("geo0_relu", ReLU(), "geo0")
    g.add("geo", _dense(width, GEO, gen), "geo0_relu")
    _heads(g, "geo", width, depth, seed)
    return g


def baseline_graph(n_freqs: int, depth: int, width: int, head_depth: int, budget_bytes: int,
                   seed: int = 0) -> GraphModule:
    """The MLP-only network of ``budget_bytes``: x -> NeRF frequency encoding -> a ReLU MLP of
    ``depth`` hidden layers, as wide as the bytes left by the colour network allow -> 16 geometry
    lanes, then the same heads as the field (network.add_frequency_mlp)."""
    g = _inputs()
    torch.manual_seed(seed)
    geo = add_frequency_mlp(g, "x", n_freqs, depth, GEO, budget_bytes - heads_bytes(width, head_depth))
    _heads(g, geo, width, head_depth, seed)
    return g


# --- occupancy -------------------------------------------------------------------------------------

def cell_probes(resolution: int, per_axis: int) -> torch.Tensor:
    """[per_axis^3, 3] offsets inside a cell (fractions, a centred lattice)."""
    a = (torch.arange(per_axis, dtype=torch.float32) + 0.5) / per_axis
    z, y, x = torch.meshgrid(a, a, a, indexing="ij")
    return torch.stack([x, y, z], -1).reshape(-1, 3)


def density_max(density_fn, resolution: int, per_axis: int, chunk: int = 1 << 17) -> torch.Tensor:
    """[G, G, G] ([k, j, i]) max of ``density_fn`` (x [P, 3] -> [P]) over a lattice of per_axis^3
    points inside each cell."""
    probes = cell_probes(resolution, per_axis)
    g = resolution
    k, j, i = torch.meshgrid(*(torch.arange(g, dtype=torch.float32),) * 3, indexing="ij")
    corners = torch.stack([i, j, k], -1).reshape(-1, 1, 3)
    out = torch.empty(g ** 3)
    per = max(1, chunk // len(probes))
    with torch.no_grad():
        for s in range(0, g ** 3, per):
            x = ((corners[s:s + per] + probes) / g).reshape(-1, 3).clamp(0.0, 1.0)
            out[s:s + per] = density_fn(x).reshape(-1, len(probes)).amax(1)
    return out.reshape(g, g, g)


def dilate(cells: torch.Tensor) -> torch.Tensor:
    """A bool grid grown by one cell along each axis and diagonal (3^3 max filter)."""
    x = cells.float()[None, None]
    return torch.nn.functional.max_pool3d(x, 3, stride=1, padding=1)[0, 0] > 0


def occupancy_graph(cells: torch.Tensor) -> GraphModule:
    """The occupancy bundle's graph: a G^3 8-bit lookup array of the bits ``cells`` [k, j, i]."""
    g = cells.shape[0]
    graph = GraphModule([("x", 3, "position")])
    graph.add("occupancy", LookupArray([g] * 3, 1, 8, init=cells.float()[..., None]), "x")
    graph.output("occupancy", "occupancy", "occupancy")
    for p in graph.parameters():
        p.requires_grad_(False)
    return graph


def occupancy_bundle(cells: torch.Tensor, provenance: dict | None = None):
    return occupancy_graph(cells).export(KIND, "hash_grid_radiance_field_occupancy", provenance=provenance)


def occupancy_cells(bundle) -> torch.Tensor:
    """The bool [G, G, G] ([k, j, i]) grid an occupancy bundle holds."""
    from inshade.models.lookup_array import dequantize

    node = bundle.nodes[0]
    t = bundle.tensors
    cells = dequantize(t["occupancy.cells"], t["occupancy.scale"], t["occupancy.offset"], node.params["bits"])
    g = node.params["resolution"][0]
    return torch.from_numpy(np.asarray(cells, np.float32).reshape(g, g, g) > 0.5)
