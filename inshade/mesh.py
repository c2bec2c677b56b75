"""Triangle meshes: loading with one clear error, bounds, and the procedural asset.

- ``load_mesh(path, require_watertight=False)``: OBJ / PLY / GLB / anything trimesh reads, scenes
  flattened into one mesh (``force="mesh"``), vertices merged, zero-area faces dropped. Every
  problem is one ``MeshError`` (a ValueError) that names the file: missing or unreadable file,
  not a mesh, no faces, non-finite vertices, all faces degenerate, and, when
  ``require_watertight``, how many open (boundary) and non-manifold edges it has.
- ``bounding_sphere(mesh)``: (centre of the bounding box, max vertex distance from it), the bound
  that sphere tracing and network normalisation use (deterministic, unlike a minimal ball).
- ``bunny(resolution)``: the shipped procedural mesh (no downloads exist here): marching cubes of
  a smooth-union rabbit with eye sockets and a fine fur ripple, Taubin-smoothed, watertight.
  ``python -m inshade.mesh [OUT.ply]`` writes it (binary PLY, byte-identical every run).

numpy + trimesh (+ scikit-image for the generator only); no torch.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import trimesh

DEFAULT_OUT = Path("/tmp/inshade_mesh/bunny.ply")


class MeshError(ValueError):
    """A mesh file that cannot be used; the message starts with the file."""


def load_mesh(path, require_watertight: bool = False) -> trimesh.Trimesh:
    """Read a triangle mesh (MeshError naming the file on any problem)."""
    path = Path(path)
    if not path.is_file():
        raise MeshError(f"{path}: no such file" if not path.exists() else f"{path}: not a file")
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh's loaders raise whatever their parsers raise
        raise MeshError(f"{path}: cannot read as a mesh: {type(exc).__name__}: {exc}") from None
    if not isinstance(mesh, trimesh.Trimesh):
        raise MeshError(f"{path}: not a triangle mesh (got {type(mesh).__name__})")
    try:
        return check_mesh(mesh, require_watertight)
    except MeshError as exc:
        raise MeshError(f"{path}: {exc}") from None


def check_mesh(mesh: trimesh.Trimesh, require_watertight: bool = False) -> trimesh.Trimesh:
    """Validate and clean an in-memory mesh (MeshError without a file name)."""
    v = np.asarray(mesh.vertices)
    f = np.asarray(mesh.faces)
    if len(f) == 0 or len(v) == 0:
        raise MeshError(f"empty mesh: {len(v)} vertices, {len(f)} faces")
    bad = ~np.isfinite(v).all(1)
    if bad.any():
        raise MeshError(f"vertices: {int(bad.sum())} of {len(v)} are NaN or infinite "
                        f"(first: index {int(np.argmax(bad))})")
    if f.min() < 0 or f.max() >= len(v):
        raise MeshError(f"faces: vertex index out of range 0..{len(v) - 1}")
    mesh = trimesh.Trimesh(v.astype(np.float64), f.astype(np.int64), process=True)  # merges vertices
    keep = mesh.area_faces > 1e-14 * max(1.0, float(np.ptp(mesh.vertices, 0).max()) ** 2)
    if not keep.any():
        raise MeshError(f"degenerate: all {len(keep)} faces have zero area")
    if not keep.all():
        mesh.update_faces(keep)
        mesh.remove_unreferenced_vertices()
    if require_watertight:
        open_edges, nonmanifold = edge_defects(mesh)
        if open_edges or nonmanifold:
            raise MeshError(f"not watertight: {open_edges} open (boundary) edges, {nonmanifold} non-manifold "
                            f"edges (a closed surface is needed for inside/outside)")
    return mesh


def edge_defects(mesh: trimesh.Trimesh) -> tuple[int, int]:
    """(edges used by one face, edges used by more than two faces)."""
    _, counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
    return int((counts == 1).sum()), int((counts > 2).sum())


def bounding_sphere(mesh: trimesh.Trimesh, margin: float = 0.0) -> tuple[np.ndarray, float]:
    """(centre [3] of the axis-aligned box, max vertex distance from it * (1 + margin))."""
    v = np.asarray(mesh.vertices, np.float64)
    center = 0.5 * (v.min(0) + v.max(0))
    return center, float(np.linalg.norm(v - center, axis=1).max()) * (1.0 + margin)


# the procedural asset ----------------------------------------------------------------------------
def _smin(a, b, k):
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return b + (a - b) * h - k * h * (1.0 - h)


def _smax(a, b, k):
    return -_smin(-a, -b, k)


def _ellipsoid(p, c, r, rot=None):
    q = p - np.asarray(c)
    if rot is not None:
        q = q @ rot
    q0 = np.linalg.norm(q / np.asarray(r), axis=-1)
    q1 = np.linalg.norm(q / np.square(r), axis=-1)
    return q0 * (q0 - 1.0) / np.maximum(q1, 1e-9)


def _rot_x(deg):
    a = np.radians(deg)
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def _rot_z(deg):
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def bunny_field(p: np.ndarray) -> np.ndarray:
    """The rabbit's implicit (negative inside; a bound, not an exact distance) at p [..., 3].
    Facing +z, y up, about 1.6 x 2.0 x 1.8 units."""
    d = _ellipsoid(p, (0.0, -0.12, -0.12), (0.50, 0.46, 0.62))                      # body
    d = _smin(d, _ellipsoid(p, (0.0, 0.32, 0.42), (0.30, 0.28, 0.30)), 0.16)      # head
    d = _smin(d, _ellipsoid(p, (0.0, 0.24, 0.68), (0.15, 0.12, 0.12)), 0.06)      # snout
    for s in (-1.0, 1.0):
        ear = _rot_z(-s * 14.0) @ _rot_x(-18.0)
        d = _smin(d, _ellipsoid(p, (s * 0.15, 0.86, 0.28), (0.09, 0.36, 0.045), ear), 0.07)   # ears
        d = _smin(d, _ellipsoid(p, (s * 0.30, -0.36, -0.25), (0.17, 0.24, 0.32)), 0.08)     # haunches
        d = _smin(d, _ellipsoid(p, (s * 0.24, -0.56, 0.28), (0.10, 0.07, 0.20)), 0.06)      # front paws
        d = _smin(d, _ellipsoid(p, (s * 0.33, -0.58, -0.05), (0.11, 0.07, 0.27)), 0.06)     # hind feet
        d = _smax(d, -_ellipsoid(p, (s * 0.17, 0.42, 0.63), (0.05, 0.05, 0.05)), 0.02)       # eye sockets
        d = _smin(d, _ellipsoid(p, (s * 0.17, 0.42, 0.615), (0.035, 0.035, 0.035)), 0.01)   # eyes
    d = _smin(d, _ellipsoid(p, (0.0, -0.05, -0.78), (0.15, 0.15, 0.13)), 0.05)    # tail
    # fur: a fine ripple (amplitude 0.008, period ~0.16) that the neural SDF and PRT must resolve
    fur = np.sin(37.0 * p[..., 0]) * np.sin(41.0 * p[..., 1] + 0.7) * np.sin(39.0 * p[..., 2] + 1.3)
    return d + 0.008 * fur


def bunny(voxel: float = 0.027, smooth_iterations: int = 4) -> trimesh.Trimesh:
    """The procedural rabbit: marching cubes of ``bunny_field`` on a ``voxel``-spaced grid, the
    largest component, Taubin smoothing (volume-preserving). Watertight; ~20k faces at the default."""
    from skimage.measure import marching_cubes

    lo, hi = np.array([-0.8, -0.8, -1.05]), np.array([0.8, 1.4, 1.0])
    n = np.ceil((hi - lo) / voxel).astype(int) + 1
    axes = [lo[i] + voxel * np.arange(n[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1)
    field = bunny_field(grid)
    field = np.pad(field, 1, constant_values=1.0)    # closed at the grid's faces
    verts, faces, _, _ = marching_cubes(field.astype(np.float32), 0.0, spacing=(voxel,) * 3)
    verts = verts - voxel + lo
    mesh = trimesh.Trimesh(verts, faces[:, ::-1], process=True)   # skimage winds inward for negative-inside
    parts = mesh.split(only_watertight=False)
    mesh = max(parts, key=lambda m: len(m.faces))
    if smooth_iterations:
        trimesh.smoothing.filter_taubin(mesh, lamb=0.5, nu=-0.53, iterations=smooth_iterations)
    mesh.fix_normals()
    return mesh


def write_bunny(out=DEFAULT_OUT, **kw) -> Path:
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    mesh = bunny(**kw)
    out.write_bytes(trimesh.exchange.ply.export_ply(mesh, encoding="binary", include_attributes=False))
    return out


if __name__ == "__main__":
    path = write_bunny(sys.argv[1] if len(sys.argv) > 1 else DEFAULT_OUT)
    m = load_mesh(path, require_watertight=True)
    print(f"{path}: {len(m.vertices)} vertices, {len(m.faces)} faces, watertight {m.is_watertight}")
