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
"""
from __future__ import annotations

import base64
import io
import math
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from .gltf_codecs import DRACO, KTX2_MAGIC, MESHOPT, CodecError, draco_attributes, ktx2_rgba, meshopt_view
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


def copy_gltf(path, folder, stem: str = "source") -> str:
    """Copy a glTF file into ``folder`` as ``stem.glb`` / ``stem.gltf``, bytes unchanged (an asset
    draws what was learnt from; any other single file, e.g. an OBJ, likewise); a .gltf brings the buffers and images it names by relative path,
    to the same relative paths. A uri outside the file's folder is a GltfError (pack it as .glb).
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


UV_SETS = (0, 1)   # TEXCOORD_n a texture may read (G-buffer targets "uv" and "uv1", runtime/geometry.py)


def gltf_uv(uv: np.ndarray) -> np.ndarray:
    """The project's uv (v up) as glTF's (v down) and back: the same flip both ways."""
    uv = np.asarray(uv, np.float64).copy()
    uv[..., 1] = 1.0 - uv[..., 1]
    return uv


# reading ------------------------------------------------------------------------------------------
def load_gltf(path) -> GltfAsset:
    """Read ``path`` (GltfError ``FILE: FIELD: problem`` on any problem)."""
    path = Path(path)
    try:
        return _Reader(path).asset()
    except GltfError as exc:
        raise GltfError(f"{path}: {exc}") from None


def _err(where: str, what: str) -> GltfError:
    return GltfError(f"{where}: {what}")


class _Reader:
    def __init__(self, path: Path):
        if not path.is_file():
            raise GltfError("no such file" if not path.exists() else "not a file")
        self.path = path
        self.notes: list[str] = []
        raw = path.read_bytes()
        self.blob = None
        if raw[:4] == struct.pack("<I", GLB_MAGIC):
            doc_bytes = self._glb(raw)
        else:
            doc_bytes = raw
        import json

        try:
            self.doc = json.loads(doc_bytes.decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as exc:
            raise GltfError(f"not glTF JSON ({exc})") from None
        if not isinstance(self.doc, dict):
            raise _err("(top level)", "must be a JSON object")
        version = (self.doc.get("asset") or {}).get("version")
        if not isinstance(version, str) or not version.startswith("2."):
            raise _err("asset.version", f"must be \"2.x\" (glTF 2.0), got {version!r}")
        required = self._list("extensionsRequired")
        unknown = [e for e in required if e not in SUPPORTED_EXTENSIONS]
        if unknown:
            raise _err("extensionsRequired", f"{', '.join(unknown)}: not supported (this reader knows "
                       f"{', '.join(SUPPORTED_EXTENSIONS)})")
        used = self._list("extensionsUsed")
        ignored = [e for e in used if e not in SUPPORTED_EXTENSIONS]
        if ignored:
            self.notes.append(f"optional extensions ignored: {', '.join(ignored)}")
        self.extensions = tuple(e for e in used if e in SUPPORTED_EXTENSIONS)
        self._buffers: dict[int, bytes] = {}
        self._images: dict[int, int] = {}
        self.images: list[np.ndarray] = []

    # containers --------------------------------------------------------------------------------
    def _glb(self, raw: bytes) -> bytes:
        if len(raw) < 20:
            raise _err("GLB header", f"{len(raw)} bytes: shorter than a header and one chunk")
        _, version, length = struct.unpack_from("<III", raw, 0)
        if version != 2:
            raise _err("GLB header", f"version {version}, expected 2")
        if length > len(raw):
            raise _err("GLB header", f"declares {length} bytes, the file has {len(raw)}")
        offset, doc = 12, None
        while offset + 8 <= length:
            size, kind = struct.unpack_from("<II", raw, offset)
            body = raw[offset + 8: offset + 8 + size]
            if len(body) != size:
                raise _err("GLB chunk", f"at byte {offset} declares {size} bytes past the end of the file")
            if kind == GLB_JSON and doc is None:
                doc = body
            elif kind == GLB_BIN and self.blob is None:
                self.blob = body
            offset += 8 + size + (-size % 4)
        if doc is None:
            raise _err("GLB", "no JSON chunk")
        return doc

    def _list(self, key: str) -> list:
        value = self.doc.get(key, [])
        if not isinstance(value, list):
            raise _err(key, "must be a list")
        return value

    def _item(self, key: str, index, where: str) -> dict:
        items = self._list(key)
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(items):
            raise _err(where, f"{index!r} is not an index into {key} (0..{len(items) - 1})")
        item = items[index]
        if not isinstance(item, dict):
            raise _err(f"{key}[{index}]", "must be an object")
        return item

    def _uri(self, uri: str, where: str) -> bytes:
        if uri.startswith("data:"):
            head, _, data = uri.partition(",")
            if not head.endswith(";base64"):
                raise _err(where, "a data URI must be base64")
            try:
                return base64.b64decode(data, validate=True)
            except ValueError as exc:
                raise _err(where, f"bad base64 ({exc})") from None
        from urllib.parse import unquote

        file = (self.path.parent / unquote(uri))
        if not file.is_file():
            raise _err(where, f"no file {file}")
        return file.read_bytes()

    def buffer(self, index: int, where: str) -> bytes:
        if index not in self._buffers:
            b = self._item("buffers", index, where)
            w = f"buffers[{index}]"
            if "uri" in b:
                data = self._uri(b["uri"], f"{w}.uri")
            elif index == 0 and self.blob is not None:
                data = self.blob
            else:
                raise _err(w, "no uri and no GLB binary chunk: the buffer's bytes are missing")
            length = b.get("byteLength")
            if not isinstance(length, int) or length < 1:
                raise _err(f"{w}.byteLength", f"must be an int >= 1, got {length!r}")
            if len(data) < length:
                raise _err(w, f"byteLength {length}, but its data has {len(data)} bytes")
            self._buffers[index] = data[:length]
        return self._buffers[index]

    def view(self, index: int, where: str) -> tuple[bytes, int | None]:
        v = self._item("bufferViews", index, where)
        w = f"bufferViews[{index}]"
        packed = next(((name, e) for name, e in (v.get("extensions") or {}).items() if name in MESHOPT), None)
        if packed is not None:   # compressed: the view's bytes are decoded from the extension's range
            name, ext = packed
            return self._decoded_view(ext, f"{w}.extensions.{name}"), ext.get("byteStride")
        data = self.buffer(v.get("buffer"), f"{w}.buffer")
        offset, length = v.get("byteOffset", 0), v.get("byteLength")
        if not isinstance(length, int) or length < 1 or not isinstance(offset, int) or offset < 0:
            raise _err(w, f"byteOffset {offset!r} / byteLength {length!r}: must be ints (offset >= 0, length >= 1)")
        if offset + length > len(data):
            raise _err(w, f"bytes {offset}..{offset + length} lie past the end of buffer {v.get('buffer')} "
                       f"({len(data)} bytes)")
        return data[offset: offset + length], v.get("byteStride")

    def _decoded_view(self, ext, where: str) -> bytes:
        if not isinstance(ext, dict):
            raise _err(where, "must be an object")
        data = self.buffer(ext.get("buffer"), f"{where}.buffer")
        offset, length = ext.get("byteOffset", 0), ext.get("byteLength")
        if not isinstance(length, int) or length < 1 or not isinstance(offset, int) or offset < 0 \
                or offset + length > len(data):
            raise _err(where, f"byteOffset {offset!r} / byteLength {length!r}: not a range of buffer "
                       f"{ext.get('buffer')} ({len(data)} bytes)")
        try:
            return meshopt_view(data[offset: offset + length], ext, where)
        except CodecError as exc:
            raise _err(exc.where, exc.what) from None

    def accessor(self, index, where: str) -> np.ndarray:
        """An accessor's elements as float64 (normalised ints scaled) or int64 [count, width]."""
        a = self._item("accessors", index, where)
        w = f"accessors[{index}]"
        if a.get("componentType") not in COMPONENTS or a.get("type") not in WIDTHS:
            raise _err(w, f"componentType {a.get('componentType')!r} / type {a.get('type')!r}: not a glTF "
                       "accessor layout")
        dtype, norm = COMPONENTS[a["componentType"]]
        width = WIDTHS[a["type"]]
        count = a.get("count")
        if not isinstance(count, int) or count < 1:
            raise _err(f"{w}.count", f"must be an int >= 1, got {count!r}")
        item = np.dtype("<" + dtype)
        element = item.itemsize * width
        if "bufferView" in a:
            data, stride = self.view(a["bufferView"], f"{w}.bufferView")
            stride = stride or element
            offset = a.get("byteOffset", 0)
            end = offset + stride * (count - 1) + element
            if not isinstance(offset, int) or offset < 0 or end > len(data):
                raise _err(w, f"{count} elements of {element} bytes (stride {stride}) from byte {offset} need "
                           f"{end} bytes; bufferView {a['bufferView']} has {len(data)}")
            rows = np.lib.stride_tricks.as_strided(np.frombuffer(data, np.uint8, offset=offset),
                                                   shape=(count, element), strides=(stride, 1))
            values = np.ascontiguousarray(rows).view(item).reshape(count, width)
        else:
            values = np.zeros((count, width), item)
        values = values.astype(np.float64 if dtype == "f4" or a.get("normalized") else np.int64)
        if a.get("normalized"):
            if norm is None:
                raise _err(f"{w}.normalized", f"{dtype} components cannot be normalised")
            values = np.maximum(values / norm, -1.0)
        if "sparse" in a:
            values = self._sparse(a["sparse"], values, item, width, norm if a.get("normalized") else None, w)
        if not np.isfinite(values).all():
            raise _err(w, "holds NaN or infinite values")
        return values

    def _sparse(self, s, values, item, width, norm, w):
        n = s.get("count")
        if not isinstance(n, int) or n < 1:
            raise _err(f"{w}.sparse.count", f"must be an int >= 1, got {n!r}")
        idx_dtype = COMPONENTS.get((s.get("indices") or {}).get("componentType"), (None,))[0]
        if idx_dtype not in ("u1", "u2", "u4"):
            raise _err(f"{w}.sparse.indices.componentType", "must be an unsigned int type")
        data, _ = self.view(s["indices"].get("bufferView"), f"{w}.sparse.indices.bufferView")
        dt = np.dtype("<" + idx_dtype)
        start = s["indices"].get("byteOffset", 0)
        if start + n * dt.itemsize > len(data):
            raise _err(f"{w}.sparse.indices", "reads past its bufferView")
        idx = np.frombuffer(data, dt, count=n, offset=start).astype(np.int64)
        if idx.max() >= len(values):
            raise _err(f"{w}.sparse.indices", f"index {int(idx.max())} past the accessor's {len(values)} elements")
        data, _ = self.view(s.get("values", {}).get("bufferView"), f"{w}.sparse.values.bufferView")
        start = s["values"].get("byteOffset", 0)
        if start + n * width * item.itemsize > len(data):
            raise _err(f"{w}.sparse.values", "reads past its bufferView")
        sub = np.frombuffer(data, item, count=n * width, offset=start).reshape(n, width).astype(values.dtype)
        if norm is not None:
            sub = np.maximum(sub / norm, -1.0)
        values = values.copy()
        values[idx] = sub
        return values

    # images and materials ----------------------------------------------------------------------
    def image(self, index, where: str) -> int:
        if index in self._images:
            return self._images[index]
        im = self._item("images", index, where)
        w = f"images[{index}]"
        if "uri" in im:
            data = self._uri(im["uri"], f"{w}.uri")
        elif "bufferView" in im:
            data, _ = self.view(im["bufferView"], f"{w}.bufferView")
        else:
            raise _err(w, "needs a uri or a bufferView")
        if data[:12] == KTX2_MAGIC and "KHR_texture_basisu" in self.extensions:
            try:
                array = ktx2_rgba(data, w)
            except CodecError as exc:
                raise _err(exc.where, exc.what) from None
        else:
            array = self._picture(data, w)
        self.images.append(np.ascontiguousarray(array))
        self._images[index] = len(self.images) - 1
        return self._images[index]

    def _picture(self, data: bytes, w: str) -> np.ndarray:
        """A PNG / JPEG (or WebP, with its extension) image as RGBA8."""
        from PIL import Image, UnidentifiedImageError

        try:
            with Image.open(io.BytesIO(data)) as pil:
                if pil.format not in IMAGE_FORMATS or IMAGE_FORMATS[pil.format] not in (None, *self.extensions):
                    raise _err(w, f"{pil.format} image: glTF images are PNG or JPEG (WebP with EXT_texture_webp, "
                               "KTX2 with KHR_texture_basisu)")
                return np.asarray(pil.convert("RGBA"), np.uint8)
        except (UnidentifiedImageError, OSError) as exc:
            raise _err(w, f"cannot decode ({exc})") from None

    def texture(self, info, where: str, scale_key: str | None = None) -> TextureRef | None:
        if info is None:
            return None
        if not isinstance(info, dict):
            raise _err(where, "must be a textureInfo object")
        tex = self._item("textures", info.get("index"), f"{where}.index")
        source = tex.get("source")
        for name in ("KHR_texture_basisu", "EXT_texture_webp"):   # an extension's image first, the core's the fallback
            ext = (tex.get("extensions") or {}).get(name)
            if isinstance(ext, dict) and "source" in ext:
                source = ext["source"]
                break
        if source is None:
            raise _err(f"textures[{info['index']}].source", "missing (no image)")
        image = self.image(source, f"textures[{info['index']}].source")
        wrap = ("repeat", "repeat")
        if "sampler" in tex:
            s = self._item("samplers", tex["sampler"], f"textures[{info['index']}].sampler")
            try:
                wrap = (WRAPS[s.get("wrapS", 10497)], WRAPS[s.get("wrapT", 10497)])
            except KeyError:
                raise _err(f"samplers[{tex['sampler']}]", "wrapS/wrapT must be 33071, 33648 or 10497") from None
        texcoord = info.get("texCoord", 0)
        transform = np.eye(3)
        ext = (info.get("extensions") or {}).get("KHR_texture_transform")
        if ext is not None:
            transform = texture_transform(ext.get("offset", (0.0, 0.0)), ext.get("rotation", 0.0),
                                          ext.get("scale", (1.0, 1.0)))
            texcoord = ext.get("texCoord", texcoord)
        if not isinstance(texcoord, int) or texcoord < 0:
            raise _err(f"{where}.texCoord", f"must be an int >= 0, got {texcoord!r}")
        scale = float(info.get(scale_key, 1.0)) if scale_key else 1.0
        return TextureRef(image, texcoord, transform, wrap, scale)

    def material(self, index: int) -> Material:
        m = self._item("materials", index, "materials")
        w = f"materials[{index}]"
        ext = m.get("extensions") or {}
        pbr = m.get("pbrMetallicRoughness") or {}
        out = Material(name=str(m.get("name", f"material {index}")))
        out.base_color = _floats(pbr.get("baseColorFactor", out.base_color), 4, f"{w}.pbrMetallicRoughness.baseColorFactor")
        out.base_color_texture = self.texture(pbr.get("baseColorTexture"), f"{w}.pbrMetallicRoughness.baseColorTexture")
        out.metallic = _unit(pbr.get("metallicFactor", 1.0), f"{w}.pbrMetallicRoughness.metallicFactor")
        out.roughness = _unit(pbr.get("roughnessFactor", 1.0), f"{w}.pbrMetallicRoughness.roughnessFactor")
        out.metallic_roughness_texture = self.texture(pbr.get("metallicRoughnessTexture"),
                                                      f"{w}.pbrMetallicRoughness.metallicRoughnessTexture")
        out.normal_texture = self.texture(m.get("normalTexture"), f"{w}.normalTexture", "scale")
        out.occlusion_texture = self.texture(m.get("occlusionTexture"), f"{w}.occlusionTexture", "strength")
        strength = float((ext.get("KHR_materials_emissive_strength") or {}).get("emissiveStrength", 1.0))
        out.emissive = tuple(strength * c for c in _floats(m.get("emissiveFactor", (0.0, 0.0, 0.0)), 3,
                                                             f"{w}.emissiveFactor"))
        out.emissive_texture = self.texture(m.get("emissiveTexture"), f"{w}.emissiveTexture")
        out.alpha_mode = m.get("alphaMode", "OPAQUE")
        if out.alpha_mode not in ALPHA_MODES:
            raise _err(f"{w}.alphaMode", f"must be one of {', '.join(ALPHA_MODES)}, got {out.alpha_mode!r}")
        out.alpha_cutoff = float(m.get("alphaCutoff", 0.5))
        out.double_sided = bool(m.get("doubleSided", False))
        if "KHR_materials_ior" in ext:
            out.ior = float(ext["KHR_materials_ior"].get("ior", 1.5))
        cc = ext.get("KHR_materials_clearcoat")
        if cc is not None:
            e = f"{w}.extensions.KHR_materials_clearcoat"
            out.clearcoat = _unit(cc.get("clearcoatFactor", 0.0), f"{e}.clearcoatFactor")
            out.clearcoat_texture = self.texture(cc.get("clearcoatTexture"), f"{e}.clearcoatTexture")
            out.clearcoat_roughness = _unit(cc.get("clearcoatRoughnessFactor", 0.0), f"{e}.clearcoatRoughnessFactor")
            out.clearcoat_roughness_texture = self.texture(cc.get("clearcoatRoughnessTexture"),
                                                           f"{e}.clearcoatRoughnessTexture")
            out.clearcoat_normal_texture = self.texture(cc.get("clearcoatNormalTexture"),
                                                        f"{e}.clearcoatNormalTexture", "scale")
        sh = ext.get("KHR_materials_sheen")
        if sh is not None:
            e = f"{w}.extensions.KHR_materials_sheen"
            out.sheen_color = _floats(sh.get("sheenColorFactor", (0.0, 0.0, 0.0)), 3, f"{e}.sheenColorFactor")
            out.sheen_color_texture = self.texture(sh.get("sheenColorTexture"), f"{e}.sheenColorTexture")
            out.sheen_roughness = _unit(sh.get("sheenRoughnessFactor", 0.0), f"{e}.sheenRoughnessFactor")
            out.sheen_roughness_texture = self.texture(sh.get("sheenRoughnessTexture"), f"{e}.sheenRoughnessTexture")
        an = ext.get("KHR_materials_anisotropy")
        if an is not None:
            e = f"{w}.extensions.KHR_materials_anisotropy"
            out.anisotropy_strength = _unit(an.get("anisotropyStrength", 0.0), f"{e}.anisotropyStrength")
            out.anisotropy_rotation = float(an.get("anisotropyRotation", 0.0))
            out.anisotropy_texture = self.texture(an.get("anisotropyTexture"), f"{e}.anisotropyTexture")
        sg = ext.get(SPECULAR_GLOSSINESS)
        if sg is not None:
            self._convert_specular_glossiness(out, sg, f"{w}.extensions.{SPECULAR_GLOSSINESS}")
        return out

    def _convert_specular_glossiness(self, out: Material, sg: dict, where: str) -> None:
        diffuse = np.array(_floats(sg.get("diffuseFactor", (1.0, 1.0, 1.0, 1.0)), 4, f"{where}.diffuseFactor"))
        specular = np.array(_floats(sg.get("specularFactor", (1.0, 1.0, 1.0)), 3, f"{where}.specularFactor"))
        gloss = _unit(sg.get("glossinessFactor", 1.0), f"{where}.glossinessFactor")
        d_tex = self.texture(sg.get("diffuseTexture"), f"{where}.diffuseTexture")
        s_tex = self.texture(sg.get("specularGlossinessTexture"), f"{where}.specularGlossinessTexture")
        out.converted_from = SPECULAR_GLOSSINESS
        if d_tex is None and s_tex is None:
            base, metallic = specular_glossiness_to_metallic(diffuse[None, :3], specular[None])
            out.base_color = (*base[0].tolist(), float(diffuse[3]))
            out.metallic, out.roughness = float(metallic[0]), 1.0 - gloss
            self.notes.append(f"{out.name}: {SPECULAR_GLOSSINESS} converted to metallic-roughness (approximate)")
            return
        ref = d_tex or s_tex
        for t in (d_tex, s_tex):
            if t is not None and (t.texcoord != ref.texcoord or not np.allclose(t.transform, ref.transform)):
                raise _err(where, "diffuse and specular-glossiness textures with different uv sets or "
                           "transforms cannot be converted per texel")
        shape = max((self.images[t.image].shape[:2] for t in (d_tex, s_tex) if t is not None),
                    key=lambda s: s[0] * s[1])
        d = _resized(self.images[d_tex.image], shape) if d_tex else np.full((*shape, 4), 255, np.uint8)
        s = _resized(self.images[s_tex.image], shape) if s_tex else np.full((*shape, 4), 255, np.uint8)
        d_lin = srgb_to_linear(d[..., :3] / 255.0) * diffuse[:3]
        s_lin = srgb_to_linear(s[..., :3] / 255.0) * specular
        g = s[..., 3] / 255.0 * gloss
        base, metallic = specular_glossiness_to_metallic(d_lin.reshape(-1, 3), s_lin.reshape(-1, 3))
        base_img = np.concatenate([_to8(linear_to_srgb(base.reshape(*shape, 3))),
                                   _to8(d[..., 3:] / 255.0 * diffuse[3])], -1)
        mr = np.stack([np.full(shape, 255, np.uint8), _to8(1.0 - g), _to8(metallic.reshape(shape)),
                       np.full(shape, 255, np.uint8)], -1)
        self.images += [base_img, mr]
        n = len(self.images)
        out.base_color, out.metallic, out.roughness = (1.0, 1.0, 1.0, 1.0), 1.0, 1.0
        out.base_color_texture = TextureRef(n - 2, ref.texcoord, ref.transform, ref.wrap)
        out.metallic_roughness_texture = TextureRef(n - 1, ref.texcoord, ref.transform, ref.wrap)
        self.notes.append(f"{out.name}: {SPECULAR_GLOSSINESS} converted to metallic-roughness per texel "
                          "(approximate: the metallic solve of the Khronos converter)")

    # geometry ----------------------------------------------------------------------------------
    def asset(self) -> GltfAsset:
        scenes = self._list("scenes")
        if scenes:
            index = self.doc.get("scene", 0)
            roots = self._item("scenes", index, "scene").get("nodes", [])
        else:
            children = {c for n in self._list("nodes") if isinstance(n, dict) for c in n.get("children", [])}
            roots = [i for i in range(len(self._list("nodes"))) if i not in children]
        parts: list[tuple] = []
        for root in roots:
            self._walk(root, np.eye(4), parts, set(), "scenes.nodes")
        if not parts:
            raise _err("scenes", "the default scene draws no triangles (no node with a mesh)")
        materials = [self.material(i) for i in range(len(self._list("materials")))]
        default = len(materials)
        for m in materials:
            for slot, t in m.textures().items():
                if t.texcoord not in UV_SETS:
                    raise _err(f"materials ({m.name}).{slot}", f"reads uv set {t.texcoord}; TEXCOORD_0 and "
                               "TEXCOORD_1 are supported")
        positions, normals, tangents, uvs, uv1s, faces, face_material = [], [], [], [], [], [], []
        base, any_uv, generated = 0, False, False
        any_uv1 = any(t.texcoord == 1 for m in materials for t in m.textures().values())
        for p in parts:
            if p["uv"] is not None:
                any_uv = True
        if not any_uv and any(m.textures() for m in materials):
            raise _err("meshes", "materials have textures, but no primitive has TEXCOORD_0")
        for p in parts:
            v = len(p["position"])
            positions.append(p["position"])
            normals.append(p["normal"])
            sets = [p["uv"], p["uv1"]]
            used = materials[p["material"]].textures() if p["material"] is not None else {}
            for slot, t in used.items():
                if sets[t.texcoord] is None:
                    raise _err(p["where"], f"material {p['material']} ({materials[p['material']].name}).{slot} reads "
                               f"TEXCOORD_{t.texcoord}, but the primitive has none")
            uv = p["uv"] if p["uv"] is not None else np.zeros((v, 2))
            uvs.append(uv)
            uv1s.append(p["uv1"] if p["uv1"] is not None else np.zeros((v, 2)))
            if p["tangent"] is None:
                # MikkTSpace on the normal texture's uv set (the spec's tangent space), else TEXCOORD_0
                tangent_uv = sets[used["normal"].texcoord] if "normal" in used else p["uv"]
                generated |= tangent_uv is not None and p["needs_tangent"]
                tangents.append(mikktspace_tangents(p["position"], p["normal"], tangent_uv, p["faces"])
                                if tangent_uv is not None else np.zeros((v, 4)))
            else:
                tangents.append(p["tangent"])
            faces.append(p["faces"] + base)
            face_material.append(np.full(len(p["faces"]), default if p["material"] is None else p["material"], np.int32))
            base += v
        face_material = np.concatenate(face_material)
        if (face_material == default).any():
            materials.append(Material(name="default"))
        if generated:
            self.notes.append("tangents generated (MikkTSpace) where the file has none")
        uv = np.concatenate(uvs)
        visual = trimesh.visual.TextureVisuals(uv=gltf_uv(uv)) if any_uv else None
        mesh = trimesh.Trimesh(np.concatenate(positions), np.concatenate(faces), visual=visual, process=False,
                               validate=False)
        mesh.vertex_attributes["normal"] = np.concatenate(normals)
        mesh.vertex_attributes["tangent"] = np.concatenate(tangents)
        # a vertex belongs to one primitive, so to one material: the G-buffer carries it per vertex
        material = np.zeros(len(mesh.vertices))
        material[mesh.faces.reshape(-1)] = np.repeat(face_material, 3)
        mesh.vertex_attributes["material"] = material
        if any_uv1:   # the second uv set, v up as the first (only where a texture reads it)
            mesh.vertex_attributes["uv1"] = gltf_uv(np.concatenate(uv1s))
        see_through = [f"{materials[i].name} ({materials[i].alpha_mode})" for i in np.unique(face_material)
                       if materials[i].alpha_mode != "OPAQUE"]
        if see_through:
            self.notes.append(f"alpha: {', '.join(see_through)} drawn with the file's own alpha in every view (MASK "
                              "cut out, BLEND peeled and laid over what lies behind, as the reference pass draws "
                              "them); a learnt material learns their colour, not their alpha")
        return GltfAsset(self.path, mesh, face_material, materials, self.images, self.notes, self.extensions)

    def _walk(self, index, parent: np.ndarray, parts: list, seen: set, where: str) -> None:
        node = self._item("nodes", index, where)
        if index in seen:
            raise _err(f"nodes[{index}]", "is its own ancestor (the node graph must be a tree)")
        seen = seen | {index}
        w = f"nodes[{index}]"
        world = parent @ _node_matrix(node, w)
        if "mesh" in node:
            instances = [world]
            inst = (node.get("extensions") or {}).get("EXT_mesh_gpu_instancing")
            if inst is not None:
                instances = [world @ m for m in self._instances(inst.get("attributes", {}), f"{w}.extensions"
                                                                ".EXT_mesh_gpu_instancing")]
            mesh = self._item("meshes", node["mesh"], f"{w}.mesh")
            prims = mesh.get("primitives")
            if not isinstance(prims, list) or not prims:
                raise _err(f"meshes[{node['mesh']}].primitives", "must be a non-empty list")
            for k, prim in enumerate(prims):
                local = self._primitive(prim, f"meshes[{node['mesh']}].primitives[{k}]")
                for m in instances:
                    parts.append(_transformed(local, m))
        for child in node.get("children", []):
            self._walk(child, world, parts, seen, f"{w}.children")

    def _instances(self, attributes: dict, where: str) -> list[np.ndarray]:
        arrays = {k: self.accessor(v, f"{where}.attributes.{k}") for k, v in attributes.items()
                  if k in ("TRANSLATION", "ROTATION", "SCALE")}
        if not arrays:
            raise _err(f"{where}.attributes", "needs TRANSLATION, ROTATION or SCALE")
        counts = {len(a) for a in arrays.values()}
        if len(counts) != 1:
            raise _err(f"{where}.attributes", "accessors of different counts")
        n = counts.pop()
        t = arrays.get("TRANSLATION", np.zeros((n, 3)))
        r = arrays.get("ROTATION", np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)))
        s = arrays.get("SCALE", np.ones((n, 3)))
        return [_trs(t[i], r[i], s[i]) for i in range(n)]

    def _primitive(self, prim: dict, where: str) -> dict:
        mode = prim.get("mode", 4)
        if mode not in MODES:
            raise _err(f"{where}.mode", f"{mode!r} is not a glTF primitive mode")
        if mode not in (4, 5, 6):
            raise _err(f"{where}.mode", f"{MODES[mode]}: only triangles (4, and strips 5 / fans 6) can be drawn")
        attrs = prim.get("attributes")
        if not isinstance(attrs, dict) or "POSITION" not in attrs:
            raise _err(f"{where}.attributes", "needs POSITION")
        draco = (prim.get("extensions") or {}).get(DRACO)
        decoded, draco_idx = self._draco(draco, f"{where}.extensions.{DRACO}") if draco is not None else ({}, None)

        def attribute(name: str) -> np.ndarray:
            if name in decoded:
                return self._draco_values(attrs[name], decoded[name], f"{where}.attributes.{name}")
            return self.accessor(attrs[name], f"{where}.attributes.{name}")

        pos = attribute("POSITION")
        if pos.shape[1] != 3:
            raise _err(f"{where}.attributes.POSITION", "must be VEC3")
        v = len(pos)
        if draco_idx is not None:
            idx = draco_idx
        elif "indices" in prim:
            idx = self.accessor(prim["indices"], f"{where}.indices")
            if idx.shape[1] != 1 or idx.dtype != np.int64:
                raise _err(f"{where}.indices", "must be an unsigned int SCALAR accessor")
            idx = idx[:, 0]
            if len(idx) and (idx.min() < 0 or idx.max() >= v):
                raise _err(f"{where}.indices", f"index {int(idx.max())} out of range: POSITION has {v} vertices")
        else:
            idx = np.arange(v)
        faces = _triangles(idx, mode, where)
        out = {"position": pos, "faces": faces, "uv": None, "normal": None, "tangent": None,
               "material": prim.get("material"), "needs_tangent": True, "where": where}
        out["uv1"] = None
        for key, name, width in (("normal", "NORMAL", 3), ("tangent", "TANGENT", 4), ("uv", "TEXCOORD_0", 2),
                                 ("uv1", "TEXCOORD_1", 2)):
            if name in attrs:
                a = attribute(name)
                if a.shape != (v, width):
                    raise _err(f"{where}.attributes.{name}", f"must be {v} elements of {width} components "
                               f"(POSITION's count), got {list(a.shape)}")
                out[key] = a.astype(np.float64)
        if out["material"] is not None:
            self._item("materials", out["material"], f"{where}.material")
        if out["normal"] is None:   # the spec: flat normals; a vertex per face corner
            out = _flat(out)
        return out

    def _draco(self, ext, where: str) -> tuple[dict, np.ndarray]:
        if not isinstance(ext, dict):
            raise _err(where, "must be an object")
        data, _ = self.view(ext.get("bufferView"), f"{where}.bufferView")
        try:
            return draco_attributes(data, ext, where)
        except CodecError as exc:
            raise _err(exc.where, exc.what) from None

    def _draco_values(self, index, values: np.ndarray, where: str) -> np.ndarray:
        """A Draco-decoded attribute as ``accessor`` returns it: its accessor gives count and width,
        and whether integers are normalised."""
        a = self._item("accessors", index, where)
        if a.get("componentType") not in COMPONENTS or a.get("type") not in WIDTHS:
            raise _err(f"accessors[{index}]", "not a glTF accessor layout")
        if values.shape != (a.get("count"), WIDTHS[a["type"]]):
            raise _err(where, f"the Draco bitstream holds {list(values.shape)} values; accessors[{index}] "
                       f"declares {a.get('count')} x {WIDTHS[a['type']]}")
        _, norm = COMPONENTS[a["componentType"]]
        if a.get("normalized") and norm is not None and values.dtype.kind in "iu":
            return np.maximum(values.astype(np.float64) / norm, -1.0)
        return values.astype(np.float64 if values.dtype.kind == "f" else np.int64)


def _floats(value, n: int, where: str) -> tuple:
    if not isinstance(value, (list, tuple)) or len(value) != n or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value):
        raise _err(where, f"must be {n} numbers, got {value!r}")
    return tuple(float(x) for x in value)


def _unit(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= value <= 1.0:
        raise _err(where, f"must be a number in [0, 1], got {value!r}")
    return float(value)


def texture_transform(offset, rotation: float, scale) -> np.ndarray:
    """KHR_texture_transform's matrix: translation * rotation * scale, on glTF uv (the spec's order)."""
    c, s = math.cos(rotation), math.sin(rotation)
    t = np.array([[1.0, 0.0, offset[0]], [0.0, 1.0, offset[1]], [0.0, 0.0, 1.0]])
    r = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    sc = np.diag([scale[0], scale[1], 1.0])
    return t @ r @ sc


def _node_matrix(node: dict, where: str) -> np.ndarray:
    if "matrix" in node:
        m = np.array(_floats(node["matrix"], 16, f"{where}.matrix")).reshape(4, 4).T   # column-major
        return m
    t = _floats(node.get("translation", (0.0, 0.0, 0.0)), 3, f"{where}.translation")
    r = _floats(node.get("rotation", (0.0, 0.0, 0.0, 1.0)), 4, f"{where}.rotation")
    s = _floats(node.get("scale", (1.0, 1.0, 1.0)), 3, f"{where}.scale")
    return _trs(t, r, s)


def _trs(t, r, s) -> np.ndarray:
    x, y, z, w = (float(c) for c in r)
    norm = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = rot * np.asarray(s, np.float64)[None, :]
    m[:3, 3] = t
    return m


def _triangles(idx: np.ndarray, mode: int, where: str) -> np.ndarray:
    if mode == 4:
        if len(idx) % 3:
            raise _err(f"{where}.indices", f"{len(idx)} indices: triangles need a multiple of 3")
        return idx.reshape(-1, 3)
    if len(idx) < 3:
        raise _err(f"{where}.indices", f"{len(idx)} indices: a strip or fan needs at least 3")
    k = np.arange(len(idx) - 2)
    if mode == 5:   # strip: every other triangle swaps its first two corners to keep the winding
        even = k % 2 == 0
        return np.stack([np.where(even, idx[k], idx[k + 1]), np.where(even, idx[k + 1], idx[k]), idx[k + 2]], 1)
    return np.stack([np.full_like(k, idx[0]), idx[k + 1], idx[k + 2]], 1)


def _flat(p: dict) -> dict:
    corner = p["faces"].reshape(-1)
    out = dict(p)
    for key in ("position", "uv", "uv1", "tangent"):
        if p[key] is not None:
            out[key] = p[key][corner]
    v = out["position"]
    f = np.arange(len(corner)).reshape(-1, 3)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    out["normal"] = np.repeat(n, 3, axis=0)
    out["faces"] = f
    return out


def _transformed(p: dict, m: np.ndarray) -> dict:
    out = dict(p)
    lin = m[:3, :3]
    out["position"] = p["position"] @ lin.T + m[:3, 3]
    normal_m = np.linalg.inv(lin).T
    n = p["normal"] @ normal_m.T
    out["normal"] = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    if p["tangent"] is not None:
        t = p["tangent"][:, :3] @ lin.T
        t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
        flip = -1.0 if np.linalg.det(lin) < 0 else 1.0
        out["tangent"] = np.concatenate([t, p["tangent"][:, 3:] * flip], 1)
    if np.linalg.det(lin) < 0:
        out["faces"] = p["faces"][:, ::-1]
    return out


def mikktspace_tangents(v: np.ndarray, n: np.ndarray, uv_gltf: np.ndarray, f: np.ndarray) -> np.ndarray:
    """[V, 4] tangents as MikkTSpace makes them (the spec's rule where a file has none): corners
    with equal position, normal and uv share one; each face's uv-gradient tangent, projected into
    the corner's normal plane and normalised, weighted by the corner's angle in that plane; w from
    the bitangent's side, negated for glTF's v-down uv (as three.js does for glTF).
    Checked against the reference MikkTSpace (npm ``mikktspace``) in tests/test_gltf.py."""
    key = np.concatenate([v, n, uv_gltf], 1)
    _, group, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    g = inverse[f]
    e1, e2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]
    d1, d2 = uv_gltf[f[:, 1]] - uv_gltf[f[:, 0]], uv_gltf[f[:, 2]] - uv_gltf[f[:, 0]]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    sign = np.sign(det)[:, None]
    t_face = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * sign
    b_face = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * sign
    t = np.zeros((len(group), 3))
    b = np.zeros((len(group), 3))
    for c in range(3):
        nc = n[f[:, c]]
        a, q = v[f[:, (c + 1) % 3]] - v[f[:, c]], v[f[:, (c + 2) % 3]] - v[f[:, c]]
        a -= nc * np.sum(nc * a, 1, keepdims=True)
        q -= nc * np.sum(nc * q, 1, keepdims=True)
        cos = np.sum(a * q, 1) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(q, axis=1), 1e-300)
        angle = np.arccos(np.clip(cos, -1.0, 1.0))[:, None]
        tc = t_face - nc * np.sum(nc * t_face, 1, keepdims=True)
        tc /= np.maximum(np.linalg.norm(tc, axis=1, keepdims=True), 1e-300)
        np.add.at(t, g[:, c], tc * angle)
        np.add.at(b, g[:, c], b_face * np.abs(det)[:, None])
    ng = n[group]
    length = np.linalg.norm(t, axis=1, keepdims=True)
    fallback = np.cross(ng, np.where(np.abs(ng[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]))
    t = np.where(length > 1e-12, t / np.maximum(length, 1e-300),
                 fallback / np.linalg.norm(fallback, axis=1, keepdims=True))
    w = np.where(np.sum(np.cross(ng, t) * b, 1) < 0.0, 1.0, -1.0)
    return np.concatenate([t, w[:, None]], 1)[inverse]


# colour and conversion helpers ---------------------------------------------------------------------
def srgb_to_linear(c):
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c):
    c = np.clip(np.asarray(c, np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055)


def _to8(x) -> np.ndarray:
    return np.clip(np.rint(np.asarray(x, np.float64) * 255.0), 0, 255).astype(np.uint8)


def _resized(image: np.ndarray, shape) -> np.ndarray:
    if image.shape[:2] == tuple(shape):
        return image
    from PIL import Image

    return np.asarray(Image.fromarray(image).resize((shape[1], shape[0]), Image.Resampling.BILINEAR), np.uint8)


def specular_glossiness_to_metallic(diffuse: np.ndarray, specular: np.ndarray, eps: float = 1e-6):
    """(base colour [N, 3], metallic [N]) from linear diffuse and specular [N, 3]: the metallic
    solve of the Khronos glTF converters (perceived brightness; dielectric F0 = 0.04)."""
    def brightness(c):
        return np.sqrt(0.299 * c[:, 0] ** 2 + 0.587 * c[:, 1] ** 2 + 0.114 * c[:, 2] ** 2)

    f0 = 0.04
    one_minus = 1.0 - specular.max(1)
    pd, ps = brightness(diffuse), brightness(specular)
    b = pd * one_minus / (1.0 - f0) + ps - 2.0 * f0
    c = f0 - ps
    metallic = np.where(ps < f0, 0.0, np.clip((-b + np.sqrt(np.maximum(b * b - 4 * f0 * c, 0.0))) / (2 * f0), 0, 1))
    from_diffuse = diffuse * (one_minus / (1.0 - f0) / np.maximum(1.0 - metallic, eps))[:, None]
    from_specular = (specular - f0 * (1.0 - metallic)[:, None]) / np.maximum(metallic, eps)[:, None]
    t = (metallic ** 2)[:, None]
    return np.clip(from_diffuse * (1 - t) + from_specular * t, 0.0, 1.0), metallic
