"""glTF test assets made here (nothing is downloaded): procedural meshes and PBR textures written
through ``GltfBuilder``, covering what the reader must handle.

- ``tiles_torus``: a uv-mapped torus under a translated, rotated node, one material with every
  core texture (base colour, metallic-roughness, normal, occlusion, emissive), the normal and
  base-colour textures under ``KHR_texture_transform`` (scale, rotation, offset); authored
  tangents. The single-material asset the material-learning techniques train on.
- ``showcase``: node hierarchy with a mirrored (negative-scale) instance, the same mesh under two
  nodes, ``EXT_mesh_gpu_instancing``, a clearcoat material, an anisotropic brushed metal with a
  direction texture, a sheen fabric (normal-mapped, no tangents: generated), a ``KHR_materials_pbrSpecularGlossiness`` material, a primitive
  without normals (flat shading) and without a material.
- ``malformed(folder)``: a corpus the reader must refuse, each with one line (see ``MALFORMED``).

``python -m inshade.geometry.gltf_scenes OUT_FOLDER`` writes them all (byte-identical each run).
numpy + trimesh + Pillow; no torch.
"""
from __future__ import annotations

import json
import math
import struct
import sys
from pathlib import Path

import numpy as np

from inshade.files import atomic_write

from .gltf import GLB_BIN, GLB_JSON, GLB_MAGIC, linear_to_srgb
from .gltf_write import GltfBuilder, Primitive
from .mesh import mesh_uv, shading_normals, tangent_frames, torus
from .shapes import plane, sphere

SIZE = 128


def _noise(size: int, scale: float, seed: int) -> np.ndarray:
    """Tileable band-limited noise, zero mean, unit std."""
    gen = np.random.default_rng(seed)
    f = np.fft.fftfreq(size)
    r2 = f[:, None] ** 2 + f[None, :] ** 2
    n = np.real(np.fft.ifft2(np.fft.fft2(gen.standard_normal((size, size))) * np.exp(-r2 * (math.pi * scale) ** 2)))
    return (n - n.mean()) / max(n.std(), 1e-12)


def _to8(x) -> np.ndarray:
    return np.clip(np.rint(np.asarray(x, np.float64) * 255.0), 0, 255).astype(np.uint8)


def tile_textures(size: int = SIZE, seed: int = 3) -> dict[str, np.ndarray]:
    """A tiled floor's textures as RGBA8 [size, size, 4] (row 0 = top): base colour (sRGB),
    metallic-roughness (G, B), normal (tangent space, +y towards the image's top), occlusion (R),
    emissive (sRGB)."""
    u = (np.arange(size) + 0.5) / size
    uu, vv = np.meshgrid(u, u)           # vv grows down the image (glTF v)
    cells = 4
    fx, fy = (uu * cells) % 1.0, (vv * cells) % 1.0
    edge = np.minimum(np.minimum(fx, 1 - fx), np.minimum(fy, 1 - fy))
    face = np.clip((edge - 0.04) / 0.06, 0.0, 1.0)
    face = face * face * (3 - 2 * face)
    cell = (np.floor(uu * cells) + cells * np.floor(vv * cells)).astype(int)
    gen = np.random.default_rng(seed)
    hue = gen.uniform(0.0, 1.0, (cells * cells, 3))[cell]
    grain = _noise(size, 2.0, seed + 1)
    base = face[..., None] * (0.25 + 0.5 * hue + 0.03 * grain[..., None]) + (1 - face[..., None]) * 0.08
    height = face + 0.02 * grain
    dx = (np.roll(height, -1, 1) - np.roll(height, 1, 1)) * (size / 2) / cells
    dy = (np.roll(height, 1, 0) - np.roll(height, -1, 0)) * (size / 2) / cells   # towards the top
    n = np.stack([-0.6 * dx, -0.6 * dy, np.ones_like(height)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    metal = (cell % 3 == 0).astype(np.float64) * face
    rough = np.clip(0.25 + 0.5 * (1 - face) + 0.1 * grain, 0.05, 1.0)
    ao = np.clip(0.55 + 0.45 * face, 0, 1)
    glow = np.where((cell % 7 == 3)[..., None], np.array([1.0, 0.45, 0.1]) * face[..., None] * 0.8, 0.0)
    one = np.ones_like(height)
    return {"base_color": _to8(np.concatenate([linear_to_srgb(base), one[..., None]], -1)),
            "metallic_roughness": _to8(np.stack([one, rough, metal, one], -1)),
            "normal": _to8(np.concatenate([0.5 + 0.5 * n, one[..., None]], -1)),
            "occlusion": _to8(np.stack([ao, ao, ao, one], -1)),
            "emissive": _to8(np.concatenate([linear_to_srgb(glow), one[..., None]], -1))}


def _primitive(mesh, material=None, *, normals=True, tangents=True) -> Primitive:
    uv = mesh_uv(mesh)
    n = shading_normals(mesh)
    t = tangent_frames(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces), uv, n) if tangents else None
    return Primitive(np.asarray(mesh.vertices), np.asarray(mesh.faces), n if normals else None, uv, t, material)


def _quat(axis, degrees) -> list[float]:
    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    h = math.radians(degrees) / 2
    return [*(a * math.sin(h)).tolist(), math.cos(h)]


def tiles_torus() -> GltfBuilder:
    b = GltfBuilder()
    t = tile_textures()
    tex = {k: b.texture(b.image(v)) for k, v in t.items()}
    transform = {"KHR_texture_transform": {"scale": [2.0, 1.0], "rotation": 0.3, "offset": [0.1, 0.05]}}
    mat = b.material({
        "name": "tiles",
        "pbrMetallicRoughness": {"baseColorTexture": {"index": tex["base_color"], "extensions": transform},
                                 "metallicRoughnessTexture": {"index": tex["metallic_roughness"]},
                                 "baseColorFactor": [1.0, 0.95, 0.9, 1.0], "metallicFactor": 1.0, "roughnessFactor": 1.0},
        "normalTexture": {"index": tex["normal"], "scale": 0.8, "extensions": transform},
        "occlusionTexture": {"index": tex["occlusion"], "strength": 0.9},
        "emissiveTexture": {"index": tex["emissive"]}, "emissiveFactor": [1.0, 1.0, 1.0]})
    mesh = b.mesh([_primitive(torus(segments=(64, 32), tiles=(2.0, 1.0)), mat)], "torus")
    b.node(mesh, translation=[0.0, 0.1, 0.0], rotation=_quat([1, 0, 0], 20), name="torus")
    return b


def showcase() -> GltfBuilder:
    b = GltfBuilder()
    size = 64
    u = (np.arange(size) + 0.5) / size
    uu, vv = np.meshgrid(u, u)
    stripes = 0.5 + 0.5 * np.sin(2 * math.pi * 6 * uu)
    weave = _to8(np.stack([linear_to_srgb(0.3 + 0.5 * stripes), linear_to_srgb(0.15 + 0.2 * stripes),
                           linear_to_srgb(0.35 * np.ones_like(uu)), np.ones_like(uu)], -1))
    angle = 0.6 * np.sin(2 * math.pi * vv)
    direction = _to8(np.stack([0.5 + 0.5 * np.cos(angle), 0.5 + 0.5 * np.sin(angle), 0.6 + 0.4 * uu,
                               np.ones_like(uu)], -1))
    diffuse = _to8(np.stack([linear_to_srgb(0.2 + 0.6 * uu), linear_to_srgb(0.3 * np.ones_like(uu)),
                             linear_to_srgb(0.6 - 0.4 * vv), np.ones_like(uu)], -1))
    spec_gloss = _to8(np.stack([0.1 + 0.8 * vv, 0.1 + 0.8 * vv, 0.1 + 0.8 * vv, 0.3 + 0.6 * uu], -1))
    paint = b.material({"name": "car paint", "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.03, 0.02, 1.0],
                                                                      "metallicFactor": 0.3, "roughnessFactor": 0.5},
                        "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0,
                                                                   "clearcoatRoughnessFactor": 0.05}}})
    brushed = b.material({"name": "brushed metal",
                          "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.85, 0.8, 1.0], "metallicFactor": 1.0,
                                                   "roughnessFactor": 0.45},
                          "extensions": {"KHR_materials_anisotropy": {
                              "anisotropyStrength": 0.8, "anisotropyRotation": 0.4,
                              "anisotropyTexture": {"index": b.texture(b.image(direction))}}}})
    fabric = b.material({"name": "fabric",
                         "pbrMetallicRoughness": {"baseColorTexture": {"index": b.texture(b.image(weave)), "extensions": {
                             "KHR_texture_transform": {"scale": [3.0, 3.0], "rotation": 0.5}}},
                             "metallicFactor": 0.0, "roughnessFactor": 0.8},
                         "normalTexture": {"index": b.texture(b.image(tile_textures(64)["normal"])), "scale": 0.5},
                         "extensions": {"KHR_materials_sheen": {"sheenColorFactor": [0.9, 0.8, 1.0],
                                                                "sheenRoughnessFactor": 0.4}},
                         "doubleSided": True})
    specular = b.material({"name": "specular-glossiness", "extensions": {"KHR_materials_pbrSpecularGlossiness": {
        "diffuseTexture": {"index": b.texture(b.image(diffuse))},
        "specularGlossinessTexture": {"index": b.texture(b.image(spec_gloss))},
        "specularFactor": [1.0, 1.0, 1.0], "glossinessFactor": 1.0}}})
    ball = sphere(0.5, 16)
    ground = b.mesh([_primitive(plane(6.0, 4), fabric, tangents=False)], "ground")
    paint_ball = b.mesh([_primitive(ball, paint)], "paint ball")
    metal_ball = b.mesh([_primitive(ball, brushed)], "metal ball")
    spec_ball = b.mesh([_primitive(ball, specular)], "spec-gloss ball")
    flat_ball = b.mesh([_primitive(sphere(0.2, 6), None, normals=False, tangents=False)], "flat ball")
    b.node(ground, name="ground")
    left = b.node(paint_ball, translation=[-1.2, 0.5, 0.0], root=False, name="paint")
    mirror = b.node(paint_ball, translation=[1.2, 0.5, 0.0], scale=[-1.0, 1.0, 1.0], root=False, name="mirrored paint")
    b.node(None, rotation=_quat([0, 1, 0], 15), scale=[1.1, 1.1, 1.1], children=[left, mirror], name="pair")
    b.node(metal_ball, translation=[0.0, 0.5, -1.2], name="metal")
    b.node(spec_ball, translation=[0.0, 0.5, 1.2], name="spec-gloss")
    k = np.arange(5)
    b.node(flat_ball, name="row", instances={
        "TRANSLATION": np.stack([-2.0 + k, np.full(5, 0.2), np.full(5, 2.2)], 1),
        "ROTATION": np.array([_quat([0, 1, 0], 20.0 * i) for i in k]),
        "SCALE": np.stack([0.6 + 0.1 * k] * 3, 1)})
    return b


SCENES = {"tiles_torus": tiles_torus, "showcase": showcase}


# the malformed corpus ------------------------------------------------------------------------------
def _glb(doc: dict, data: bytes = b"") -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    data += b"\0" * (-len(data) % 4)
    chunks = struct.pack("<II", len(text), GLB_JSON) + text
    if data:
        chunks += struct.pack("<II", len(data), GLB_BIN) + data
    return struct.pack("<III", GLB_MAGIC, 2, 12 + len(chunks)) + chunks


def _triangle_doc(**changes) -> tuple[dict, bytes]:
    data = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes() + np.array([0, 1, 2], np.uint32).tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 0]},
                         {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                           {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
           "buffers": [{"byteLength": 48}]}
    for path, value in changes.items():
        target = doc
        keys = path.split("__")
        for k in keys[:-1]:
            target = target[int(k)] if isinstance(target, list) else target[k]
        last = keys[-1]
        if isinstance(target, list):
            target[int(last)] = value
        else:
            target[last] = value
    return doc, data


# name -> (what is wrong, the field the one-line error must name)
MALFORMED = {
    "missing_buffer": ("the buffer's file does not exist", "buffers[0].uri"),
    "accessor_out_of_range": ("an accessor reads past its bufferView", "accessors[0]"),
    "unknown_required_extension": ("a required extension nobody knows", "extensionsRequired"),
    "lines": ("a primitive of lines", "meshes[0].primitives[0].mode"),
    "index_out_of_range": ("an index past the vertex count", "meshes[0].primitives[0].indices"),
    "not_gltf_2": ("asset.version 1.0", "asset.version"),
    "truncated_glb": ("a GLB cut short", "GLB"),
}


def malformed(folder) -> dict[str, Path]:
    """Write the corpus into ``folder``: {name: path}."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    doc, data = _triangle_doc()
    doc["buffers"][0]["uri"] = "absent.bin"
    out["missing_buffer"] = folder / "missing_buffer.gltf"
    atomic_write(out["missing_buffer"], json.dumps(doc))
    doc, data = _triangle_doc(accessors__0__count=40)
    out["accessor_out_of_range"] = folder / "accessor_out_of_range.glb"
    atomic_write(out["accessor_out_of_range"], _glb(doc, data))
    doc, data = _triangle_doc(extensionsUsed=["VENDOR_magic"], extensionsRequired=["VENDOR_magic"])
    out["unknown_required_extension"] = folder / "unknown_required_extension.glb"
    atomic_write(out["unknown_required_extension"], _glb(doc, data))
    doc, data = _triangle_doc()
    doc["meshes"][0]["primitives"][0]["mode"] = 1
    doc["accessors"][1]["count"] = 2
    out["lines"] = folder / "lines.glb"
    atomic_write(out["lines"], _glb(doc, data))
    doc, _ = _triangle_doc()
    data = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes() + np.array([0, 1, 7], np.uint32).tobytes()
    out["index_out_of_range"] = folder / "index_out_of_range.glb"
    atomic_write(out["index_out_of_range"], _glb(doc, data))
    doc, data = _triangle_doc(asset={"version": "1.0"})
    out["not_gltf_2"] = folder / "not_gltf_2.glb"
    atomic_write(out["not_gltf_2"], _glb(doc, data))
    doc, data = _triangle_doc()
    out["truncated_glb"] = folder / "truncated_glb.glb"
    atomic_write(out["truncated_glb"], _glb(doc, data)[:60])
    return out


def write_all(folder) -> dict[str, Path]:
    folder = Path(folder)
    return {name: make().write(folder / f"{name}.glb") for name, make in SCENES.items()}


def main(argv: list[str]) -> int:
    if len(argv) != 1 or argv[0] in ("-h", "--help"):
        print("usage: python -m inshade.geometry.gltf_scenes OUT_FOLDER\n\nwrites the procedural glTF test "
              f"assets ({', '.join(SCENES)}) and the malformed corpus (malformed/)")
        return 0 if argv and argv[0] in ("-h", "--help") else 2
    for name, path in write_all(argv[0]).items():
        print(f"wrote {path}")
    malformed(Path(argv[0]) / "malformed")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
