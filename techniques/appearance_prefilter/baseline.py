"""The bench's equal-memory LoD baseline: the scene's mesh decimated by quadric error
(fast-simplification, Fast-Quadric-Mesh-Simplification) to a byte budget, with each kept face's
material the area-weighted average of the original faces nearest to it. This is the classic mesh
LoD the paper's competitors start from; it is rendered by the same ray tracer as the ground truth.

Bytes are counted as a renderer would store the LoD: float32 positions (12 B per vertex), uint32
indices (12 B per face) and an 8-bit material per face (RGB base colour, roughness, metallic: 5 B).
"""
from __future__ import annotations

import dataclasses

import numpy as np

VERTEX_BYTES = 12
FACE_BYTES = 12 + 5


def lod_bytes(vertices: int, faces: int) -> int:
    return VERTEX_BYTES * int(vertices) + FACE_BYTES * int(faces)


MAX_STEP = 0.99   # the largest reduction asked of one decimator pass
MAX_PASSES = 4


def _simplify(vertices: np.ndarray, faces: np.ndarray, reduction: float):
    """The mesh decimated toward (1 - reduction) of its faces, in passes of at most MAX_STEP each, so
    a mesh of millions of faces still reaches the few hundred a coarse budget allows."""
    import fast_simplification

    if reduction <= 0.0:
        return vertices, faces
    target = max(1.0, (1.0 - min(reduction, 0.999999)) * len(faces))
    v, f = vertices.astype(np.float32), faces.astype(np.int64)
    for _ in range(MAX_PASSES):
        step = 1.0 - target / max(len(f), 1)
        if step <= 1e-3 or len(f) == 0:
            break
        v, f = fast_simplification.simplify(v, f, target_reduction=float(min(step, MAX_STEP)))
        v, f = np.asarray(v, np.float32), np.asarray(f, np.int64)
    return np.asarray(v, np.float64), np.asarray(f, np.int64)


def decimate(scene, budget_bytes: int):
    """The scene with its mesh decimated until it fits ``budget_bytes`` (a bisection over the
    reduction, since the decimator cannot hit a face count exactly) and its per-face material
    averaged onto the kept faces. Returns (scene, bytes); a budget below a 1-face mesh gives an
    empty mesh (the LoD has vanished, as the paper's simplified meshes do at coarse scales)."""
    import trimesh
    from scipy.spatial import cKDTree

    mesh = scene.mesh
    full = lod_bytes(len(mesh.vertices), len(mesh.faces))
    if full <= budget_bytes:
        return scene, full
    lo, hi, best = 0.0, 1.0, None
    for _ in range(14):
        mid = 0.5 * (lo + hi)
        v, f = _simplify(np.asarray(mesh.vertices), np.asarray(mesh.faces), mid)
        if lod_bytes(len(v), len(f)) <= budget_bytes:
            best, hi = (v, f), mid
        else:
            lo = mid
    if best is None or len(best[1]) == 0:
        empty = trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), process=False)
        return _with_material(scene, empty, np.zeros(0, np.int64), np.zeros(0)), 0
    lod = trimesh.Trimesh(best[0], best[1], process=False)
    # each original face goes to the nearest kept face (centroids); kept faces average their share
    owner = cKDTree(lod.triangles_center).query(mesh.triangles_center)[1]
    return _with_material(scene, lod, owner, mesh.area_faces), lod_bytes(len(lod.vertices), len(lod.faces))


def _with_material(scene, lod, owner: np.ndarray, area: np.ndarray):
    from scipy.spatial import cKDTree

    n = len(lod.faces)
    weight = np.bincount(owner, weights=area, minlength=n)

    def average(values):
        values = np.asarray(values, np.float64)
        if n == 0:   # the LoD has vanished: no face keeps a material
            return np.zeros((0,) + values.shape[1:])
        flat = values.reshape(len(values), -1)
        sums = np.stack([np.bincount(owner, weights=area * flat[:, c], minlength=n)
                         for c in range(flat.shape[1])], 1)
        out = sums / np.maximum(weight, 1e-30)[:, None]
        orphans = weight <= 0.0   # a kept face no original face chose: take its nearest original face
        if orphans.any():
            near = cKDTree(scene.mesh.triangles_center).query(lod.triangles_center[orphans])[1]
            out[orphans] = flat[near]
        return out.reshape((n,) + values.shape[1:])

    return dataclasses.replace(
        scene, mesh=lod, parts=[],   # the parts' face ranges do not survive decimation
        base_colour=average(scene.base_colour).astype(np.float32),
        roughness=average(scene.roughness).astype(np.float32),
        metallic=average(scene.metallic).astype(np.float32),
        two_sided=average(np.asarray(scene.two_sided, np.float64)) >= 0.5)
