"""A glTF file as the source of a UV-free material: read it (one error line for anything that cannot
be used) and size what it holds -- the texture bytes
the decoder is compared with and the texels its surface carries (the hierarchy's depth follows from
them). numpy + the glTF reader; no torch.
"""
from __future__ import annotations

import base64
import json
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from inshade.geometry.gltf import GLB_JSON, GLB_MAGIC, GltfError, load_gltf
from inshade.geometry.gltf_sample import require_first_uv_set
from inshade.geometry.mesh import GLTF_SUFFIXES, mesh_uv

SOURCE = "source"   # the copy's name in the asset folder: source.glb | source.gltf


class GltfSourceError(ValueError):
    """A glTF file that cannot be learnt from; ``FILE: FIELD: problem``."""


def read(path):
    """The ``GltfAsset`` of ``path``. Its textures are looked up at the mesh's uv, so a file with
    textured materials and no TEXCOORD_0 is refused (the reader says so, naming the field)."""
    path = Path(path)
    if path.suffix.lower() not in GLTF_SUFFIXES:
        raise GltfSourceError(f"{path}: --gltf: expected a .glb or .gltf file")
    if not path.is_file():
        raise GltfSourceError(f"{path}: --gltf: no such file")
    try:
        asset = load_gltf(path)
        require_first_uv_set(asset)
        return asset
    except GltfError as exc:   # a textured material without TEXCOORD_0 is one of these
        raise GltfSourceError(str(exc)) from None


def _document(path: Path) -> tuple[dict, bytes | None]:
    """The glTF JSON and, for a .glb, the raw file (for its buffer views)."""
    raw = path.read_bytes()
    if path.suffix.lower() == ".glb":
        magic, _, _ = struct.unpack_from("<III", raw, 0)
        length, kind = struct.unpack_from("<II", raw, 12)
        if magic != GLB_MAGIC or kind != GLB_JSON:   # the reader has accepted it: not reached for a read file
            raise GltfSourceError(f"{path}: header: not a GLB file")
        return json.loads(raw[20:20 + length]), raw
    return json.loads(raw), None


def _external(doc: dict) -> list[str]:
    """The relative file uris of buffers and images (data uris excluded)."""
    uris = [item.get("uri") for key in ("buffers", "images") for item in doc.get(key, []) if isinstance(item, dict)]
    return [u for u in uris if isinstance(u, str) and not u.startswith("data:")]


def file_image_bytes(path) -> int:
    """The bytes the file spends on images as it stores them (PNG/JPEG: buffer views, data uris or
    image files), every image counted once."""
    path = Path(path)
    doc, raw = _document(path)
    views = doc.get("bufferViews", [])
    total = 0
    for image in doc.get("images", []):
        if "bufferView" in image:
            total += int(views[image["bufferView"]]["byteLength"])
        elif str(image.get("uri", "")).startswith("data:"):
            total += len(base64.b64decode(image["uri"].split(",", 1)[1]))
        elif "uri" in image:
            total += (path.parent / unquote(image["uri"])).stat().st_size
    return total


def used_images(asset) -> list[int]:
    """The images the used materials read (indices into ``asset.images``)."""
    return sorted({t.image for m in asset.used_materials() for t in asset.materials[m].textures().values()})


def texture_bytes(asset) -> int:
    """The textures the used materials read, uncompressed as the renderer uploads them (RGBA8, base
    level; mip maps would add a third)."""
    return int(sum(asset.images[i].shape[0] * asset.images[i].shape[1] * 4 for i in used_images(asset)))


def surface_texels(asset) -> float:
    """How many texels the surface carries: per material, the most of any of its textures (texels x
    the uv area of its faces x the area scale of its KHR_texture_transform), summed over materials.
    A face then covers ``texels / faces`` of them (model.py choose_levels)."""
    uv = mesh_uv(asset.mesh)
    if uv is None:
        return 1.0
    t = uv[np.asarray(asset.mesh.faces)]
    a, b = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    total = 0.0
    for m in asset.used_materials():
        faces_area = float(area[asset.face_material == m].sum())
        texels = [asset.images[r.image].shape[0] * asset.images[r.image].shape[1] * abs(np.linalg.det(r.transform[:2, :2]))
                  for r in asset.materials[m].textures().values()]
        total += faces_area * max(texels, default=0.0)
    return max(total, 1.0)
