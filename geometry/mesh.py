"""Triangle meshes: loading with one clear error, bounds, and the procedural asset.

- ``load_mesh(path, require_watertight=False)``: OBJ / PLY / anything trimesh reads, glTF / GLB
  through the project's glTF reader (geometry/gltf.py), scenes flattened into one mesh, vertices
  merged, zero-area faces dropped. Every problem is one ``MeshError`` (a ValueError) that names the file: missing or unreadable file,
  not a mesh, no faces, non-finite vertices, all faces degenerate, and, when
  ``require_watertight``, how many open (boundary) and non-manifold edges it has.
- ``bounding_sphere(mesh)``: (centre of the bounding box, max vertex distance from it), the bound
  that sphere tracing and network normalisation use (deterministic, unlike a minimal ball).
- Texture coordinates: a file's uv (OBJ ``vt``, PLY/GLB texture coordinates) survive loading
  (vertices on a uv seam stay split); ``mesh_uv(mesh)`` returns them or None.
  ``shading_normals(mesh)`` averages normals across such seams (welded by position), and
  ``vertex_tangents(mesh, normals)`` gives per-vertex (tangent, handedness) for normal maps;
  ``check_tangents(mesh)`` refuses uv that define no tangent anywhere.
- ``torus()`` / ``write_torus(out)``: a procedural uv-mapped torus (OBJ), the PBR-texture asset's
  mesh; its uv tile the texture ``tiles`` times around each circle.
- ``bunny(resolution)``: the shipped procedural mesh (no downloads exist here): marching cubes of
  a smooth-union rabbit with eye sockets and a fine fur ripple, Taubin-smoothed, watertight.
  ``python -m inshade.geometry.mesh [OUT.ply]`` writes it (binary PLY, byte-identical every run).

numpy + trimesh (+ scikit-image for the generator only); no torch.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import trimesh

DEFAULT_OUT = Path("/tmp/inshade_mesh/bunny.ply")
GLTF_SUFFIXES = (".gltf", ".glb")   # read by geometry/gltf.py (node transforms, instances, every primitive)


class MeshError(ValueError):
    """A mesh file that cannot be used; the message starts with the file."""


def load_mesh(path, require_watertight: bool = False) -> trimesh.Trimesh:
    """Read a triangle mesh (MeshError naming the file on any problem)."""
    path = Path(path)
    if not path.is_file():
        raise MeshError(f"{path}: no such file" if not path.exists() else f"{path}: not a file")
    if path.suffix.lower() in GLTF_SUFFIXES:
        from .gltf import GltfError, load_gltf

        try:
            mesh = load_gltf(path).mesh
        except GltfError as exc:
            raise MeshError(str(exc)) from None
        try:
            return check_mesh(mesh, require_watertight)
        except MeshError as exc:
            raise MeshError(f"{path}: {exc}") from None
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


def mesh_uv(mesh: trimesh.Trimesh) -> np.ndarray | None:
    """Per-vertex texture coordinates [V, 2] float64, or None when the mesh has none."""
    uv = getattr(mesh.visual, "uv", None)
    if uv is None:
        return None
    uv = np.asarray(uv, np.float64)
    return uv if uv.shape == (len(mesh.vertices), 2) else None


def check_mesh(mesh: trimesh.Trimesh, require_watertight: bool = False) -> trimesh.Trimesh:
    """Validate and clean an in-memory mesh (MeshError without a file name)."""
    v = np.asarray(mesh.vertices)
    f = np.asarray(mesh.faces)
    uv = mesh_uv(mesh)
    if len(f) == 0 or len(v) == 0:
        raise MeshError(f"empty mesh: {len(v)} vertices, {len(f)} faces")
    bad = ~np.isfinite(v).all(1)
    if bad.any():
        raise MeshError(f"vertices: {int(bad.sum())} of {len(v)} are NaN or infinite "
                        f"(first: index {int(np.argmax(bad))})")
    if f.min() < 0 or f.max() >= len(v):
        raise MeshError(f"faces: vertex index out of range 0..{len(v) - 1}")
    visual = None
    if uv is not None:
        if not np.isfinite(uv).all():
            raise MeshError(f"texture coordinates: {int((~np.isfinite(uv).all(1)).sum())} are NaN or infinite")
        visual = trimesh.visual.TextureVisuals(uv=uv)
    # merges vertices (not across uv seams: vertices with different uv stay apart)
    mesh = trimesh.Trimesh(v.astype(np.float64), f.astype(np.int64), visual=visual, process=True)
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


def shading_normals(mesh: trimesh.Trimesh) -> np.ndarray:
    """Unit vertex normals [V, 3] float64, averaged over every face at a position: a uv seam
    splits vertices, and trimesh's own vertex normals would then differ on its two sides (a
    visible crease). Identical to ``mesh.vertex_normals`` for a mesh without seams."""
    welded = trimesh.Trimesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), process=False)
    _, first, inverse = np.unique(welded.vertices, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    merged = trimesh.Trimesh(welded.vertices[first], inverse[welded.faces], process=False)
    return np.asarray(merged.vertex_normals, np.float64)[inverse]


UV_AREA_EPS = 1e-20   # |uv edge determinant| below which a face says nothing about tangents


def check_tangents(mesh: trimesh.Trimesh) -> None:
    """MeshError unless ``vertex_tangents`` is defined by the uv somewhere: the mesh has uv and at
    least one face whose uv span an area (where none does, every tangent would be an arbitrary
    fallback, e.g. all uv identical)."""
    uv = mesh_uv(mesh)
    if uv is None:
        raise MeshError("no texture coordinates: tangents need a uv-mapped mesh")
    f = np.asarray(mesh.faces)
    d1, d2 = uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]
    if not (np.abs(d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]) > UV_AREA_EPS).any():
        raise MeshError(f"texture coordinates are degenerate: all {len(f)} faces have zero uv area "
                        "(e.g. every vertex has the same uv), so tangents are undefined")


def vertex_tangents(mesh: trimesh.Trimesh, normals: np.ndarray | None = None) -> np.ndarray:
    """Per-vertex [V, 4] (unit tangent along +u, handedness w = +-1) for tangent-space normal maps:
    ``tangent_frames`` of the mesh's arrays, with ``shading_normals`` unless ``normals`` are given.
    Raises MeshError without uv (``check_tangents`` also refuses uv that span no area anywhere)."""
    uv = mesh_uv(mesh)
    if uv is None:
        raise MeshError("no texture coordinates: normal-mapped shading needs a uv-mapped mesh "
                        "(OBJ vt, or PLY/GLB texture coordinates)")
    n = shading_normals(mesh) if normals is None else np.asarray(normals, np.float64)
    return tangent_frames(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces), uv, n)


def tangent_frames(v: np.ndarray, f: np.ndarray, uv: np.ndarray, n: np.ndarray) -> np.ndarray:
    """[V, 4] tangents of vertices ``v`` [V, 3], faces ``f``, uv [V, 2] (v up) and unit normals
    ``n``: per face the edge vectors solved against the uv edges, accumulated with the face's
    area, made orthogonal to the normal (Gram-Schmidt); the bitangent is w * cross(n, t)."""
    e1, e2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]
    d1, d2 = uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(det) > UV_AREA_EPS
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
    # the face's area weights it (the solved vectors are per unit uv, so rescale by |det| ...)
    weight = np.abs(det)[:, None]
    t_face = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * inv * weight
    b_face = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * inv * weight
    t = np.zeros_like(v)
    b = np.zeros_like(v)
    for corner in range(3):
        np.add.at(t, f[:, corner], t_face)
        np.add.at(b, f[:, corner], b_face)
    t -= n * np.sum(n * t, 1, keepdims=True)
    length = np.linalg.norm(t, axis=1, keepdims=True)
    # vertices whose faces have no usable uv: any unit vector orthogonal to n
    fallback = np.cross(n, np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]))
    t = np.where(length > 1e-12, t / np.maximum(length, 1e-300), fallback / np.linalg.norm(fallback, axis=1, keepdims=True))
    w = np.where(np.sum(np.cross(n, t) * b, 1) < 0.0, -1.0, 1.0)
    return np.concatenate([t, w[:, None]], 1)


# the procedural assets ---------------------------------------------------------------------------
def torus(major: float = 1.0, minor: float = 0.42, segments: tuple[int, int] = (96, 48),
          tiles: tuple[float, float] = (4.0, 2.0)) -> trimesh.Trimesh:
    """A torus about +y, uv-mapped: u runs around the main ring (``tiles[0]`` texture repeats),
    v around the tube (``tiles[1]``). The seam columns are duplicated so uv is continuous on each
    face; shading normals weld them again."""
    nu, nv = segments
    a = np.linspace(0.0, 2.0 * np.pi, nu + 1)
    b = np.linspace(0.0, 2.0 * np.pi, nv + 1)
    aa, bb = np.meshgrid(a, b, indexing="ij")                       # [nu + 1, nv + 1]
    ring = major + minor * np.cos(bb)
    pos = np.stack([ring * np.cos(aa), minor * np.sin(bb), -ring * np.sin(aa)], -1).reshape(-1, 3)
    uv = np.stack([aa / (2.0 * np.pi) * tiles[0], bb / (2.0 * np.pi) * tiles[1]], -1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    v00 = (i * (nv + 1) + j).reshape(-1)
    v10, v01, v11 = v00 + nv + 1, v00 + 1, v00 + nv + 2
    # counter-clockwise seen from outside (outward normals)
    faces = np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])
    return trimesh.Trimesh(pos, faces, visual=trimesh.visual.TextureVisuals(uv=uv), process=False)


def obj_text(mesh: trimesh.Trimesh) -> str:
    """A minimal OBJ (v, vt, f v/vt), fixed 9-digit formatting: byte-identical every run."""
    uv = mesh_uv(mesh)
    lines = ["# inshade procedural mesh"]
    lines += [f"v {x:.9f} {y:.9f} {z:.9f}" for x, y, z in np.asarray(mesh.vertices)]
    if uv is not None:
        lines += [f"vt {s:.9f} {t:.9f}" for s, t in uv]
        lines += [f"f {a + 1}/{a + 1} {b + 1}/{b + 1} {c + 1}/{c + 1}" for a, b, c in np.asarray(mesh.faces)]
    else:
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(mesh.faces)]
    return "\n".join(lines) + "\n"


def write_torus(out, **kw) -> Path:
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    from inshade.files import atomic_write

    return atomic_write(out, obj_text(torus(**kw)))


# the procedural bunny ----------------------------------------------------------------------------
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
