"""glTF 2.0 assets in: one reader for every technique that takes a mesh or a material.

``load_gltf(path) -> GltfAsset`` reads a ``.gltf`` (JSON + buffers/images as files or data URIs) or
a ``.glb`` and returns what the renderer and the trainers use:

- ``mesh``: one ``trimesh.Trimesh`` of every triangle the default scene draws, in world space
  (node transforms composed down the hierarchy, every instance of a mesh, ``EXT_mesh_gpu_instancing``
  included), vertices not merged. Texture coordinates set 0 are the uv (``mesh_uv``) in the
  project's convention, v up: ``v = 1 - v_gltf`` (``gltf_uv`` turns them back); normals (authored,
  else flat per face as the spec says) are ``mesh.vertex_attributes["normal"]``; tangents (authored,
  else MikkTSpace's, as the spec asks: ``mikktspace_tangents``) are ``vertex_attributes["tangent"]``
  [V, 4] (w = handedness, bitangent = w * cross(n, t)); ``vertex_attributes["material"]`` is each
  vertex's material index (a vertex belongs to one primitive).
  A transform with negative determinant flips the winding back, as the spec asks.
  Triangle strips and fans become triangles; points and lines are refused.
- ``face_material`` [F]: each face's index into ``materials``; primitives without a material use
  the spec's default material, appended last when used.
- ``materials``: ``Material`` records of the metallic-roughness model with its textures
  (``TextureRef``: image, texcoord set, ``KHR_texture_transform`` as a 3x3 uv matrix, wrap modes),
  normal scale, occlusion strength, emissive (with ``KHR_materials_emissive_strength``), alpha mode,
  ``KHR_materials_ior``, ``KHR_materials_clearcoat``, ``KHR_materials_sheen``,
  ``KHR_materials_anisotropy``; ``KHR_materials_pbrSpecularGlossiness`` is converted to
  metallic-roughness per texel (the Khronos converter's metallic solve; approximate, and said so).
- ``images``: decoded RGBA8 arrays [H, W, 4], row 0 = the top of the image (glTF's v = 0).
- ``notes``: what the reader did that a user should know (optional extensions ignored, conversions,
  generated tangents).

Every problem is one ``GltfError`` whose message reads ``FILE: FIELD: problem`` (``buffers[0].uri``,
``accessors[3]``, ``meshes[0].primitives[1].mode``, ``extensionsRequired``), never a traceback.
numpy + pygltflib + Pillow + trimesh; no torch.

The reader in parts, each one concern: ``gltf_types`` (the records, the error, the spec's tables),
``gltf_document`` (the file: GLB chunks, buffers, accessors, images), ``gltf_materials``
(textures, materials, the specular-glossiness conversion), ``gltf_meshes`` (the node walk,
primitives, instancing, tangents); this module puts their results together into one asset.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from .gltf_document import GltfDocument
from .gltf_materials import linear_to_srgb, material, specular_glossiness_to_metallic, srgb_to_linear, texture_transform
from .gltf_meshes import mikktspace_tangents, scene_primitives
from .gltf_types import (ALPHA_MODES, COMPONENTS, GLB_BIN, GLB_JSON, GLB_MAGIC, IMAGE_FORMATS, MODES,
                         SPECULAR_GLOSSINESS, SUPPORTED_EXTENSIONS, UV_SETS, WIDTHS, WRAPS, GltfAsset, GltfError,
                         Material, TextureRef, field_error, gltf_uv)

# the reader's public names, wherever they are defined (techniques, tests and the writer import them from here)
__all__ = ["ALPHA_MODES", "COMPONENTS", "GLB_BIN", "GLB_JSON", "GLB_MAGIC", "IMAGE_FORMATS", "MODES",
           "SPECULAR_GLOSSINESS", "SUPPORTED_EXTENSIONS", "UV_SETS", "WIDTHS", "WRAPS", "GltfAsset", "GltfError",
           "Material", "TextureRef", "copy_gltf", "gltf_uv", "linear_to_srgb", "load_gltf", "mikktspace_tangents",
           "specular_glossiness_to_metallic", "srgb_to_linear", "texture_transform"]


def copy_gltf(path, folder, stem: str = "source") -> str:
    """Copy a glTF file into ``folder`` as ``stem.glb`` / ``stem.gltf``, bytes unchanged (an asset
    draws what was learnt from; any other single file, e.g. an OBJ, likewise); a .gltf brings the
    buffers and images it names by relative path, to the same relative paths. A uri outside the file's folder is a GltfError (pack it as .glb).
    Every file is written atomically. Returns the copy's name."""
    import json
    from urllib.parse import unquote

    from inshade.files import atomic_write

    path, folder = Path(path), Path(folder)
    name = f"{stem}{path.suffix.lower()}"
    files = []
    if path.suffix.lower() == ".gltf":
        doc = json.loads(path.read_text())
        base = path.parent.resolve()
        for key in ("buffers", "images"):
            for i, item in enumerate(doc.get(key) or []):
                uri = item.get("uri") if isinstance(item, dict) else None
                if not isinstance(uri, str) or uri.startswith("data:"):
                    continue
                source = (base / unquote(uri)).resolve()
                if base not in source.parents:
                    raise GltfError(f"{path}: {key}[{i}].uri: {uri!r} lies outside the file's folder; an asset "
                                    "copies the file with what it names (pack it as .glb)")
                files.append(source)
    atomic_write(folder / name, path.read_bytes())
    for source in files:
        atomic_write(folder / source.relative_to(path.parent.resolve()), source.read_bytes())
    return name

# reading ------------------------------------------------------------------------------------------
def load_gltf(path) -> GltfAsset:
    """Read ``path`` (GltfError ``FILE: FIELD: problem`` on any problem)."""
    path = Path(path)
    try:
        return _asset(GltfDocument(path))
    except GltfError as exc:
        raise GltfError(f"{path}: {exc}") from None


def _asset(doc: GltfDocument) -> GltfAsset:
    """The scene's primitives joined into one mesh, with the materials they use."""
    parts = scene_primitives(doc)
    materials = _materials(doc)
    default = len(materials)
    any_uv = any(p["uv"] is not None for p in parts)
    any_uv1 = any(t.texcoord == 1 for m in materials for t in m.textures().values())
    if not any_uv and any(m.textures() for m in materials):
        raise field_error("meshes", "materials have textures, but no primitive has TEXCOORD_0")
    columns, generated = _columns(parts, materials, default)
    face_material = np.concatenate(columns["face_material"])
    if (face_material == default).any():
        materials.append(Material(name="default"))
    if generated:
        doc.notes.append("tangents generated (MikkTSpace) where the file has none")
    uv = np.concatenate(columns["uv"])
    visual = trimesh.visual.TextureVisuals(uv=gltf_uv(uv)) if any_uv else None
    mesh = trimesh.Trimesh(np.concatenate(columns["position"]), np.concatenate(columns["faces"]), visual=visual,
                           process=False, validate=False)
    mesh.vertex_attributes["normal"] = np.concatenate(columns["normal"])
    mesh.vertex_attributes["tangent"] = np.concatenate(columns["tangent"])
    # a vertex belongs to one primitive, so to one material: the G-buffer carries it per vertex
    material_of_vertex = np.zeros(len(mesh.vertices))
    material_of_vertex[mesh.faces.reshape(-1)] = np.repeat(face_material, 3)
    mesh.vertex_attributes["material"] = material_of_vertex
    if any_uv1:   # the second uv set, v up as the first (only where a texture reads it)
        mesh.vertex_attributes["uv1"] = gltf_uv(np.concatenate(columns["uv1"]))
    see_through = [f"{materials[i].name} ({materials[i].alpha_mode})" for i in np.unique(face_material)
                   if materials[i].alpha_mode != "OPAQUE"]
    if see_through:
        doc.notes.append(f"alpha: {', '.join(see_through)} drawn with the file's own alpha in every view (MASK "
                         "cut out, BLEND peeled and laid over what lies behind, as the reference pass draws "
                         "them); a learnt material learns their colour, not their alpha")
    return GltfAsset(doc.path, mesh, face_material, materials, doc.images, doc.notes, doc.extensions)


def _materials(doc: GltfDocument) -> list[Material]:
    """Every material of the file (used or not: indices stay the file's), their uv sets checked."""
    materials = [material(doc, i) for i in range(len(doc.entries("materials")))]
    for m in materials:
        for slot, t in m.textures().items():
            if t.texcoord not in UV_SETS:
                raise field_error(f"materials ({m.name}).{slot}", f"reads uv set {t.texcoord}; TEXCOORD_0 and "
                                  "TEXCOORD_1 are supported")
    return materials


def _columns(parts: list[dict], materials: list[Material], default: int) -> tuple[dict, bool]:
    """{attribute: [one array per primitive]} with faces offset into the joined vertices and tangents
    made where a primitive has none; and whether any were made."""
    columns = {key: [] for key in ("position", "normal", "tangent", "uv", "uv1", "faces", "face_material")}
    base, generated = 0, False
    for p in parts:
        v = len(p["position"])
        columns["position"].append(p["position"])
        columns["normal"].append(p["normal"])
        sets = [p["uv"], p["uv1"]]
        used = materials[p["material"]].textures() if p["material"] is not None else {}
        for slot, t in used.items():
            if sets[t.texcoord] is None:
                raise field_error(p["where"], f"material {p['material']} ({materials[p['material']].name}).{slot} "
                                  f"reads TEXCOORD_{t.texcoord}, but the primitive has none")
        columns["uv"].append(p["uv"] if p["uv"] is not None else np.zeros((v, 2)))
        columns["uv1"].append(p["uv1"] if p["uv1"] is not None else np.zeros((v, 2)))
        if p["tangent"] is None:
            # MikkTSpace on the normal texture's uv set (the spec's tangent space), else TEXCOORD_0
            tangent_uv = sets[used["normal"].texcoord] if "normal" in used else p["uv"]
            generated |= tangent_uv is not None and p["needs_tangent"]
            columns["tangent"].append(mikktspace_tangents(p["position"], p["normal"], tangent_uv, p["faces"])
                                      if tangent_uv is not None else np.zeros((v, 4)))
        else:
            columns["tangent"].append(p["tangent"])
        columns["faces"].append(p["faces"] + base)
        columns["face_material"].append(np.full(len(p["faces"]), default if p["material"] is None else p["material"],
                                                np.int32))
        base += v
    return columns, generated
