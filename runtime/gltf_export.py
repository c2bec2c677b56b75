"""``inshade export-gltf ASSET -o OUT.glb``: an asset's mesh and material back out as one glTF 2.0
binary, for the tools users already have (Blender, three.js, the Khronos sample viewer).

- The mesh: the scene's, in world space, with its normals, uv (stored v down, as glTF does) and
  tangents; split into one primitive per material.
- The material, by ``material``:
  ``decoded``: what the asset's network decodes, baked into the mesh's uv space through the GL
  runtime by the program's ``ProgramSpec.bake`` hook, written as base colour (sRGB),
  metallic-roughness, normal, occlusion and emissive textures of ``size`` texels;
  ``reference``: the materials of the glTF file the scene was made from, as they are (a converted
  specular-glossiness material comes out metallic-roughness);
  ``auto``: decoded where the program can bake, else the reference.
- The file is written atomically; an existing file is kept unless ``force``. Every refusal is one
  ``GltfExportError`` naming the asset and what is missing.

numpy + Pillow + the GL runtime; no torch.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from inshade.geometry.gltf import linear_to_srgb
from inshade.geometry.gltf_write import GltfBuilder, Primitive, add_material
from inshade.geometry.mesh import mesh_uv, shading_normals, vertex_tangents

MATERIAL_SOURCES = ("auto", "decoded", "reference")
DEFAULT_SIZE = 512


class GltfExportError(ValueError):
    """An asset that cannot be exported as asked; the message names it."""


@dataclass
class GltfExport:
    path: Path
    material: str                     # "decoded" | "reference"
    primitives: int
    notes: list = field(default_factory=list)


def _to8(x) -> np.ndarray:
    return np.clip(np.rint(np.asarray(x, np.float64) * 255.0), 0, 255).astype(np.uint8)


def channel_images(channels: dict) -> dict[str, np.ndarray]:
    """Baked channels ([S, S(, k)] floats, geometry/gltf_sample.py names) as the glTF textures they
    fill: {"base_color", "metallic_roughness", "normal", "occlusion", "emissive"} RGBA8 images
    (only those the channels determine)."""
    first = next(iter(channels.values()))
    one = np.ones(first.shape[:2])
    out = {}
    if "base_color" in channels:
        alpha = channels.get("alpha", one)
        out["base_color"] = np.concatenate([_to8(linear_to_srgb(channels["base_color"])), _to8(alpha)[..., None]], -1)
    if "metallic" in channels or "roughness" in channels:
        out["metallic_roughness"] = np.stack([_to8(one), _to8(channels.get("roughness", one)),
                                              _to8(channels.get("metallic", one)), _to8(one)], -1)
    if "normal" in channels:
        n = channels["normal"] / np.maximum(np.linalg.norm(channels["normal"], axis=-1, keepdims=True), 1e-12)
        out["normal"] = np.concatenate([_to8(0.5 + 0.5 * n), _to8(one)[..., None]], -1)
    if "occlusion" in channels:
        ao = _to8(channels["occlusion"])
        out["occlusion"] = np.stack([ao, ao, ao, _to8(one)], -1)
    if "emissive" in channels and np.asarray(channels["emissive"]).max() > 0:
        out["emissive"] = np.concatenate([_to8(linear_to_srgb(channels["emissive"])), _to8(one)[..., None]], -1)
    return out


def _decoded_material(builder: GltfBuilder, channels: dict) -> int:
    images = channel_images(channels)
    # glTF images run v down; baked channels have row 0 at the top (v = 1 in the project's uv), and
    # glTF's v = 1 - v: the same rows, as they are
    tex = {k: builder.texture(builder.image(v)) for k, v in images.items()}
    spec: dict = {"name": "decoded", "pbrMetallicRoughness": {"metallicFactor": 1.0 if "metallic" in channels else 0.0,
                                                              "roughnessFactor": 1.0}}
    if "base_color" in tex:
        spec["pbrMetallicRoughness"]["baseColorTexture"] = {"index": tex["base_color"]}
    if "metallic_roughness" in tex:
        spec["pbrMetallicRoughness"]["metallicRoughnessTexture"] = {"index": tex["metallic_roughness"]}
    if "normal" in tex:
        spec["normalTexture"] = {"index": tex["normal"]}
    if "occlusion" in tex:
        spec["occlusionTexture"] = {"index": tex["occlusion"]}
    if "emissive" in tex:
        spec["emissiveTexture"] = {"index": tex["emissive"]}
        spec["emissiveFactor"] = [1.0, 1.0, 1.0]
    return builder.material(spec)


def _mesh_arrays(mesh):
    own = mesh.vertex_attributes
    normals = own["normal"] if "normal" in own else shading_normals(mesh)
    uv = mesh_uv(mesh)
    tangents = None
    if uv is not None:
        tangents = own["tangent"] if "tangent" in own else vertex_tangents(mesh, normals)
    return np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces), normals, uv, tangents


def _primitive(arrays, faces_of, material) -> Primitive:
    v, f, n, uv, t = arrays
    used, local = np.unique(f[faces_of].reshape(-1), return_inverse=True)
    pick = lambda a: None if a is None else np.asarray(a)[used]  # noqa: E731
    return Primitive(v[used], local.reshape(-1, 3), pick(n), pick(uv), pick(t), material)


def export_gltf(source, out, *, material: str = "auto", size: int = DEFAULT_SIZE, settings: dict | None = None,
                force: bool = False) -> GltfExport:
    """Write ``out`` (a .glb) from the asset at ``source``; see the module docstring."""
    from inshade.scene.description import load_scene

    out = Path(out)
    if material not in MATERIAL_SOURCES:
        raise GltfExportError(f"--material: must be one of {', '.join(MATERIAL_SOURCES)}, got {material!r}")
    if out.suffix.lower() != ".glb":
        raise GltfExportError(f"{out}: -o: export-gltf writes a binary glTF; name it .glb")
    if out.exists() and not force:
        raise GltfExportError(f"{out}: -o: exists; add --force to replace it")
    scene = load_scene(source)
    if scene.mesh is None:
        raise GltfExportError(f"{source}: its scene draws no mesh ({scene.spec.geometry} geometry): "
                              "export-gltf writes a mesh with its material")
    bake = scene.spec.bake
    gltf = scene.mesh.gltf
    if material == "auto":
        material = "decoded" if bake is not None else "reference"
    if material == "decoded" and bake is None:
        raise GltfExportError(f"{source}: {scene.program} has no material to decode into textures "
                              f"(use --material reference{'' if gltf is not None else ' with a glTF scene'})")
    if material == "reference" and gltf is None:
        raise GltfExportError(f"{source}: --material reference: the scene's mesh {scene.mesh.name} is not a glTF "
                              "file, so there is no reference material to write")
    if material == "decoded" and mesh_uv(scene.mesh.data) is None:
        raise GltfExportError(f"{source}: the mesh {scene.mesh.name} has no uv to bake the decoded material into")
    builder = GltfBuilder()
    arrays = _mesh_arrays(scene.mesh.data)
    notes = []
    if material == "decoded":
        values = scene.check_settings(settings or {})
        index = _decoded_material(builder, bake(scene, values, int(size)))
        groups = [(np.arange(len(arrays[1])), index)]
        notes.append(f"material decoded by {scene.program} at {size}x{size} texels")
    else:
        image_index: dict = {}
        groups = []
        for m in np.unique(gltf.face_material):
            written = add_material(builder, gltf.materials[m], gltf.images, image_index)
            groups.append((np.flatnonzero(gltf.face_material == m), written))
        notes += gltf.notes
    mesh = builder.mesh([_primitive(arrays, faces, m) for faces, m in groups], scene.name)
    builder.node(mesh, name=scene.name)
    builder.write(out)
    return GltfExport(out, material, len(groups), notes)
