"""glTF 2.0 out: ``GltfBuilder`` assembles meshes, materials, PNG textures and a node tree and writes
one self-contained ``.glb``, or a ``.gltf`` with its ``.bin`` beside it (atomically, byte-identical
for the same input).

    b = GltfBuilder()
    tex = b.texture(b.image(rgba_uint8))
    mat = b.material({"pbrMetallicRoughness": {"baseColorTexture": {"index": tex}}})
    b.node(mesh=b.mesh([Primitive(vertices, faces, uv=uv, material=mat)]))
    b.write("out.glb")

``add_material`` writes a material the reader returned (``geometry.gltf.Material``) back as JSON, its
texture transforms as KHR_texture_transform.

Texture coordinates are given in the project's convention (v up, ``geometry/gltf.py``) and stored
as glTF's (v down). Accessors carry min/max where the spec asks (POSITION) and every bufferView is
4-byte aligned, so what is written passes the Khronos validator. numpy + Pillow; no torch.
"""
from __future__ import annotations

import io
import json
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.files import atomic_files, atomic_write

from .gltf import GLB_BIN, GLB_JSON, GLB_MAGIC, gltf_uv

ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
WRAP_CODES = {"repeat": 10497, "clamp": 33071, "mirror": 33648}
LINEAR, LINEAR_MIPMAP_LINEAR = 9729, 9987


@dataclass
class Primitive:
    """One triangle list: vertices [V, 3], faces [F, 3] (counter-clockwise), optional unit normals,
    uv (v up), tangents [V, 4], a material index and a second uv set (TEXCOORD_1, v up)."""
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    uv: np.ndarray | None = None
    tangents: np.ndarray | None = None
    material: int | None = None
    uv1: np.ndarray | None = None


class GltfBuilder:
    def __init__(self, generator: str = "inshade", *, draco: bool = False, meshopt: bool = False,
                 textures: str = "png"):
        """``draco``: meshes as KHR_draco_mesh_compression bitstreams; ``meshopt``: their vertex and
        index views as EXT_meshopt_compression streams (lossless; a fallback buffer without data);
        ``textures``: "png", or "ktx2" (KHR_texture_basisu, UASTC). They need the gltf extra's encoders
        (geometry/gltf_codecs.py)."""
        if draco and meshopt:
            raise ValueError("draco and meshopt: a mesh is compressed by one of them")
        self.meshopt = bool(meshopt)
        self.fallback = 0        # bytes of the meshopt views as decoded (buffer 1, no data)
        self.doc: dict = {"asset": {"version": "2.0", "generator": generator}}
        self.data = bytearray()
        self.used: set[str] = set()
        self.required: set[str] = set()
        self.roots: list[int] = []
        self.draco = bool(draco)
        self.textures = textures
        self.sources: dict[int, str] = {}   # image -> the extension a texture names it through

    def _add(self, key: str, item: dict) -> int:
        self.doc.setdefault(key, []).append(item)
        return len(self.doc[key]) - 1

    def _view(self, payload: bytes, target: int | None = None) -> int:
        self.data += b"\0" * (-len(self.data) % 4)
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(payload)}
        if target is not None:
            view["target"] = target
        self.data += payload
        return self._add("bufferViews", view)

    def accessor(self, array: np.ndarray, kind: str, *, target: int | None = ARRAY_BUFFER,
                 bounds: bool = False) -> int:
        """A float32 (or uint32 for SCALAR indices) accessor of ``array`` [N, k]."""
        a = np.asarray(array)
        integer = np.issubdtype(a.dtype, np.integer)
        a = np.ascontiguousarray(a, np.uint32 if integer else np.float32)
        packed = self.meshopt and target in (ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER)
        view = self._meshopt_view(a, target) if packed else self._view(a.tobytes(), target)
        acc = {"bufferView": view, "componentType": 5125 if integer else 5126, "count": int(a.shape[0]), "type": kind}
        if bounds:
            flat = a.reshape(len(a), -1)
            acc["min"] = [float(x) for x in flat.min(0)]
            acc["max"] = [float(x) for x in flat.max(0)]
        return self._add("accessors", acc)

    def _meshopt_view(self, a: np.ndarray, target: int) -> int:
        """A bufferView whose bytes are meshopt's vertex (ATTRIBUTES) or index (TRIANGLES) stream of
        ``a``, decoded into the fallback buffer's range it names."""
        from .gltf_codecs import MESHOPT, meshopt_encode

        indices = target == ELEMENT_ARRAY_BUFFER
        payload, stride = meshopt_encode(a, indices)
        self.data += b"\0" * (-len(self.data) % 4)
        ext = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(payload), "byteStride": stride,
               "count": int(a.size if indices else a.shape[0]), "mode": "TRIANGLES" if indices else "ATTRIBUTES"}
        self.data += payload
        view = {"buffer": 1, "byteOffset": self.fallback, "byteLength": int(a.nbytes), "target": target,
                "extensions": {MESHOPT[0]: ext}}
        if not indices:
            view["byteStride"] = stride
        self.fallback += int(a.nbytes) + (-int(a.nbytes) % 4)
        self.use(MESHOPT[0], required=True)
        return self._add("bufferViews", view)

    def use(self, extension: str, required: bool = False) -> None:
        self.used.add(extension)
        if required:
            self.required.add(extension)

    def image(self, rgba: np.ndarray, colour: bool = True) -> int:
        """A PNG image of ``rgba`` [H, W, 3|4] uint8 (row 0 = the top, glTF's v = 0), or a KTX2 one
        (sRGB where ``colour``, else linear) when the builder writes KTX2 textures."""
        from PIL import Image

        if self.textures == "ktx2":
            from .gltf_codecs import BASISU, ktx2_encode

            rgba = np.asarray(rgba, np.uint8)
            if rgba.shape[2] == 3:
                rgba = np.dstack([rgba, np.full(rgba.shape[:2], 255, np.uint8)])
            index = self.encoded_image(ktx2_encode(rgba, colour), "image/ktx2")
            self.sources[index] = BASISU
            return index
        buf = io.BytesIO()
        Image.fromarray(np.ascontiguousarray(rgba, np.uint8)).save(buf, format="PNG", optimize=False,
                                                                    compress_level=6)
        return self._add("images", {"bufferView": self._view(buf.getvalue()), "mimeType": "image/png"})

    def encoded_image(self, payload: bytes, mime: str) -> int:
        """An image already encoded (e.g. ``image/ktx2``, ``image/webp``), stored as it is."""
        return self._add("images", {"bufferView": self._view(bytes(payload)), "mimeType": mime})

    def texture(self, image: int, wrap: tuple[str, str] = ("repeat", "repeat"), mipmaps: bool = True,
                extension: str | None = None) -> int:
        """``extension``: the image is that extension's source (KHR_texture_basisu, EXT_texture_webp),
        required, with no core fallback (a KTX2 image the builder encoded is one by itself)."""
        extension = self.sources.get(image, extension)
        sampler = self._add("samplers", {"magFilter": LINEAR,
                                         "minFilter": LINEAR_MIPMAP_LINEAR if mipmaps else LINEAR,
                                         "wrapS": WRAP_CODES[wrap[0]], "wrapT": WRAP_CODES[wrap[1]]})
        if extension is None:
            return self._add("textures", {"source": image, "sampler": sampler})
        self.use(extension, required=True)
        return self._add("textures", {"sampler": sampler, "extensions": {extension: {"source": image}}})

    def material(self, spec: dict) -> int:
        """A material as glTF JSON; the extensions it names are declared used."""
        for ext in (spec.get("extensions") or {}):
            self.use(ext)
        for info in _texture_infos(spec):
            for ext in (info.get("extensions") or {}):
                self.use(ext)
        return self._add("materials", spec)

    def mesh(self, primitives: list[Primitive], name: str = "") -> int:
        prims = []
        for p in primitives:
            if self.draco:
                prims.append(self._draco_primitive(p))
                continue
            v = np.asarray(p.vertices, np.float64)
            attrs = {"POSITION": self.accessor(v, "VEC3", bounds=True)}
            if p.normals is not None:
                n = np.asarray(p.normals, np.float64)
                attrs["NORMAL"] = self.accessor(n / np.linalg.norm(n, axis=1, keepdims=True), "VEC3")
            if p.tangents is not None:
                attrs["TANGENT"] = self.accessor(p.tangents, "VEC4")
            for name, uv in (("TEXCOORD_0", p.uv), ("TEXCOORD_1", p.uv1)):
                if uv is not None:
                    attrs[name] = self.accessor(gltf_uv(uv), "VEC2")
            prim = {"attributes": attrs, "indices": self.accessor(np.asarray(p.faces).reshape(-1, 1), "SCALAR",
                                                                   target=ELEMENT_ARRAY_BUFFER),
                    "mode": 4}
            if p.material is not None:
                prim["material"] = int(p.material)
            prims.append(prim)
        return self._add("meshes", {"name": name, "primitives": prims} if name else {"primitives": prims})

    def _draco_primitive(self, p: Primitive) -> dict:
        """A primitive whose attributes and indices are one Draco bitstream: its accessors hold no
        data, only what the decoded values are (count, type; POSITION's bounds as decoded)."""
        from .gltf_codecs import DRACO, draco_encode

        if p.uv1 is not None:
            raise ValueError("a second uv set is not written into Draco bitstreams here")

        n = None if p.normals is None else np.asarray(p.normals, np.float64)
        payload, decoded = draco_encode(p.vertices, p.faces, None if n is None else n / np.linalg.norm(n, axis=1,
                                                                                                      keepdims=True),
                                        None if p.uv is None else gltf_uv(p.uv), p.tangents)
        attrs, ids = {}, {}
        for name, (uid, values) in decoded.items():
            acc = {"componentType": 5126, "count": len(values), "type": f"VEC{values.shape[1]}"}
            if name == "POSITION":
                acc["min"] = [float(x) for x in values.min(0)]
                acc["max"] = [float(x) for x in values.max(0)]
            attrs[name], ids[name] = self._add("accessors", acc), uid
        indices = self._add("accessors", {"componentType": 5125, "count": int(np.asarray(p.faces).size),
                                          "type": "SCALAR"})
        self.use(DRACO, required=True)
        prim = {"attributes": attrs, "indices": indices, "mode": 4,
                "extensions": {DRACO: {"bufferView": self._view(payload), "attributes": ids}}}
        if p.material is not None:
            prim["material"] = int(p.material)
        return prim

    def node(self, mesh: int | None = None, *, translation=None, rotation=None, scale=None, matrix=None,
             children=(), instances: dict | None = None, root: bool = True, name: str = "") -> int:
        """A node; ``instances`` = {"TRANSLATION": [N, 3], "ROTATION": [N, 4], "SCALE": [N, 3]}
        draws the mesh N times (EXT_mesh_gpu_instancing). Root nodes join the scene."""
        node: dict = {}
        if name:
            node["name"] = name
        if mesh is not None:
            node["mesh"] = mesh
        for key, value in (("translation", translation), ("rotation", rotation), ("scale", scale)):
            if value is not None:
                node[key] = [float(x) for x in value]
        if matrix is not None:
            node["matrix"] = [float(x) for x in np.asarray(matrix, np.float64).T.reshape(-1)]
        if children:
            node["children"] = [int(c) for c in children]
        if instances:
            self.use("EXT_mesh_gpu_instancing")
            node["extensions"] = {"EXT_mesh_gpu_instancing": {"attributes": {
                k: self.accessor(np.asarray(v, np.float64), "VEC4" if k == "ROTATION" else "VEC3", target=None)
                for k, v in instances.items()}}}
        index = self._add("nodes", node)
        if root:
            self.roots.append(index)
        return index

    def document(self, buffer_uri: str | None = None) -> dict:
        """The glTF JSON; ``buffer_uri`` names the binary buffer's file (None: a GLB's own chunk)."""
        doc = dict(self.doc)
        doc["scene"] = 0
        doc["scenes"] = [{"nodes": self.roots}]
        if self.used:
            doc["extensionsUsed"] = sorted(self.used)
        if self.required:
            doc["extensionsRequired"] = sorted(self.required)
        if self.data:
            doc["buffers"] = [{"byteLength": len(self.data) + (-len(self.data) % 4)}]
            if buffer_uri is not None:
                doc["buffers"][0]["uri"] = buffer_uri
        if self.fallback:   # what the meshopt views decode into: no data, readers decode instead
            doc["buffers"].append({"byteLength": self.fallback,
                                   "extensions": {"EXT_meshopt_compression": {"fallback": True}}})
        return doc

    def glb(self) -> bytes:
        data = bytes(self.data) + b"\0" * (-len(self.data) % 4)
        text = json.dumps(self.document(), separators=(",", ":"), sort_keys=True).encode()
        text += b" " * (-len(text) % 4)
        chunks = struct.pack("<II", len(text), GLB_JSON) + text
        if data:
            chunks += struct.pack("<II", len(data), GLB_BIN) + data
        return struct.pack("<III", GLB_MAGIC, 2, 12 + len(chunks)) + chunks

    def write(self, path) -> Path:
        """``.glb``: one binary file; ``.gltf``: the JSON and its buffer beside it (``NAME.bin``)."""
        path = Path(path)
        if path.suffix.lower() != ".gltf":
            return atomic_write(path, self.glb())
        data = bytes(self.data) + b"\0" * (-len(self.data) % 4)
        binary = path.with_suffix(".bin")
        with atomic_files(binary, path) as (bin_tmp, json_tmp):
            bin_tmp.write_bytes(data)
            json_tmp.write_text(json.dumps(self.document(binary.name), indent=1, sort_keys=True))
        return path


def _texture_infos(spec: dict):
    """Every textureInfo object in a material's JSON (to declare the extensions they use)."""
    if isinstance(spec, dict):
        if "index" in spec and isinstance(spec.get("index"), int):
            yield spec
        for v in spec.values():
            yield from _texture_infos(v)


def transform_extension(matrix: np.ndarray) -> dict | None:
    """KHR_texture_transform's {offset, rotation, scale} of a 3x3 uv matrix T * R * S (None for the identity)."""
    m = np.asarray(matrix, np.float64)
    if np.allclose(m, np.eye(3), atol=1e-12):
        return None
    sx, sy = float(np.hypot(m[0, 0], m[1, 0])), float(np.hypot(m[0, 1], m[1, 1]))
    return {"offset": [float(m[0, 2]), float(m[1, 2])], "rotation": float(np.arctan2(-m[1, 0], m[0, 0])),
            "scale": [sx, sy]}


# Material fields -> (glTF JSON path, key of the slot's scalar in its textureInfo)
_SLOTS = {
    "base_color_texture": (("pbrMetallicRoughness", "baseColorTexture"), None),
    "metallic_roughness_texture": (("pbrMetallicRoughness", "metallicRoughnessTexture"), None),
    "normal_texture": (("normalTexture",), "scale"),
    "occlusion_texture": (("occlusionTexture",), "strength"),
    "emissive_texture": (("emissiveTexture",), None),
    "clearcoat_texture": (("extensions", "KHR_materials_clearcoat", "clearcoatTexture"), None),
    "clearcoat_roughness_texture": (("extensions", "KHR_materials_clearcoat", "clearcoatRoughnessTexture"), None),
    "clearcoat_normal_texture": (("extensions", "KHR_materials_clearcoat", "clearcoatNormalTexture"), "scale"),
    "sheen_color_texture": (("extensions", "KHR_materials_sheen", "sheenColorTexture"), None),
    "sheen_roughness_texture": (("extensions", "KHR_materials_sheen", "sheenRoughnessTexture"), None),
    "anisotropy_texture": (("extensions", "KHR_materials_anisotropy", "anisotropyTexture"), None),
}


COLOUR_TEXTURES = ("base_color_texture", "emissive_texture", "sheen_color_texture")   # sRGB-encoded slots


def add_material(builder: GltfBuilder, material, images: list, image_index: dict) -> int:
    """Add a ``geometry.gltf.Material`` (a converted one comes out metallic-roughness) and return its
    index; its images (``images`` of the asset it came from) are added once each per use as colour or
    data (``image_index`` maps (the asset's image index, colour) to the builder's)."""
    m = material
    spec: dict = {"name": m.name, "pbrMetallicRoughness": {"baseColorFactor": list(m.base_color),
                                                          "metallicFactor": m.metallic, "roughnessFactor": m.roughness}}
    if any(m.emissive):
        strength = max(m.emissive)
        factor = [c / strength for c in m.emissive] if strength > 1.0 else list(m.emissive)
        spec["emissiveFactor"] = factor
        if strength > 1.0:
            spec.setdefault("extensions", {})["KHR_materials_emissive_strength"] = {"emissiveStrength": strength}
    if m.alpha_mode != "OPAQUE":
        spec["alphaMode"] = m.alpha_mode
        if m.alpha_mode == "MASK":
            spec["alphaCutoff"] = m.alpha_cutoff
    if m.double_sided:
        spec["doubleSided"] = True
    ext = spec.setdefault("extensions", {})
    if m.ior != 1.5:
        ext["KHR_materials_ior"] = {"ior": m.ior}
    if m.clearcoat > 0 or m.clearcoat_texture is not None:
        ext["KHR_materials_clearcoat"] = {"clearcoatFactor": m.clearcoat, "clearcoatRoughnessFactor": m.clearcoat_roughness}
    if any(m.sheen_color) or m.sheen_color_texture is not None:
        ext["KHR_materials_sheen"] = {"sheenColorFactor": list(m.sheen_color), "sheenRoughnessFactor": m.sheen_roughness}
    if m.anisotropy_strength > 0 or m.anisotropy_texture is not None:
        ext["KHR_materials_anisotropy"] = {"anisotropyStrength": m.anisotropy_strength,
                                           "anisotropyRotation": m.anisotropy_rotation}
    for field_name, (path, scalar) in _SLOTS.items():
        ref = getattr(m, field_name)
        if ref is None:
            continue
        key = (ref.image, field_name in COLOUR_TEXTURES)   # a KTX2 image says whether it is sRGB
        if key not in image_index:
            image_index[key] = builder.image(images[ref.image], colour=key[1])
        info: dict = {"index": builder.texture(image_index[key], ref.wrap)}
        if scalar is not None and ref.scale != 1.0:
            info[scalar] = ref.scale
        transform = transform_extension(ref.transform)
        if transform is not None:
            info["extensions"] = {"KHR_texture_transform": transform}
        target = spec
        for key in path[:-1]:
            target = target.setdefault(key, {})
        target[path[-1]] = info
    if not ext:
        del spec["extensions"]
    return builder.material(spec)
