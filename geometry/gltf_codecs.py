"""The compression extensions real glTF files ship with, decoded by their maintained libraries:

- ``KHR_draco_mesh_compression`` (a primitive's attributes and indices in one Draco bitstream):
  PyPI ``DracoPy`` (Google's Draco); the primitive's accessors give count, type and component type,
  the extension maps each attribute to its Draco attribute id.
- ``EXT_meshopt_compression`` / ``KHR_meshopt_compression`` (a bufferView encoded by
  meshoptimizer's vertex / index codecs, with an optional octahedral / quaternion / exponential
  filter): PyPI ``meshoptimizer``; the view's bytes come back as if they had never been compressed.
- ``KHR_texture_basisu`` (KTX2 images with Basis Universal ETC1S or UASTC payloads): transcoded to
  RGBA8 by Binomial's basisu through PyPI ``alktx2``; level 0 is read (the renderer builds its own
  mip chain, as for PNG and JPEG).

Both are the optional ``gltf`` extra; a file that needs one when it is missing gets one line naming
the extension and the install. Decoded data is what the same libraries give other readers
(tests/geometry/test_gltf_codecs.py compares with glTF Transform's decode, bit for bit).
"""
from __future__ import annotations

import numpy as np

DRACO = "KHR_draco_mesh_compression"
MESHOPT = ("EXT_meshopt_compression", "KHR_meshopt_compression")
BASISU = "KHR_texture_basisu"
EXTENSIONS = (DRACO, *MESHOPT, BASISU)
KTX2_MAGIC = b"\xabKTX 20\xbb\r\n\x1a\n"
MESHOPT_MODES = ("ATTRIBUTES", "TRIANGLES", "INDICES")
MESHOPT_FILTERS = {"NONE": None, "OCTAHEDRAL": "decode_filter_oct", "QUATERNION": "decode_filter_quat",
                   "EXPONENTIAL": "decode_filter_exp"}


class CodecError(ValueError):
    """(field, problem): the reader turns it into its FILE: FIELD: problem line."""

    def __init__(self, where: str, what: str):
        super().__init__(where, what)
        self.where, self.what = where, what


def _library(module: str, distribution: str, extension: str, where: str):
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise CodecError(where, f"{extension} needs {distribution}, which is not installed: "
                                "pip install 'inshade[gltf]'") from None


def draco_attributes(data: bytes, ext: dict, where: str) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """({semantic: values [count, width] as Draco decodes them}, triangle indices [3F]) of a
    primitive's ``KHR_draco_mesh_compression`` bitstream."""
    draco = _library("DracoPy", "DracoPy", DRACO, where)
    ids = ext.get("attributes")
    if not isinstance(ids, dict) or not all(isinstance(v, int) and not isinstance(v, bool) for v in ids.values()):
        raise CodecError(f"{where}.attributes", "must map attribute names to Draco attribute ids")
    try:
        mesh = draco.decode(data)
    except Exception as exc:   # the decoder's own failure types: a bad bitstream is the file's problem
        raise CodecError(where, f"cannot decode the Draco bitstream ({exc})") from None
    faces = getattr(mesh, "faces", None)
    if faces is None or not len(faces):
        raise CodecError(where, "the Draco bitstream is a point cloud: only triangle meshes can be drawn")
    out = {}
    for name, uid in ids.items():
        attribute = mesh.get_attribute_by_unique_id(uid)
        if attribute is None:
            raise CodecError(f"{where}.attributes.{name}", f"no Draco attribute with id {uid} in the bitstream")
        out[name] = np.asarray(attribute["data"]).reshape(len(attribute["data"]), -1)
    return out, np.asarray(faces, np.int64).reshape(-1)


def meshopt_view(data: bytes, ext: dict, where: str) -> bytes:
    """The bytes of a bufferView compressed with meshopt (``data``: the compressed range)."""
    meshopt = _library("meshoptimizer", "meshoptimizer", "EXT_meshopt_compression", where)
    count, stride = ext.get("count"), ext.get("byteStride")
    mode, filter_ = ext.get("mode"), ext.get("filter", "NONE")
    if not isinstance(count, int) or count < 1 or not isinstance(stride, int) or stride < 1:
        raise CodecError(where, f"count {count!r} / byteStride {stride!r}: must be ints >= 1")
    if mode not in MESHOPT_MODES:
        raise CodecError(f"{where}.mode", f"{mode!r} is not one of {', '.join(MESHOPT_MODES)}")
    if filter_ not in MESHOPT_FILTERS:
        raise CodecError(f"{where}.filter", f"{filter_!r} is not one of {', '.join(MESHOPT_FILTERS)}")
    # the wrapper's default forms only: its dtype= form allocates count elements, not count x stride bytes;
    # its index decoders fill the first count x stride bytes of a uint32 array
    try:
        if mode == "ATTRIBUTES":
            out = np.ascontiguousarray(meshopt.decode_vertex_buffer(count, stride, data)).view(np.uint8)
            if MESHOPT_FILTERS[filter_] is not None:
                out = np.ascontiguousarray(getattr(meshopt, MESHOPT_FILTERS[filter_])(out, count, stride))
        elif filter_ != "NONE":
            raise CodecError(f"{where}.filter", f"{filter_}: filters apply to ATTRIBUTES only")
        elif mode == "TRIANGLES":
            out = meshopt.decode_index_buffer(count, stride, data)
        else:
            out = meshopt.decode_index_sequence(count, stride, data)
    except (ValueError, RuntimeError) as exc:
        raise CodecError(where, f"cannot decode the meshopt {mode.lower()} data ({exc})") from None
    raw = np.ascontiguousarray(out).tobytes()[:count * stride]
    if len(raw) != count * stride:
        raise CodecError(where, f"decoded {len(raw)} bytes, expected count x byteStride = {count * stride}")
    return raw


def ktx2_rgba(data: bytes, where: str) -> np.ndarray:
    """A KTX2 image's level 0 as RGBA8 [H, W, 4], row 0 = the top (glTF's v = 0)."""
    import io

    from PIL import Image

    ktx2 = _library("alktx2", "alktx2", BASISU, where)
    try:
        png, _ = ktx2.decode_ktx2_to_bytes(bytes(data), format="png", level=0)
    except (ValueError, RuntimeError) as exc:
        raise CodecError(where, f"cannot transcode the KTX2 image ({exc})") from None
    with Image.open(io.BytesIO(png)) as image:
        return np.asarray(image.convert("RGBA"), np.uint8)


# --- writing ---------------------------------------------------------------------------------------

# Draco attribute types (draco::GeometryAttribute::Type) -> the glTF semantic it holds
DRACO_SEMANTICS = {0: "POSITION", 1: "NORMAL", 3: "TEXCOORD_0", 4: "TANGENT"}
# bits per component, as glTF Transform's defaults: positions 14, normals 10, uv 12 (tangents: generic, 12)
DRACO_BITS = {"quantization_bits": 14, "normal_quantization_bits": 10, "tex_coord_quantization_bits": 12}
TEXTURE_CODECS = ("png", "ktx2")
MESH_CODECS = ("none", "draco", "meshopt")


class EncoderMissing(ValueError):
    """A codec's library is not installed (the message names the install)."""


def _encoder(module: str, extension: str):
    try:
        return _library(module, module, extension, "")
    except CodecError as exc:
        raise EncoderMissing(exc.what) from None


def draco_encode(vertices, faces, normals=None, uv=None, tangents=None) -> tuple[bytes, dict[str, np.ndarray]]:
    """(the Draco bitstream of one triangle list, {semantic: the values it decodes to}) with vertex
    order kept (the accessors' counts are the input's); uv in glTF's convention."""
    draco = _encoder("DracoPy", DRACO)
    extra = {}
    if uv is not None:
        extra["tex_coord"] = np.asarray(uv, np.float64)
    if normals is not None:
        extra["normals"] = np.asarray(normals, np.float64)
    if tangents is not None:
        extra["generic_attributes"] = {0: np.asarray(tangents, np.float64)}
    payload = draco.encode(np.asarray(vertices, np.float64), np.asarray(faces, np.uint32).reshape(-1, 3),
                           compression_level=7, preserve_order=True, **DRACO_BITS, **extra)
    decoded = draco.decode(payload)
    out = {}
    for uid in range(1 + len(extra)):
        a = decoded.get_attribute_by_unique_id(uid)
        if a is not None:
            out[DRACO_SEMANTICS[a["attribute_type"]]] = (uid, np.asarray(a["data"], np.float32).reshape(
                len(a["data"]), -1))
    return payload, out


def meshopt_encode(a: np.ndarray, indices: bool) -> tuple[bytes, int]:
    """(meshopt's stream of ``a``, its byteStride): uint32 triangle indices [3F] (or [F, 3]), or
    vertices [N, k] of 4-byte components, one row a vertex; lossless."""
    meshopt = _encoder("meshoptimizer", MESHOPT[0])
    if indices:
        flat = np.ascontiguousarray(a, np.uint32).reshape(-1)
        return bytes(meshopt.encode_index_buffer(flat, len(flat), int(flat.max()) + 1)), 4
    rows = np.ascontiguousarray(a).reshape(len(a), -1)
    return bytes(meshopt.encode_vertex_buffer(rows, len(rows), rows.itemsize * rows.shape[1])), \
        rows.itemsize * rows.shape[1]


def ktx2_encode(rgba: np.ndarray, colour: bool) -> bytes:
    """A KTX2 file of ``rgba`` [H, W, 4] uint8 (UASTC, Basis Universal, through basisu), marked sRGB
    for colour images (base colour, emissive, sheen colour) and linear for data (normals, roughness...)."""
    alktx2 = _encoder("alktx2", BASISU)
    rgba = np.ascontiguousarray(rgba, np.uint8)
    return alktx2.encode_raw_rgba_to_ktx2(rgba.tobytes(), rgba.shape[1], rgba.shape[0], codec="uastc",
                                          srgb=bool(colour), linear=not colour, threads=1)
