"""How fast a hash grid + ReLU MLP SDF can change: a sound bound from the weights, and the largest
slope measured on a dense sample.

Sound bound. Within a cell, level l interpolates its vertices multilinearly in p = scale_l x + 0.5,
so the derivative of feature k along axis d is scale_l times a convex combination of the differences
of the vertex pairs along d: at most ``scale_l * M[l, k, d]``, M the largest such difference. A dense
level's M is measured edge by edge (its vertex grid is its table); a hashed level's neighbours sit
on arbitrary rows, so its M is the feature's range over the level's rows (max - min: any two rows).
The encoding's Jacobian is then bounded elementwise by J = scale * M, the first dense layer's by
B = |W1| J, and ||W1 J(x)||_2 <= ||B||_2 (a nonnegative matrix bounding another elementwise bounds
its spectral norm); each later dense layer multiplies by its spectral norm and relu by 1. The
network is continuous and piecewise smooth, so the sup of its Jacobian norm is its Lipschitz constant.

Measured slope: ``max |f(a) - f(b)| / |a - b|`` over short segments (a fraction of the finest cell)
at many points: a lower bound on the true constant, the number the shipped step is scaled by.

Certificate: the sound bound is too loose to step by (rays would crawl), but it proves what a faster
step did: ``certify_positive`` shows f > 0 along a ray segment by halving it until every piece's
midpoint value exceeds the bound times its half length.
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.components import grid_node_levels
from inshade.components.unorm import decode
from inshade.models.graph import GraphModule


def encoding_jacobian_bound(grid) -> np.ndarray:
    """J [levels * features, dims]: |d feature / d x_d| <= J, for a HashGrid node (see the module doc)."""
    table = grid.table.detach().double().cpu().numpy()
    if grid.params()["precision"] == "f16":
        table = table.astype(np.float16).astype(np.float64)
    if grid.params()["precision"] == "u8":   # the decoded codes
        r = grid.unorm_range()
        table = decode(grid.codes(grid.table), r["scale"], r["offset"]).astype(np.float64)
    dims, feats = grid.dims, grid.params()["features"]
    rows = []
    levels = grid_node_levels(grid.type, grid.params(), dims)
    for level in levels:
        part = table[level.offset:level.offset + level.rows]
        if level.dense:
            res = level.resolution
            cube = part[:res ** dims].reshape((res,) * dims + (feats,))     # axis order z, y, x (x fastest)
            m = np.stack([np.abs(np.diff(cube, axis=dims - 1 - d)).reshape(-1, feats).max(0)
                          for d in range(dims)], -1)                          # [F, dims]
        else:
            spread = part.max(0) - part.min(0)
            m = np.repeat(spread[:, None], dims, 1)
        rows.append(float(level.scale) * m)
    return np.concatenate(rows, 0)


def sound_bound(g: GraphModule, grid_node: str = "grid", input_scale: float = 1.0) -> float:
    """Upper bound on the Lipschitz constant (L2) of a chain graph ``[affine ->] grid -> (dense,
    relu)* -> dense``, with respect to the graph input; ``input_scale`` is the factor a frozen affine
    before the grid applies (0.5 for q -> 0.5 q + 0.5)."""
    ids = list(g.nodes)
    start = ids.index(grid_node)
    j = encoding_jacobian_bound(g.nodes[grid_node])
    first = True
    total = 1.0
    for node_id in ids[start + 1:]:
        comp = g.nodes[node_id]
        if comp.type == "dense":
            w = comp.linear.weight.detach().double().cpu().numpy()
            if first:
                total = float(np.linalg.norm(np.abs(w) @ j, 2))
                first = False
            else:
                total *= float(np.linalg.norm(w, 2))
        elif comp.type != "relu":
            raise ValueError(f"{node_id}: {comp.type} has no bound here (dense and relu only)")
    return total * input_scale


def measured_slope(f, points: torch.Tensor, h: float, seed: int = 0, chunk: int = 65536) -> float:
    """max |f(p + h u) - f(p)| / h over ``points`` [N, dims] and, per point, the axis directions and
    one random unit direction u."""
    gen = torch.Generator().manual_seed(seed)
    dims = points.shape[1]
    best = 0.0
    with torch.no_grad():
        for i in range(0, points.shape[0], chunk):
            p = points[i:i + chunk]
            base = f(p)
            rand = torch.randn(p.shape, generator=gen)
            dirs = [torch.eye(dims)[d].expand_as(p) for d in range(dims)] + [rand / rand.norm(dim=1, keepdim=True)]
            for u in dirs:
                best = max(best, float(((f(p + h * u) - base).abs() / h).max()))
    return best


def certify_positive(f, ro: torch.Tensor, rd: torch.Tensor, t0: torch.Tensor, t1: torch.Tensor, lipschitz: float,
                     min_half: float = 1e-7, chunk: int = 65536, max_evaluations: int = 50_000_000):
    """Per ray, whether ``f(ro + t rd) > 0`` is proved for every t in [t0, t1] from ``lipschitz`` alone
    (rd unit, f a world distance). Segments are halved until each one's midpoint value exceeds
    ``lipschitz`` x its half length (then f > 0 on all of it); a midpoint with f <= 0 is a crossing.
    Returns (proved [N] bool, crossing [N] bool, evaluations): a ray neither proved nor crossing
    has a segment below ``min_half`` (undecided). Batched breadth first: large batches, few steps."""
    n = ro.shape[0]
    proved = torch.ones(n, dtype=torch.bool)
    crossing = torch.zeros(n, dtype=torch.bool)
    idx = torch.arange(n)[t1 > t0]
    a, b = t0[idx].double(), t1[idx].double()
    evaluations = 0
    with torch.no_grad():
        while idx.numel():
            mid, half = 0.5 * (a + b), 0.5 * (b - a)
            p = (ro[idx].double() + rd[idx].double() * mid[:, None]).float()
            d = torch.cat([f(p[i:i + chunk]) for i in range(0, p.shape[0], chunk)]).double()
            evaluations += int(idx.numel())
            crossed = d <= 0
            crossing[idx[crossed]] = True
            split = (d <= lipschitz * half) & ~crossed
            stuck = split & (half < min_half)
            proved[idx[crossed | stuck]] = False
            split = split & ~stuck & ~crossing[idx]
            if evaluations > max_evaluations:
                proved[idx[split]] = False
                break
            idx, a, m, b = idx[split], a[split], mid[split], b[split]
            idx, a, b = torch.cat([idx, idx]), torch.cat([a, m]), torch.cat([m, b])
    return proved & ~crossing, crossing, evaluations
