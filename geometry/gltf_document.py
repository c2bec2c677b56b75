"""A glTF file as the reader sees it: the JSON document (``.gltf``, or a ``.glb``'s JSON chunk), its
buffers (files, data URIs, the GLB binary chunk; EXT_meshopt_compression views decoded), its
accessors as arrays and its images decoded to RGBA8 (PNG, JPEG, WebP with EXT_texture_webp, KTX2
with KHR_texture_basisu). ``GltfDocument`` also holds what a read accumulates: the notes and the
images in the order they are first used (a material's texture refers to them by that index).
"""
from __future__ import annotations

import base64
import io
import json
import struct
from pathlib import Path

import numpy as np

from .gltf_codecs import KTX2_MAGIC, MESHOPT, CodecError, ktx2_rgba, meshopt_view
from .gltf_types import COMPONENTS, GLB_BIN, GLB_JSON, GLB_MAGIC, IMAGE_FORMATS, SUPPORTED_EXTENSIONS, WIDTHS, \
    GltfError, field_error


class GltfDocument:
    """A parsed glTF file; every problem is a ``GltfError`` naming the field."""

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
        try:
            self.doc = json.loads(doc_bytes.decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as exc:
            raise GltfError(f"not glTF JSON ({exc})") from None
        if not isinstance(self.doc, dict):
            raise field_error("(top level)", "must be a JSON object")
        version = (self.doc.get("asset") or {}).get("version")
        if not isinstance(version, str) or not version.startswith("2."):
            raise field_error("asset.version", f"must be \"2.x\" (glTF 2.0), got {version!r}")
        required = self.entries("extensionsRequired")
        unknown = [e for e in required if e not in SUPPORTED_EXTENSIONS]
        if unknown:
            raise field_error("extensionsRequired", f"{', '.join(unknown)}: not supported (this reader knows "
                              f"{', '.join(SUPPORTED_EXTENSIONS)})")
        used = self.entries("extensionsUsed")
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
            raise field_error("GLB header", f"{len(raw)} bytes: shorter than a header and one chunk")
        _, version, length = struct.unpack_from("<III", raw, 0)
        if version != 2:
            raise field_error("GLB header", f"version {version}, expected 2")
        if length > len(raw):
            raise field_error("GLB header", f"declares {length} bytes, the file has {len(raw)}")
        offset, doc = 12, None
        while offset + 8 <= length:
            size, kind = struct.unpack_from("<II", raw, offset)
            body = raw[offset + 8: offset + 8 + size]
            if len(body) != size:
                raise field_error("GLB chunk", f"at byte {offset} declares {size} bytes past the end of the file")
            if kind == GLB_JSON and doc is None:
                doc = body
            elif kind == GLB_BIN and self.blob is None:
                self.blob = body
            offset += 8 + size + (-size % 4)
        if doc is None:
            raise field_error("GLB", "no JSON chunk")
        return doc

    def entries(self, key: str) -> list:
        """The top-level list ``key`` (absent: empty)."""
        value = self.doc.get(key, [])
        if not isinstance(value, list):
            raise field_error(key, "must be a list")
        return value

    def entry(self, key: str, index, where: str) -> dict:
        """``key[index]``, an object; ``where`` names the field that holds the index."""
        items = self.entries(key)
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(items):
            raise field_error(where, f"{index!r} is not an index into {key} (0..{len(items) - 1})")
        item = items[index]
        if not isinstance(item, dict):
            raise field_error(f"{key}[{index}]", "must be an object")
        return item

    def _uri(self, uri: str, where: str) -> bytes:
        if uri.startswith("data:"):
            head, _, data = uri.partition(",")
            if not head.endswith(";base64"):
                raise field_error(where, "a data URI must be base64")
            try:
                return base64.b64decode(data, validate=True)
            except ValueError as exc:
                raise field_error(where, f"bad base64 ({exc})") from None
        from urllib.parse import unquote

        file = (self.path.parent / unquote(uri))
        if not file.is_file():
            raise field_error(where, f"no file {file}")
        return file.read_bytes()

    def buffer(self, index: int, where: str) -> bytes:
        if index not in self._buffers:
            b = self.entry("buffers", index, where)
            w = f"buffers[{index}]"
            if "uri" in b:
                data = self._uri(b["uri"], f"{w}.uri")
            elif index == 0 and self.blob is not None:
                data = self.blob
            else:
                raise field_error(w, "no uri and no GLB binary chunk: the buffer's bytes are missing")
            length = b.get("byteLength")
            if not isinstance(length, int) or length < 1:
                raise field_error(f"{w}.byteLength", f"must be an int >= 1, got {length!r}")
            if len(data) < length:
                raise field_error(w, f"byteLength {length}, but its data has {len(data)} bytes")
            self._buffers[index] = data[:length]
        return self._buffers[index]

    def view(self, index: int, where: str) -> tuple[bytes, int | None]:
        v = self.entry("bufferViews", index, where)
        w = f"bufferViews[{index}]"
        packed = next(((name, e) for name, e in (v.get("extensions") or {}).items() if name in MESHOPT), None)
        if packed is not None:   # compressed: the view's bytes are decoded from the extension's range
            name, ext = packed
            return self._decoded_view(ext, f"{w}.extensions.{name}"), ext.get("byteStride")
        data = self.buffer(v.get("buffer"), f"{w}.buffer")
        offset, length = v.get("byteOffset", 0), v.get("byteLength")
        if not isinstance(length, int) or length < 1 or not isinstance(offset, int) or offset < 0:
            raise field_error(w, f"byteOffset {offset!r} / byteLength {length!r}: must be ints (offset >= 0, "
                              "length >= 1)")
        if offset + length > len(data):
            raise field_error(w, f"bytes {offset}..{offset + length} lie past the end of buffer "
                              f"{v.get('buffer')} ({len(data)} bytes)")
        return data[offset: offset + length], v.get("byteStride")

    def _decoded_view(self, ext, where: str) -> bytes:
        if not isinstance(ext, dict):
            raise field_error(where, "must be an object")
        data = self.buffer(ext.get("buffer"), f"{where}.buffer")
        offset, length = ext.get("byteOffset", 0), ext.get("byteLength")
        if not isinstance(length, int) or length < 1 or not isinstance(offset, int) or offset < 0 \
                or offset + length > len(data):
            raise field_error(where, f"byteOffset {offset!r} / byteLength {length!r}: not a range of buffer "
                              f"{ext.get('buffer')} ({len(data)} bytes)")
        try:
            return meshopt_view(data[offset: offset + length], ext, where)
        except CodecError as exc:
            raise field_error(exc.where, exc.what) from None

    def accessor(self, index, where: str) -> np.ndarray:
        """An accessor's elements as float64 (normalised ints scaled) or int64 [count, width]."""
        a = self.entry("accessors", index, where)
        w = f"accessors[{index}]"
        if a.get("componentType") not in COMPONENTS or a.get("type") not in WIDTHS:
            raise field_error(w, f"componentType {a.get('componentType')!r} / type {a.get('type')!r}: not a "
                              "glTF accessor layout")
        dtype, norm = COMPONENTS[a["componentType"]]
        width = WIDTHS[a["type"]]
        count = a.get("count")
        if not isinstance(count, int) or count < 1:
            raise field_error(f"{w}.count", f"must be an int >= 1, got {count!r}")
        item = np.dtype("<" + dtype)
        element = item.itemsize * width
        if "bufferView" in a:
            data, stride = self.view(a["bufferView"], f"{w}.bufferView")
            stride = stride or element
            offset = a.get("byteOffset", 0)
            end = offset + stride * (count - 1) + element
            if not isinstance(offset, int) or offset < 0 or end > len(data):
                raise field_error(w, f"{count} elements of {element} bytes (stride {stride}) from byte {offset} "
                                  f"need {end} bytes; bufferView {a['bufferView']} has {len(data)}")
            rows = np.lib.stride_tricks.as_strided(np.frombuffer(data, np.uint8, offset=offset),
                                                   shape=(count, element), strides=(stride, 1))
            values = np.ascontiguousarray(rows).view(item).reshape(count, width)
        else:
            values = np.zeros((count, width), item)
        values = values.astype(np.float64 if dtype == "f4" or a.get("normalized") else np.int64)
        if a.get("normalized"):
            if norm is None:
                raise field_error(f"{w}.normalized", f"{dtype} components cannot be normalised")
            values = np.maximum(values / norm, -1.0)
        if "sparse" in a:
            values = self._sparse(a["sparse"], values, item, width, norm if a.get("normalized") else None, w)
        if not np.isfinite(values).all():
            raise field_error(w, "holds NaN or infinite values")
        return values

    def _sparse(self, s, values, item, width, norm, w):
        n = s.get("count")
        if not isinstance(n, int) or n < 1:
            raise field_error(f"{w}.sparse.count", f"must be an int >= 1, got {n!r}")
        idx_dtype = COMPONENTS.get((s.get("indices") or {}).get("componentType"), (None,))[0]
        if idx_dtype not in ("u1", "u2", "u4"):
            raise field_error(f"{w}.sparse.indices.componentType", "must be an unsigned int type")
        data, _ = self.view(s["indices"].get("bufferView"), f"{w}.sparse.indices.bufferView")
        dt = np.dtype("<" + idx_dtype)
        start = s["indices"].get("byteOffset", 0)
        if start + n * dt.itemsize > len(data):
            raise field_error(f"{w}.sparse.indices", "reads past its bufferView")
        idx = np.frombuffer(data, dt, count=n, offset=start).astype(np.int64)
        if idx.max() >= len(values):
            raise field_error(f"{w}.sparse.indices", f"index {int(idx.max())} past the accessor's {len(values)} "
                              "elements")
        data, _ = self.view(s.get("values", {}).get("bufferView"), f"{w}.sparse.values.bufferView")
        start = s["values"].get("byteOffset", 0)
        if start + n * width * item.itemsize > len(data):
            raise field_error(f"{w}.sparse.values", "reads past its bufferView")
        sub = np.frombuffer(data, item, count=n * width, offset=start).reshape(n, width).astype(values.dtype)
        if norm is not None:
            sub = np.maximum(sub / norm, -1.0)
        values = values.copy()
        values[idx] = sub
        return values

    # images ------------------------------------------------------------------------------------
    def image(self, index, where: str) -> int:
        """``images[index]`` decoded once; its index into ``self.images``."""
        if index in self._images:
            return self._images[index]
        im = self.entry("images", index, where)
        w = f"images[{index}]"
        if "uri" in im:
            data = self._uri(im["uri"], f"{w}.uri")
        elif "bufferView" in im:
            data, _ = self.view(im["bufferView"], f"{w}.bufferView")
        else:
            raise field_error(w, "needs a uri or a bufferView")
        if data[:12] == KTX2_MAGIC and "KHR_texture_basisu" in self.extensions:
            try:
                array = ktx2_rgba(data, w)
            except CodecError as exc:
                raise field_error(exc.where, exc.what) from None
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
                    raise field_error(w, f"{pil.format} image: glTF images are PNG or JPEG (WebP with "
                                      "EXT_texture_webp, KTX2 with KHR_texture_basisu)")
                return np.asarray(pil.convert("RGBA"), np.uint8)
        except (UnidentifiedImageError, OSError) as exc:
            raise field_error(w, f"cannot decode ({exc})") from None
