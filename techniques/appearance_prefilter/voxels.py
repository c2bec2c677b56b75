"""Sparse multi-scale voxelisation (the contract's voxel table).

Scale s is a grid of 2^s cells per axis over [0, 1]^3; cell (i, j, k) covers [i, i+1]/2^s in x,
[j, j+1]/2^s in y, [k, k+1]/2^s in z. A cell is a voxel when a triangle overlaps it: the exact
separating-axis test (Akenine-Moeller: 3 box axes, the triangle normal, 9 edge x axis
crossings), closed sets (touching counts), run vectorised over candidate cells from each
triangle's AABB. Its sphere bounds the triangles CLIPPED to the cell (Sutherland-Hodgman
against the 6 faces): the clipped points' AABB centre and the largest distance to it (r >= 1e-6).

``voxelise`` returns ``cells`` uint32 [N, 4] = (scale, i, j, k) sorted by (scale, k, j, i) and
``spheres`` float32 [N, 4] = (cx, cy, cz, r). The voxel count of every scale is computed first
(SAT only) and a range whose count * bytes_per_voxel exceeds the memory budget is refused
before the clipping work.

numpy only.
"""
from __future__ import annotations

import numpy as np

MAX_SCALE = 9
# latents (Z = 64, fp16) + cell + sphere + one index texel: the decoder asset's per-voxel bytes
BYTES_PER_VOXEL = 64 * 2 + 16 + 16 + 4
CANDIDATES_PER_CHUNK = 1 << 21    # bounds the SAT's temporary arrays (~0.5 GB peak)
MIN_RADIUS = 1e-6


class VoxelError(ValueError):
    """Bad scale range or a memory budget the range does not fit; the message names the field."""


def _triangles(scene_or_mesh) -> np.ndarray:
    mesh = getattr(scene_or_mesh, "mesh", scene_or_mesh)
    tri = np.asarray(mesh.vertices, np.float64)[np.asarray(mesh.faces)]
    if tri.size == 0:
        raise VoxelError("scene.mesh: empty geometry (no faces)")
    return tri


def check_scales(s_min, s_max) -> tuple[int, int]:
    for name, v in (("s_min", s_min), ("s_max", s_max)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise VoxelError(f"{name}: must be an int, got {v!r}")
    if not 0 <= s_min <= s_max <= MAX_SCALE:
        raise VoxelError(f"scales: need 0 <= s_min <= s_max <= {MAX_SCALE}, got s_min={s_min}, s_max={s_max}")
    return int(s_min), int(s_max)


# --- candidates and the separating-axis test ----------------------------------------------------

def _candidate_chunks(tri: np.ndarray, scale: int):
    """(triangle index, cell ijk) pairs of every cell touching a triangle's AABB, in chunks."""
    n = 1 << scale
    lo = np.clip(np.floor(tri.min(1) * n), 0, n - 1).astype(np.int64)
    hi = np.clip(np.floor(tri.max(1) * n), 0, n - 1).astype(np.int64)
    ext = hi - lo + 1
    count = ext.prod(1)
    ends = np.cumsum(count)
    start = 0
    while start < len(tri):
        # as many triangles as fit the chunk (at least one)
        base = ends[start - 1] if start else 0
        stop = max(start + 1, int(np.searchsorted(ends, base + CANDIDATES_PER_CHUNK, side="right")))
        idx = np.repeat(np.arange(start, stop), count[start:stop])
        local = np.arange(len(idx)) - np.repeat(np.cumsum(count[start:stop]) - count[start:stop], count[start:stop])
        e = ext[idx]
        ijk = lo[idx] + np.stack([local % e[:, 0], (local // e[:, 0]) % e[:, 1], local // (e[:, 0] * e[:, 1])], 1)
        yield idx, ijk
        start = stop


def overlaps(tri: np.ndarray, centre: np.ndarray, half: float) -> np.ndarray:
    """Closed triangle/box overlap [P] bool for triangles [P, 3, 3] and boxes (centre [P, 3], half)."""
    v = tri - centre[:, None, :]
    sep = np.zeros(len(v), bool)
    # box face normals: the triangle's AABB against the box
    sep |= (v.min(1) > half).any(1) | (v.max(1) < -half).any(1)
    e = v[:, [1, 2, 0]] - v                                   # edges e0 = v1 - v0, ...
    for i in range(3):
        for axis in range(3):
            a = np.cross(e[:, i], np.eye(3)[axis])            # edge x box axis
            p = (v * a[:, None, :]).sum(-1)                   # [P, 3]
            r = half * np.abs(a).sum(-1)
            sep |= (p.min(1) > r) | (p.max(1) < -r)
    nrm = np.cross(e[:, 0], v[:, 2] - v[:, 0])
    d = (nrm * v[:, 0]).sum(-1)
    r = half * np.abs(nrm).sum(-1)
    sep |= np.abs(d) > r
    return ~sep


def _scale_pairs(tri: np.ndarray, scale: int):
    """(triangle index [P], cell ijk [P, 3]) of every overlapping pair at this scale."""
    n = 1 << scale
    half = 0.5 / n
    tris, cells = [], []
    for idx, ijk in _candidate_chunks(tri, scale):
        keep = overlaps(tri[idx], (ijk + 0.5) / n, half)
        tris.append(idx[keep])
        cells.append(ijk[keep])
    return np.concatenate(tris), np.concatenate(cells)


def _unique_cells(ijk: np.ndarray, scale: int):
    """Unique cells in (k, j, i) order and the inverse index of each pair."""
    n = 1 << scale
    key = (ijk[:, 2] * n + ijk[:, 1]) * n + ijk[:, 0]
    uniq, inverse = np.unique(key, return_inverse=True)
    cells = np.stack([uniq % n, (uniq // n) % n, uniq // (n * n)], 1)
    return cells, inverse


# --- clipping and spheres -----------------------------------------------------------------------

def clip_to_boxes(tri: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Sutherland-Hodgman: triangles [P, 3, 3] clipped to boxes [P, 3] lo/hi.
    Returns (points [P, 9, 3], valid [P, 9] bool): each row's polygon vertices (<= 9)."""
    k = 9
    poly = np.zeros((len(tri), k, 3))
    poly[:, :3] = tri
    count = np.full(len(tri), 3)
    for axis in range(3):
        for sign, bound in ((1.0, lo[:, axis]), (-1.0, hi[:, axis])):
            dist = sign * (poly[..., axis] - bound[:, None])          # >= 0 inside
            j = np.arange(k)
            valid = j[None, :] < count[:, None]
            nxt = np.where(j[None, :] + 1 < count[:, None], j[None, :] + 1, 0)
            pn = np.take_along_axis(poly, nxt[..., None], 1)
            dn = np.take_along_axis(dist, nxt, 1)
            inside, inside_n = dist >= 0.0, dn >= 0.0
            t = dist / np.where(dist - dn == 0.0, 1.0, dist - dn)
            cross_pt = poly + t[..., None] * (pn - poly)
            emit = np.stack([valid & inside, valid & (inside != inside_n)], 2).reshape(len(tri), 2 * k)
            pts = np.stack([poly, cross_pt], 2).reshape(len(tri), 2 * k, 3)
            order = np.argsort(~emit, axis=1, kind="stable")[:, :k]   # kept points first, in order
            poly = np.take_along_axis(pts, order[..., None], 1)
            count = np.minimum(emit.sum(1), k)
    return poly, np.arange(k)[None, :] < count[:, None]


def _spheres(tri, tri_idx, inverse, cells, scale) -> np.ndarray:
    n = 1 << scale
    lo = cells[inverse] / n
    pts, valid = clip_to_boxes(tri[tri_idx], lo, lo + 1.0 / n)
    owner = np.repeat(inverse, valid.sum(1))
    flat = pts[valid]
    v = len(cells)
    bmin = np.full((v, 3), np.inf)
    bmax = np.full((v, 3), -np.inf)
    np.minimum.at(bmin, owner, flat)
    np.maximum.at(bmax, owner, flat)
    # (guard) a cell whose pairs all clip to nothing falls back to its centre
    empty = ~np.isfinite(bmin).all(1)
    centre = np.where(empty[:, None], (cells + 0.5) / n, 0.5 * (bmin + bmax))
    r = np.zeros(v)
    np.maximum.at(r, owner, np.linalg.norm(flat - centre[owner], axis=1))
    return np.concatenate([centre, np.maximum(r, MIN_RADIUS)[:, None]], 1)


def count_voxels(scene, s_min: int, s_max: int) -> dict[int, int]:
    """Voxel count per scale (the SAT pass only)."""
    s_min, s_max = check_scales(s_min, s_max)
    tri = _triangles(scene)
    return {s: len(_unique_cells(_scale_pairs(tri, s)[1], s)[0]) for s in range(s_min, s_max + 1)}


def voxelise(scene, s_min: int, s_max: int, memory_budget_bytes: int | None = None,
             bytes_per_voxel: int = BYTES_PER_VOXEL):
    """(cells uint32 [N, 4], spheres float32 [N, 4]) of every non-empty cell at scales s_min..s_max."""
    s_min, s_max = check_scales(s_min, s_max)
    if isinstance(bytes_per_voxel, bool) or not isinstance(bytes_per_voxel, (int, np.integer)) or bytes_per_voxel <= 0:
        raise VoxelError(f"bytes_per_voxel: must be an int > 0, got {bytes_per_voxel!r}")
    tri = _triangles(scene)
    per_scale = {}
    for s in range(s_min, s_max + 1):
        tri_idx, ijk = _scale_pairs(tri, s)
        cells, inverse = _unique_cells(ijk, s)
        per_scale[s] = (tri_idx, cells, inverse)
    total = sum(len(c) for _, c, _ in per_scale.values())
    if memory_budget_bytes is not None and total * bytes_per_voxel > memory_budget_bytes:
        counts = ", ".join(f"scale {s}: {len(c)}" for s, (_, c, _) in per_scale.items())
        raise VoxelError(f"memory_budget_bytes: scales {s_min}..{s_max} need {total * bytes_per_voxel} bytes "
                         f"({total} voxels x {bytes_per_voxel} B; {counts}) > budget {memory_budget_bytes}")
    all_cells, all_spheres = [], []
    for s, (tri_idx, cells, inverse) in per_scale.items():
        all_spheres.append(_spheres(tri, tri_idx, inverse, cells, s))
        all_cells.append(np.concatenate([np.full((len(cells), 1), s), cells], 1))
    return (np.ascontiguousarray(np.concatenate(all_cells), np.uint32),
            np.ascontiguousarray(np.concatenate(all_spheres), np.float32))
