"""glTF's vocabulary, shared by the reader's parts (geometry/gltf.py re-exports it): the records a
read returns (``Material``, ``TextureRef``, ``GltfAsset``), the one error type, the tables of the
spec's enums and the field checks every part uses.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from .gltf_codecs import EXTENSIONS as CODEC_EXTENSIONS

# what this reader understands; a required extension outside it is refused, an optional one ignored
SUPPORTED_EXTENSIONS = (
    "KHR_texture_transform", "KHR_materials_clearcoat", "KHR_materials_anisotropy", "KHR_materials_sheen",
    "KHR_materials_pbrSpecularGlossiness", "KHR_materials_emissive_strength", "KHR_materials_ior",
    "KHR_mesh_quantization", "EXT_mesh_gpu_instancing", "EXT_texture_webp", *CODEC_EXTENSIONS,
)
# image formats a texture's source may have: the core's, and those an extension brings
IMAGE_FORMATS = {"PNG": None, "JPEG": None, "WEBP": "EXT_texture_webp"}
SPECULAR_GLOSSINESS = "KHR_materials_pbrSpecularGlossiness"

COMPONENTS = {5120: ("i1", 127.0), 5121: ("u1", 255.0), 5122: ("i2", 32767.0), 5123: ("u2", 65535.0),
              5125: ("u4", None), 5126: ("f4", None)}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
MODES = {0: "points", 1: "lines", 2: "line loop", 3: "line strip", 4: "triangles", 5: "triangle strip",
         6: "triangle fan"}
WRAPS = {33071: "clamp", 33648: "mirror", 10497: "repeat"}
ALPHA_MODES = ("OPAQUE", "MASK", "BLEND")
GLB_MAGIC, GLB_JSON, GLB_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942


class GltfError(ValueError):
    """A glTF file that cannot be used; the message names the file and the field."""


@dataclass
class TextureRef:
    """A material's texture: an image, the uv set it reads, KHR_texture_transform as a 3x3 matrix on
    glTF uv (column vector, ``uv' = M @ (u, v, 1)``), the sampler's wrap modes and the slot's scalar
    (normal scale, occlusion strength; 1 elsewhere)."""
    image: int
    texcoord: int = 0
    transform: np.ndarray = field(default_factory=lambda: np.eye(3))
    wrap: tuple[str, str] = ("repeat", "repeat")
    scale: float = 1.0


@dataclass
class Material:
    """glTF's metallic-roughness material with the KHR lobes this project shades (defaults = the
    spec's defaults). Colours are linear (factors), textures hold what the file stores."""
    name: str = ""
    base_color: tuple = (1.0, 1.0, 1.0, 1.0)
    base_color_texture: TextureRef | None = None
    metallic: float = 1.0
    roughness: float = 1.0
    metallic_roughness_texture: TextureRef | None = None   # G = roughness, B = metallic
    normal_texture: TextureRef | None = None               # scale = normal scale
    occlusion_texture: TextureRef | None = None            # R; scale = strength
    emissive: tuple = (0.0, 0.0, 0.0)                       # emissive_strength applied
    emissive_texture: TextureRef | None = None
    alpha_mode: str = "OPAQUE"
    alpha_cutoff: float = 0.5
    double_sided: bool = False
    ior: float = 1.5
    clearcoat: float = 0.0
    clearcoat_texture: TextureRef | None = None             # R
    clearcoat_roughness: float = 0.0
    clearcoat_roughness_texture: TextureRef | None = None   # G
    clearcoat_normal_texture: TextureRef | None = None
    sheen_color: tuple = (0.0, 0.0, 0.0)
    sheen_color_texture: TextureRef | None = None           # RGB (sRGB)
    sheen_roughness: float = 0.0
    sheen_roughness_texture: TextureRef | None = None       # A
    anisotropy_strength: float = 0.0
    anisotropy_rotation: float = 0.0                        # radians, from the tangent towards the bitangent
    anisotropy_texture: TextureRef | None = None            # RG direction, B strength
    converted_from: str | None = None                       # SPECULAR_GLOSSINESS when converted

    def textures(self) -> dict[str, TextureRef]:
        """{slot: TextureRef} of the textures it has."""
        return {k[:-len("_texture")]: v for k, v in vars(self).items() if k.endswith("_texture") and v is not None}


@dataclass
class GltfAsset:
    path: Path
    mesh: trimesh.Trimesh
    face_material: np.ndarray
    materials: list
    images: list
    notes: list = field(default_factory=list)
    extensions: tuple = ()          # extensions the file uses that this reader applied

    def material_of(self, index: int = 0) -> Material:
        return self.materials[index]

    def used_materials(self) -> list[int]:
        return sorted(int(m) for m in np.unique(self.face_material))


UV_SETS = (0, 1)   # TEXCOORD_n a texture may read (G-buffer targets "uv" and "uv1", runtime/geometry.py)


def gltf_uv(uv: np.ndarray) -> np.ndarray:
    """The project's uv (v up) as glTF's (v down) and back: the same flip both ways."""
    uv = np.asarray(uv, np.float64).copy()
    uv[..., 1] = 1.0 - uv[..., 1]
    return uv


def field_error(where: str, what: str) -> GltfError:
    """The error a part raises: ``FIELD: problem`` (``load_gltf`` puts the file in front)."""
    return GltfError(f"{where}: {what}")


def floats(value, n: int, where: str) -> tuple:
    """``n`` finite numbers (a factor, a node's translation) as floats."""
    if not isinstance(value, (list, tuple)) or len(value) != n or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value):
        raise field_error(where, f"must be {n} numbers, got {value!r}")
    return tuple(float(x) for x in value)


def unit(value, where: str) -> float:
    """A number in [0, 1] (metallic, roughness, a lobe's strength) as a float."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= value <= 1.0:
        raise field_error(where, f"must be a number in [0, 1], got {value!r}")
    return float(value)

