"""Sub-scene transfer networks for large scenes (Learnt Transfer, Dhawal et al. 2022 §4.4): the region split,
the δ-margin, the variance merge, the blend weights and the generated GLSL that selects a network by
the hit point's region. numpy only (no torch): the runtime's chunks hook calls ``region_chunks``.

- ``RegionGrid(x0, z0, x1, z1, nx, nz)``: a uniform grid over the floor plan (xz, y up). A point's
  cell is ``clamp(floor((p.xz - min) * inv_cell), 0, n - 1)``: points beyond the plan belong to the
  border cells.
- ``margin_mask(grid, cells, p, delta)``: the training points of a region, the points of its cells
  plus those within ``delta`` (world units, in xz) of them -- the paper's "extra δ area" (Fig. 4).
- ``merge_regions(grid, cell_ids, transfer, max_networks, max_variance)``: greedy agglomeration of
  neighbouring regions, cheapest first, by the variance of the transfer vectors of their union
  (the trace of the covariance of the 16 coefficients; CPCA-like "variance analysis" without the
  principal components). Returns the table cell -> network, networks numbered by first cell.
- ``blend_weights(grid, table, band, p)``: up to four (network, weight) pairs per point. Within
  ``band`` (cell units, per axis) of a cell side whose neighbour has another network the two
  networks are mixed linearly (0.5 / 0.5 on the side, own network alone at ``band`` inside), the
  bilinear product at corners; pairs naming one network are summed into the first. ``band`` 0:
  a hard switch. float32 arithmetic in the order of shaders/lib/prt_regions.glsl (the torch twin
  ``region_twin.region_transfer`` uses this function, so weights agree bit for bit).
- bundles: each region network is an ordinary transfer bundle (kind "prt") whose
  ``meta.render.transfer`` frame is its own region's box (positions normalised to it) and whose
  ``meta.render.region`` = ``region_record(...)`` names the grid, the full table, the blend band
  and its own index. ``read_region_set`` checks a scene's bundles agree; ``region_chunks`` emits
  the ``<prt_network>`` chunk for lib/prt.glsl: all networks (each ``<network_PREFIX>``), a
  dynamic branch per network, and ``PRT_NET_EVAL`` = ``prt_regions_eval`` (lib/prt_regions.glsl)
  with the identity frame, so the unchanged sdf_prt pass shades the blended transfer. The deferred
  mesh_prt pass calls the same prt_transfer with the G-buffer's surface point, so a mesh scene
  selects and blends by region the same way (tests/techniques/prt/test_prt_regions_mesh.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from inshade.codegen.glsl import flt
from inshade.geometry.sdf import f32

REGION_FORMAT = 1
MAX_NETWORKS = 32        # GLSL branch chain and scene size sanity bound
F32 = np.float32


class RegionError(ValueError):
    """A region split or region set that cannot be used; the message names the field."""


def _finite(v, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(v):
        raise RegionError(f"{where}: must be a finite number, got {v!r}")
    return float(v)


def _count(v, where: str, hi: int = 64) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 1 <= v <= hi:
        raise RegionError(f"{where}: must be an int in 1..{hi}, got {v!r}")
    return int(v)


@dataclass(frozen=True)
class RegionGrid:
    """A uniform nx x nz grid over the floor-plan rectangle [x0, x1] x [z0, z1]."""

    x0: float
    z0: float
    x1: float
    z1: float
    nx: int
    nz: int

    def __post_init__(self):
        for k in ("x0", "z0", "x1", "z1"):
            object.__setattr__(self, k, f32(_finite(getattr(self, k), f"grid.{k}")))
        for k in ("nx", "nz"):
            object.__setattr__(self, k, _count(getattr(self, k), f"grid.{k}"))
        if not (self.x1 > self.x0 and self.z1 > self.z0):
            raise RegionError(f"grid: needs x1 > x0 and z1 > z0, got [{self.x0}, {self.x1}] x [{self.z0}, {self.z1}]")

    @property
    def cells(self) -> int:
        return self.nx * self.nz

    @property
    def cell_size(self) -> tuple[float, float]:
        return (self.x1 - self.x0) / self.nx, (self.z1 - self.z0) / self.nz

    @property
    def inv_cell(self) -> tuple[float, float]:
        """float32 reciprocals of the cell size (the shader multiplies by them)."""
        cw, cd = self.cell_size
        return f32(1.0 / cw), f32(1.0 / cd)

    def coords(self, p) -> np.ndarray:
        """Cell coordinates [N, 2] float32: (p.xz - min) * inv_cell, as the shader computes them."""
        p = _points(p)
        lo = np.array([self.x0, self.z0], F32)
        return ((p[:, [0, 2]] - lo) * np.array(self.inv_cell, F32)).astype(F32)

    def cell_index(self, p) -> np.ndarray:
        """[N, 2] int: clamped (ix, iz) of each point."""
        c = np.floor(self.coords(p)).astype(np.int64)
        return np.stack([np.clip(c[:, 0], 0, self.nx - 1), np.clip(c[:, 1], 0, self.nz - 1)], -1)

    def cell_of(self, p) -> np.ndarray:
        """[N] int: the cell id iz * nx + ix of each point."""
        ci = self.cell_index(p)
        return ci[:, 1] * self.nx + ci[:, 0]

    def rect(self, cell: int) -> tuple[float, float, float, float]:
        """(x0, z0, x1, z1) of a cell; border cells reach to infinity outwards (they own the points
        beyond the plan)."""
        ix, iz = int(cell) % self.nx, int(cell) // self.nx
        cw, cd = self.cell_size
        return (-math.inf if ix == 0 else self.x0 + ix * cw, -math.inf if iz == 0 else self.z0 + iz * cd,
                math.inf if ix == self.nx - 1 else self.x0 + (ix + 1) * cw,
                math.inf if iz == self.nz - 1 else self.z0 + (iz + 1) * cd)

    def neighbours(self, cell: int) -> list[int]:
        ix, iz = cell % self.nx, cell // self.nx
        out = []
        for dx, dz in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            jx, jz = ix + dx, iz + dz
            if 0 <= jx < self.nx and 0 <= jz < self.nz:
                out.append(jz * self.nx + jx)
        return out

    def to_dict(self) -> dict:
        return {"min": [self.x0, self.z0], "max": [self.x1, self.z1], "cells": [self.nx, self.nz]}

    @classmethod
    def from_dict(cls, d, where: str = "grid") -> "RegionGrid":
        if not isinstance(d, dict) or set(d) != {"min", "max", "cells"}:
            raise RegionError(f"{where}: must be {{\"min\": [x0, z0], \"max\": [x1, z1], \"cells\": [nx, nz]}}")
        for k in ("min", "max", "cells"):
            if not isinstance(d[k], (list, tuple)) or len(d[k]) != 2:
                raise RegionError(f"{where}.{k}: must be 2 numbers, got {d[k]!r}")
        try:
            return cls(d["min"][0], d["min"][1], d["max"][0], d["max"][1], d["cells"][0], d["cells"][1])
        except RegionError as exc:
            raise RegionError(f"{where}: {exc}") from None


def _points(p) -> np.ndarray:
    p = np.asarray(p, F32)
    if p.ndim != 2 or p.shape[1] < 3:
        raise RegionError(f"points: must be [N, 3], got shape {list(p.shape)}")
    if not np.isfinite(p[:, :3]).all():
        raise RegionError("points: contain NaN/inf")
    return p


def _check_table(grid: RegionGrid, table) -> np.ndarray:
    t = np.asarray(table)
    if t.shape != (grid.cells,) or not np.issubdtype(t.dtype, np.integer):
        raise RegionError(f"table: must be {grid.cells} ints (one network per cell), got {list(np.shape(table))} "
                          f"of {t.dtype}")
    n = int(t.max()) + 1 if t.size else 0
    if t.min() < 0 or sorted(set(t.tolist())) != list(range(n)):
        raise RegionError(f"table: network ids must be 0..N-1 with every id used, got {sorted(set(t.tolist()))}")
    if n > MAX_NETWORKS:
        raise RegionError(f"table: {n} networks; at most {MAX_NETWORKS}")
    return t.astype(np.int64)


# the δ-margin ----------------------------------------------------------------------------------------
def margin_mask(grid: RegionGrid, cells, p, delta: float) -> np.ndarray:
    """[N] bool: points in the union of ``cells`` or within ``delta`` (xz distance) of it."""
    delta = _finite(delta, "delta")
    if delta < 0:
        raise RegionError(f"delta: must be >= 0, got {delta}")
    cells = [int(c) for c in cells]
    if not cells or any(not 0 <= c < grid.cells for c in cells):
        raise RegionError(f"cells: must be a non-empty list of ids in 0..{grid.cells - 1}, got {cells}")
    p = _points(p).astype(np.float64)
    x, z = p[:, 0], p[:, 2]
    keep = np.zeros(p.shape[0], bool)
    for c in cells:
        x0, z0, x1, z1 = grid.rect(c)
        dx = np.maximum(np.maximum(x0 - x, x - x1), 0.0)
        dz = np.maximum(np.maximum(z0 - z, z - z1), 0.0)
        keep |= dx * dx + dz * dz <= delta * delta
    return keep


# the variance merge ----------------------------------------------------------------------------------
def _stats(cell_ids: np.ndarray, transfer: np.ndarray, cells: int):
    n = np.bincount(cell_ids, minlength=cells).astype(np.float64)
    s = np.zeros((cells, transfer.shape[1]))
    q = np.zeros(cells)
    np.add.at(s, cell_ids, transfer)
    np.add.at(q, cell_ids, (transfer * transfer).sum(1))
    return n, s, q


def _variance(n: float, s: np.ndarray, q: float) -> float:
    """Trace of the covariance of a pooled set: E|t|^2 - |E t|^2 (0 for an empty set)."""
    if n <= 0:
        return 0.0
    return max(0.0, q / n - float((s / n) @ (s / n)))


def merge_regions(grid: RegionGrid, cell_ids, transfer, max_networks: int | None = None,
                  max_variance: float | None = None) -> np.ndarray:
    """The table cell -> network [cells] int64 after greedy merging (module docstring): while some
    pair of neighbouring regions exists, merge the pair whose union has the least transfer variance
    if there are more than ``max_networks`` regions or that variance is <= ``max_variance``."""
    if max_networks is None and max_variance is None:
        raise RegionError("merge: give max_networks and/or max_variance (else nothing decides when to stop)")
    if max_networks is not None:
        max_networks = _count(max_networks, "max_networks", grid.cells)
    if max_variance is not None and _finite(max_variance, "max_variance") < 0:
        raise RegionError(f"max_variance: must be >= 0, got {max_variance}")
    ids = np.asarray(cell_ids)
    t = np.asarray(transfer, np.float64)
    bad_ids = ids.ndim != 1 or not np.issubdtype(ids.dtype, np.integer)
    if bad_ids or (ids.size and (ids.min() < 0 or ids.max() >= grid.cells)):
        raise RegionError(f"cell_ids: must be [N] ints in 0..{grid.cells - 1}")
    if t.ndim != 2 or t.shape[0] != ids.shape[0]:
        raise RegionError(f"transfer: must be [N, K] with N = {ids.shape[0]} (one row per cell id), "
                          f"got {list(t.shape)}")
    if not np.isfinite(t).all():
        raise RegionError("transfer: contains NaN/inf")
    n, s, q = _stats(ids.astype(np.int64), t, grid.cells)
    label = list(range(grid.cells))                     # region of each cell (its smallest cell id)
    members = {c: [c] for c in range(grid.cells)}
    stats = {c: (n[c], s[c].copy(), q[c]) for c in range(grid.cells)}
    while len(members) > 1:
        best = None
        for a in sorted(members):
            for c in members[a]:
                for d in grid.neighbours(c):
                    b = label[d]
                    if b <= a:
                        continue
                    na, sa, qa = stats[a]
                    nb, sb, qb = stats[b]
                    cost = _variance(na + nb, sa + sb, qa + qb)
                    if best is None or (cost, a, b) < best:
                        best = (cost, a, b)
        if best is None:
            break
        cost, a, b = best
        over = max_networks is not None and len(members) > max_networks
        cheap = max_variance is not None and cost <= max_variance
        if not (over or cheap):
            break
        for c in members[b]:
            label[c] = a
        members[a] = sorted(members[a] + members.pop(b))
        (na, sa, qa), (nb, sb, qb) = stats[a], stats.pop(b)
        stats[a] = (na + nb, sa + sb, qa + qb)
    order = {r: i for i, r in enumerate(sorted(members))}   # networks numbered by first cell
    return np.array([order[label[c]] for c in range(grid.cells)], np.int64)


def region_variances(grid: RegionGrid, table, cell_ids, transfer) -> list[float]:
    """The transfer variance of each network's region (merge statistics for reports)."""
    table = _check_table(grid, table)
    n, s, q = _stats(np.asarray(cell_ids, np.int64), np.asarray(transfer, np.float64), grid.cells)
    out = []
    for r in range(int(table.max()) + 1):
        sel = table == r
        out.append(_variance(n[sel].sum(), s[sel].sum(0), q[sel].sum()))
    return out


def region_frame(grid: RegionGrid, table, index: int, p, delta: float) -> tuple[tuple, float]:
    """(center, radius) a region network normalises positions by: the box of its training points
    (its cells + the δ-margin) -- the sphere about the box's centre through its corners."""
    table = _check_table(grid, table)
    cells = np.nonzero(table == index)[0].tolist()
    if not cells:
        raise RegionError(f"index: network {index} has no cell")
    pts = _points(p).astype(np.float64)
    sel = pts[margin_mask(grid, cells, pts, delta)]
    if sel.shape[0] == 0:
        raise RegionError(f"network {index}: no points in its cells {cells} or their margin")
    lo, hi = sel[:, :3].min(0), sel[:, :3].max(0)
    center = (lo + hi) * 0.5
    radius = max(float(np.linalg.norm(hi - lo)) * 0.5, 1e-3)
    return tuple(float(c) for c in center), radius


# blend weights (lib/prt_regions.glsl prt_region_weights, same float32 operations) -------------------
def _band(band) -> tuple[float, float]:
    b = np.broadcast_to(np.asarray(band, np.float64), (2,))
    if not np.isfinite(b).all() or (b < 0).any() or (b > 0.5).any() or ((b > 0) & (b < 1e-6)).any():
        raise RegionError(f"band: must be 0 or in [1e-6, 0.5] cell units per axis, got {band!r}")
    return f32(b[0]), f32(b[1])


def inv_band(band) -> tuple[float, float]:
    """float32 1 / band per axis (0 for a hard switch: the shader's weight is then a step)."""
    return tuple(f32(1.0 / b) if b > 0 else 0.0 for b in _band(band))


def _axis_weight(f: np.ndarray, ib: float, hard: bool) -> np.ndarray:
    """Own-network weight along one axis from the in-cell coordinate f (float32)."""
    half = F32(0.5)
    d = np.where(f < half, f, F32(1.0) - f).astype(F32)
    if hard:
        return np.ones_like(f)
    return (half + half * np.clip(d * F32(ib), F32(0.0), F32(1.0))).astype(F32)


def blend_weights(grid: RegionGrid, table, band, p) -> tuple[np.ndarray, np.ndarray]:
    """(nets [N, 4] int64, weights [N, 4] float32) per point (see the module docstring); slots whose
    weight is 0 name network -1."""
    table = _check_table(grid, table)
    ibx, ibz = inv_band(band)
    c = grid.coords(p)
    ci = grid.cell_index(p)
    f = (c - ci.astype(F32)).astype(F32)
    side = np.where(f < F32(0.5), -1, 1)
    nb = ci + side
    has = np.stack([(nb[:, 0] >= 0) & (nb[:, 0] < grid.nx), (nb[:, 1] >= 0) & (nb[:, 1] < grid.nz)], -1)
    nbc = np.stack([np.clip(nb[:, 0], 0, grid.nx - 1), np.clip(nb[:, 1], 0, grid.nz - 1)], -1)
    ax = np.where(has[:, 0], _axis_weight(f[:, 0], ibx, ibx == 0.0), F32(1.0)).astype(F32)
    az = np.where(has[:, 1], _axis_weight(f[:, 1], ibz, ibz == 0.0), F32(1.0)).astype(F32)
    one = F32(1.0)
    cells = np.stack([ci[:, 1] * grid.nx + ci[:, 0], ci[:, 1] * grid.nx + nbc[:, 0],
                      nbc[:, 1] * grid.nx + ci[:, 0], nbc[:, 1] * grid.nx + nbc[:, 0]], -1)
    w = np.stack([ax * az, (one - ax) * az, ax * (one - az), (one - ax) * (one - az)], -1).astype(F32)
    nets = table[cells]
    for i in range(1, 4):                 # fold duplicates into the first slot naming the network
        for j in range(i):
            same = (nets[:, j] == nets[:, i]) & (w[:, i] > 0) & (w[:, j] > 0)
            w[same, j] = (w[same, j] + w[same, i]).astype(F32)
            w[same, i] = F32(0.0)
    nets = np.where(w > 0, nets, -1)
    return nets, w


# bundles and the generated chunk ---------------------------------------------------------------------
def region_record(grid: RegionGrid, table, band, delta: float, index: int) -> dict:
    """``meta.render.region`` of region network ``index``."""
    table = _check_table(grid, table)
    bx, bz = _band(band)
    if not 0 <= int(index) <= int(table.max()):
        raise RegionError(f"index: must be in 0..{int(table.max())}, got {index!r}")
    return {"format": REGION_FORMAT, "grid": grid.to_dict(), "table": [int(v) for v in table],
            "band": [bx, bz], "delta": f32(_finite(delta, "delta")), "index": int(index)}


@dataclass(frozen=True)
class RegionSet:
    grid: RegionGrid
    table: tuple
    band: tuple
    order: tuple          # order[i] = position (in the bundles given) of network i

    @property
    def count(self) -> int:
        return len(self.order)


def is_region_bundle(bundle) -> bool:
    return isinstance((bundle.meta.get("render") or {}).get("region"), dict)


def read_region_set(bundles) -> RegionSet:
    """The region set of a scene's transfer bundles; RegionError naming the bundle and the field
    when they disagree (grid, table, band), an index is missing or repeated."""
    first, order = None, {}
    for pos, b in enumerate(bundles):
        where = f"{b.path if b.path is not None else b.name}: render.region"
        rec = (b.meta.get("render") or {}).get("region")
        if not isinstance(rec, dict):
            raise RegionError(f"{where}: missing (every network of a region set names its region)")
        if rec.get("format") != REGION_FORMAT:
            raise RegionError(f"{where}.format: expected {REGION_FORMAT}, got {rec.get('format')!r}")
        grid = RegionGrid.from_dict(rec.get("grid"), f"{where}.grid")
        table = tuple(rec.get("table") or ())
        try:
            _check_table(grid, np.asarray(table, np.int64) if table else np.zeros(0, np.int64))
            band = _band(rec.get("band"))
        except (RegionError, TypeError, ValueError) as exc:
            raise RegionError(f"{where}: {exc}") from None
        key = (grid, table, band)
        if first is None:
            first = key
        elif key != first:
            field = "grid" if grid != first[0] else "table" if table != first[1] else "band"
            raise RegionError(f"{where}.{field}: differs from the first network's (one region set per scene)")
        index = rec.get("index")
        if isinstance(index, bool) or not isinstance(index, int) or index in order:
            raise RegionError(f"{where}.index: must be a unique int, got {index!r}")
        order[index] = pos
    if first is None:
        raise RegionError("networks: a region set needs at least one transfer network")
    count = max(first[1]) + 1
    if sorted(order) != list(range(count)):
        raise RegionError(f"networks: the table names networks 0..{count - 1}; the scene gives {sorted(order)}")
    return RegionSet(first[0], first[1], first[2], tuple(order[i] for i in range(count)))


def region_chunks(bundles, prefixes, frames) -> dict[str, str]:
    """``{"prt_network": ...}`` for a region set. ``frames[i]``: codegen.transfer_frame of
    bundles[i] (center, inv_radius, scale); ``prefixes[i]`` its GLSL prefix."""
    from .codegen import PRT_CHUNK, network_chunk_name

    rs = read_region_set(bundles)
    for pos, b in enumerate(bundles):
        names = [(p.name, p.dim) for p in b.inputs]
        if names != [("position", 3), ("normal", 3)] or b.out_dim != 16:
            raise RegionError(f"{b.path or b.name}: inputs: region networks take position[3], normal[3] -> 16")
    grid = rs.grid
    ibx, ibz = inv_band(rs.band)
    vec = lambda v: "vec3(" + ", ".join(flt(c) for c in v) + ")"  # noqa: E731
    up0 = prefixes[rs.order[0]].upper()
    # each network once, in order: its index, eval function and frame (lib/prt_regions PRT_REGION_TERM)
    terms = [f"PRT_REGION_TERM({i}, {prefixes[pos]}_eval, {vec(frames[pos]['center'])}, "
             f"{flt(frames[pos]['inv_radius'])}, {flt(frames[pos]['scale'])})" for i, pos in enumerate(rs.order)]
    lines = ["// Generated by inshade.techniques.prt.regions from the region networks' render.region. Do not edit.",
             f"// {rs.count} networks over a {grid.nx}x{grid.nz} grid; "
             + ", ".join(f"{i}: {bundles[pos].name}" for i, pos in enumerate(rs.order))]
    lines += [f"#include <{network_chunk_name(prefixes[pos])}>" for pos in rs.order]
    lines += [
        "#define PRT_NET_EVAL prt_regions_eval",
        f"#define PRT_NET_IN_BLOCKS {up0}_IN_BLOCKS",
        f"#define PRT_NET_OUT_BLOCKS {up0}_OUT_BLOCKS",
        "#define PRT_CENTER vec3(0.0)      // identity: prt_regions_eval gets world positions",
        "#define PRT_INV_RADIUS 1.0",
        "#define PRT_SCALE 1.0",
        f"#define PRT_REGION_COUNT {rs.count}",
        f"#define PRT_REGION_NX {grid.nx}",
        f"#define PRT_REGION_NZ {grid.nz}",
        f"#define PRT_REGION_MIN vec2({flt(grid.x0)}, {flt(grid.z0)})",
        f"#define PRT_REGION_INV_CELL vec2({flt(grid.inv_cell[0])}, {flt(grid.inv_cell[1])})",
        f"#define PRT_REGION_INV_BAND vec2({flt(ibx)}, {flt(ibz)})   // 0: hard switch on that axis",
        f"const int PRT_REGION_TABLE[{grid.cells}] = int[]({', '.join(str(v) for v in rs.table)});",
        "#define PRT_REGION_TERMS " + " ".join(terms),
        "",
        "#include <lib/prt_regions>",
        "",
    ]
    return {PRT_CHUNK: "\n".join(lines)}
