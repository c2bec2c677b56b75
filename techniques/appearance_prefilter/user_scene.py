"""A user's scene file as an appearance-prefiltering scene: ``--scene FILE`` (a glTF 2.0 file, or an
OBJ / PLY / STL mesh) in place of a procedural one (scene.py), the rest of the pipeline unchanged.

- glTF (geometry/gltf.py): every triangle the default scene draws, in world space; per face the
  material's base colour (texture x factor, linear), roughness and metallic (geometry/gltf_sample.py
  ``material_channels``) averaged over ``FACE_SAMPLES`` equal-area points of the face (the centroids
  of its 3 x 3 subdivision) at their interpolated uv: the per-face material the bake and the
  ray-traced reference use. One part per material, two-sided where the material is ``doubleSided``.
  Not carried into the prefiltered scene: normal maps, occlusion and emissive textures, the KHR
  lobes (clearcoat, sheen, anisotropy) -- the scene's notes say so.
- any other mesh (geometry/mesh.py ``load_mesh``): one part with the constant material ``PLAIN``.

A one-sided part that is not closed (scene.py asks solids to be watertight, as the bake shades
closed solids from outside) is treated as two-sided, and a note says which.

The mesh is normalised into the unit box as scene.py does (largest extent ``1 - 2 MARGIN``,
centred at 0.5); ``UserScene.world`` keeps the map (box = (world - centre) * scale + 0.5) so a pass
drawing the file in its own coordinates can march the voxels (passes/appearance_prefilter_gltf.frag).

numpy + trimesh; no torch.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from .scene import MARGIN, SCENES, PrefilterScene, SceneError, scene_from_mesh

GLTF_SUFFIXES = (".glb", ".gltf")
PLAIN = {"base_colour": (0.7, 0.7, 0.7), "roughness": 0.5, "metallic": 0.0}   # a file without materials
SUBDIVISION = 3            # FACE_SAMPLES = SUBDIVISION^2 points per face


def is_file_scene(scene: str) -> bool:
    """Whether a ``--scene`` value names a file (anything but a procedural scene's name)."""
    return scene not in SCENES


def scene_name(scene: str) -> str:
    """The scene's name in folders and titles: the procedural name, or the file's stem."""
    return Path(scene).stem if is_file_scene(scene) else scene


@dataclass
class UserScene:
    scene: PrefilterScene
    kind: str                      # "gltf" | "mesh"
    world: dict                    # {"centre": [3], "scale": s}: box = (world - centre) * scale + 0.5
    bounds: tuple                  # (lo [3], hi [3]) of the file's mesh, world units
    notes: list = field(default_factory=list)


def face_samples(subdivision: int = SUBDIVISION) -> np.ndarray:
    """Barycentric weights [k^2, 3] of the centroids of a triangle's k x k subdivision (equal areas)."""
    k = subdivision
    points = [((i + 1 / 3) / k, (j + 1 / 3) / k) for i in range(k) for j in range(k - i)]
    points += [((i + 2 / 3) / k, (j + 2 / 3) / k) for i in range(k - 1) for j in range(k - 1 - i)]
    a = np.asarray(points)
    return np.column_stack([a, 1.0 - a.sum(1)])


def _gltf_materials(asset, mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-face (base colour [F, 3], roughness [F], metallic [F]) averaged over the face samples."""
    from inshade.geometry.gltf_sample import material_channels
    from inshade.geometry.mesh import mesh_uv

    faces = np.asarray(mesh.faces)
    uv = mesh_uv(mesh)
    uv = np.zeros((len(mesh.vertices), 2)) if uv is None else uv
    uv1 = mesh.vertex_attributes.get("uv1")
    weights = face_samples()
    base = np.zeros((len(faces), 3))
    rough, metal = np.zeros(len(faces)), np.zeros(len(faces))
    for m in np.unique(asset.face_material):
        sel = np.flatnonzero(asset.face_material == m)
        points = np.einsum("sc,fcx->fsx", weights, uv[faces[sel]]).reshape(-1, 2)
        points1 = (None if uv1 is None else
                   np.einsum("sc,fcx->fsx", weights, uv1[faces[sel]]).reshape(-1, 2))   # a texture's TEXCOORD_1
        ch = material_channels(asset, int(m), points, points1)
        base[sel] = ch["base_color"].reshape(len(sel), -1, 3).mean(1)
        rough[sel] = ch["roughness"].reshape(len(sel), -1).mean(1)
        metal[sel] = ch["metallic"].reshape(len(sel), -1).mean(1)
    return base, rough, metal


def _closed(vertices, faces) -> bool:
    piece = trimesh.Trimesh(vertices, faces, process=False)
    piece.merge_vertices()
    return bool(piece.is_watertight)


def load_user_scene(path, extent: float = 1.0 - 2.0 * MARGIN) -> UserScene:
    """The file as a normalised PrefilterScene (GltfError / MeshError / SceneError naming the file
    and field)."""
    path = Path(path)
    notes = []
    if path.suffix.lower() in GLTF_SUFFIXES:
        from inshade.geometry.gltf import load_gltf

        asset = load_gltf(path)
        mesh, kind = asset.mesh, "gltf"
        base, rough, metal = _gltf_materials(asset, mesh)
        groups = [(asset.materials[m].name or f"material {m}", np.flatnonzero(asset.face_material == m),
                   asset.materials[m].double_sided) for m in np.unique(asset.face_material)]
        notes.append("per-face material: base colour, roughness and metallic averaged over each face; normal, "
                     "occlusion and emissive textures and the KHR lobes are not prefiltered")
        notes += asset.notes
    else:
        from inshade.geometry.mesh import load_mesh

        mesh, kind = load_mesh(path), "mesh"
        n = len(mesh.faces)
        base = np.tile(PLAIN["base_colour"], (n, 1))
        rough, metal = np.full(n, PLAIN["roughness"]), np.full(n, PLAIN["metallic"])
        groups = [(path.stem, np.arange(n), False)]
        notes.append(f"no materials: base colour {list(PLAIN['base_colour'])}, roughness {PLAIN['roughness']}, "
                     f"metallic {PLAIN['metallic']}")
    vertices = np.asarray(mesh.vertices, np.float64)
    faces = np.asarray(mesh.faces, np.int64)
    order, parts, sided, start = [], [], [], 0
    for name, sel, two_sided in groups:
        if not two_sided and not _closed(vertices, faces[sel]):
            notes.append(f"{name}: one-sided but not closed; prefiltered as two-sided")
            two_sided = True
        order.append(sel)
        parts.append((name, start, start + len(sel)))
        sided.append(np.full(len(sel), two_sided))
        start += len(sel)
    order = np.concatenate(order)
    lo, hi = vertices.min(0), vertices.max(0)
    centre, size = 0.5 * (lo + hi), float((hi - lo).max())
    if size <= 0.0:
        raise SceneError(f"{path}: mesh: all vertices coincide (zero extent)")
    scale = float(extent) / size
    box = trimesh.Trimesh((vertices - centre) * scale + 0.5, faces[order], process=False)
    scene = scene_from_mesh(box, base[order], rough[order], metal[order], np.concatenate(sided),
                            name=scene_name(str(path)), parts=parts, normalise=False)
    return UserScene(scene, kind, {"centre": centre.tolist(), "scale": scale}, (lo, hi), notes)
