"""``inshade export-gltf ASSET -o OUT.glb``: an asset's mesh and material back out as one glTF 2.0
binary, for the tools users already have (Blender, three.js, the Khronos sample viewer).

- The mesh: the scene's, in world space, with its normals, uv (stored v down, as glTF does) and
  tangents; split into one primitive per material.
- The material, by ``material``:
  ``decoded``: what the asset's network decodes, baked into the mesh's uv space through the GL
  runtime by the program's ``ProgramSpec.bake`` hook (a ``MaterialBake``), written as base colour
  (sRGB), metallic-roughness, normal, occlusion and emissive textures of ``size`` texels, mapped
  onto the mesh's uv by a KHR_texture_transform where the bake covers another rectangle; where the
  bake replaces one material of a glTF scene the others are written as the file has them;
  ``reference``: the materials of the glTF file the scene was made from, as they are (a converted
  specular-glossiness material comes out metallic-roughness);
  ``auto``: decoded where the program can bake, else the reference.
- The file is written atomically; an existing file is kept unless ``force``. Every refusal is one
  ``GltfExportError`` naming the asset and what is missing.

numpy + Pillow + the GL runtime; no torch.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from inshade.geometry.gltf import Material, TextureRef, linear_to_srgb, texture_transform
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


def bake_transform(bake) -> np.ndarray:
    """The 3x3 KHR_texture_transform matrix taking glTF uv g to the bake's texture:
    t = ((g_u - o_u) / e_u, (g_v + o_v + e_v - 1) / e_v) for the rectangle origin o, extent e in
    the project's v-up uv (row 0 of the bake is its top, glTF's t_v = 0)."""
    (ou, ov), (eu, ev) = bake.origin, bake.extent
    return texture_transform((-ou / eu, (ov + ev - 1.0) / ev), 0.0, (1.0 / eu, 1.0 / ev))


def decoded_material(bake, base: Material | None, first_image: int) -> tuple[Material, list]:
    """(the material, its new images): ``base`` (the file's material the bake replaces, or the
    spec's default) with the baked channels' textures in place of its own and their factors,
    scale and strength set to 1; the channels it does not bake (emission, clearcoat, sheen, ...)
    stay as ``base`` has them. The new textures are images ``first_image``, ``first_image + 1``, ..."""
    m = copy.deepcopy(base) if base is not None else Material(name="decoded")
    images = channel_images(bake.channels)
    wrap = tuple("repeat" if r else "clamp" for r in bake.repeat)
    transform = bake_transform(bake)
    order = list(images)
    ref = lambda k: TextureRef(first_image + order.index(k), 0, transform, wrap)  # noqa: E731
    if "base_color" in images:
        m.base_color = (1.0, 1.0, 1.0, m.base_color[3])
        m.base_color_texture = ref("base_color")
    if "metallic_roughness" in images:
        m.metallic = 1.0 if "metallic" in bake.channels else m.metallic
        m.roughness = 1.0 if "roughness" in bake.channels else m.roughness
        m.metallic_roughness_texture = ref("metallic_roughness")
    if "normal" in images:
        m.normal_texture = ref("normal")
    if "occlusion" in images:
        m.occlusion_texture = ref("occlusion")
    if "emissive" in images:
        m.emissive, m.emissive_texture = (1.0, 1.0, 1.0), ref("emissive")
    m.converted_from = None
    return m, [images[k] for k in order]


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
                force: bool = False, compress: str = "none", textures: str = "png") -> GltfExport:
    """Write ``out`` (a .glb) from the asset at ``source``; see the module docstring. ``compress``:
    the mesh as it is ("none"), KHR_draco_mesh_compression ("draco", quantized) or
    EXT_meshopt_compression ("meshopt", lossless); ``textures``: "png" or "ktx2" (KHR_texture_basisu,
    UASTC)."""
    from inshade.geometry.gltf_codecs import MESH_CODECS, TEXTURE_CODECS
    from inshade.scene.description import load_scene

    out = Path(out)
    if material not in MATERIAL_SOURCES:
        raise GltfExportError(f"--material: must be one of {', '.join(MATERIAL_SOURCES)}, got {material!r}")
    if out.suffix.lower() != ".glb":
        raise GltfExportError(f"{out}: -o: export-gltf writes a binary glTF; name it .glb")
    if out.exists() and not force:
        raise GltfExportError(f"{out}: -o: exists; add --force to replace it")
    if compress not in MESH_CODECS:
        raise GltfExportError(f"--compress: must be one of {', '.join(MESH_CODECS)}, got {compress!r}")
    if textures not in TEXTURE_CODECS:
        raise GltfExportError(f"--textures: must be one of {', '.join(TEXTURE_CODECS)}, got {textures!r}")
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
    builder = GltfBuilder(draco=compress == "draco", meshopt=compress == "meshopt", textures=textures)
    arrays = _mesh_arrays(scene.mesh.data)
    notes = []
    materials = list(gltf.materials) if gltf is not None else [None]
    images = list(gltf.images) if gltf is not None else []
    face_material = gltf.face_material if gltf is not None else np.zeros(len(arrays[1]), int)
    if material == "decoded":   # the decoded material in place of the one it replaces (all: None)
        baked = bake(scene, scene.check_settings(settings or {}), int(size))
        for m in (range(len(materials)) if baked.material is None else [baked.material]):
            materials[m], new = decoded_material(baked, materials[m], len(images))
            images += new
        notes.append(f"material decoded by {scene.program} at {size}x{size} texels")
    image_index: dict = {}
    groups = [(np.flatnonzero(face_material == m), add_material(builder, materials[m], images, image_index))
              for m in np.unique(face_material)]
    if gltf is not None:
        notes += gltf.notes
    mesh = builder.mesh([_primitive(arrays, faces, m) for faces, m in groups], scene.name)
    builder.node(mesh, name=scene.name)
    builder.write(out)
    return GltfExport(out, material, len(groups), notes)
