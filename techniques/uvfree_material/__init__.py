"""uvfree_material: a UV-free neural material on meshes (Walloner 2024, "Neural Compression of
Material Properties using a Geometry-Associated Feature Hierarchy"), decoded in a fragment shader.

Features live on a regular 2^l subdivision of every triangle (L levels), shared across edges and
vertices through precomputed owner tables and stored in per-level hash tables (component
``mesh_features``: geometry/mesh_topology.py, models/mesh_features.py, components/mesh_features/emit.py);
an MLP decodes the concatenated features to 9 material channels (model.py CHANNELS). The pass
reads the mesh's visibility buffer (face id + barycentrics, ProgramSpec.visibility) and decodes
each visible pixel once, then shades the channels with lib/pbr_shading. An asset folder
(``trained/uvfree_material_<object>_<config>``) holds the bundle ``material`` (kind
``uvfree_material``), the mesh and its reference uv textures (albedo, normal, rma) that the
``reference`` view samples. quantize.py (``python -m inshade.techniques.uvfree_material.quantize``)
stores a trained asset's feature table at 8 bits per value (mesh_features precision ``u8``: half
the feature bytes), post-training or with a short quantisation-aware fine-tune.

From a glTF file (``inshade train uvfree_material --gltf FILE``) the decoder learns the file's
material channels (gltf_channels.py) on the file's own mesh, and passes/mesh_uvfree_gltf.frag draws
it against the file's material (lib/gltf_material): bundle kind ``uvfree_material_gltf``, the
copied file as the scene's mesh (gltf_scene.py).
"""

from inshade.papers import FEATURE_HIERARCHY
from inshade.technique import Choice, ProgramSpec, folder_technique

KIND = "uvfree_material"
KIND_GLTF = "uvfree_material_gltf"   # decodes a glTF file's channels (gltf_channels.py), drawn with its materials
# u_uvf_view / u_uvf_channel / u_uvf_wireframe in index order: the pass's UVF_VIEW_*, UVF_CHANNEL_* and
# UVF_WIREFRAME_* come from the program's choices (CHOICES)
VIEWS = ("decoded", "reference", "split", "error")
CHANNEL_VIEWS = ("shaded", "albedo", "normal", "roughness", "metallic", "ao")
WIREFRAME = ("off", "triangles", "level")
CHOICES = (Choice("u_uvf_view", "UVF_VIEW", VIEWS), Choice("u_uvf_channel", "UVF_CHANNEL", CHANNEL_VIEWS),
           Choice("u_uvf_wireframe", "UVF_WIREFRAME", WIREFRAME))
UNIFORM_DEFAULTS = {"u_uvf_view": VIEWS.index("split"), "u_uvf_channel": CHANNEL_VIEWS.index("shaded"),
                    "u_uvf_wireframe": WIREFRAME.index("off"), "u_uvf_wire_level": 1,
                    "u_uvf_error_scale": 4.0, "u_light_count": 2}


# u_uvg_view / u_uvg_channel of passes/mesh_uvfree_gltf.frag, in index order (UVG_VIEW_*, UVG_CHANNEL_*)
GLTF_VIEWS = ("reference", "decoded", "split", "error")   # "decoded": as VIEWS names it
ERROR_SCALE = 4.0   # the error view shows |network - reference| times this (the "error_scale" setting)
GLTF_CHANNEL_VIEWS = ("shaded", "base_color", "normal", "metallic", "roughness", "occlusion", "emissive")
GLTF_CHOICES = (Choice("u_uvg_view", "UVG_VIEW", GLTF_VIEWS), Choice("u_uvg_channel", "UVG_CHANNEL", GLTF_CHANNEL_VIEWS))
GLTF_UNIFORM_DEFAULTS = {"u_uvg_view": GLTF_VIEWS.index("split"), "u_uvg_channel": GLTF_CHANNEL_VIEWS.index("shaded"),
                         "u_light_count": 2, "u_uvg_error_scale": ERROR_SCALE}


def _material_network(scene):
    nets = [n for n in scene.networks if n.prefix == "mat"]
    if len(nets) != 1:
        raise ValueError("networks: a uvfree_material scene needs one network with prefix \"mat\" (the material bundle)")
    return nets[0]


def _validate(scene):
    """One material network at prefix "mat"; the scene's mesh is the one the bundle was trained on
    (features are addressed by face id: same faces, same order, same welded topology)."""
    from .scene_check import check_mesh_matches

    check_mesh_matches(scene, _material_network(scene))


def _gltf_layout(bundle) -> tuple:
    from .gltf_channels import read_render_meta

    return read_render_meta(bundle.meta.get("render"), f"bundle {bundle.name!r}")


def _validate_gltf(scene):
    """The material network of a glTF file: the scene's mesh is that file (face ids as trained) and
    the bundle says which channels its lanes hold."""
    from inshade.bundle import load

    from .scene_check import check_mesh_matches

    net = _material_network(scene)
    check_mesh_matches(scene, net)
    _gltf_layout(load(net.bundle))


def _gltf_chunks(scene, bundles, networks, codegen_options) -> dict:
    """<uvf_gltf_channels>: the decoder's lane of each channel, from the bundle's render field."""
    from .gltf_channels import CHUNK, layout_chunk

    bundle = next(b for b, n in zip(bundles, networks) if n.prefix == "mat")
    return {CHUNK: layout_chunk(*_gltf_layout(bundle))}


TECHNIQUE = folder_technique(
    __name__, "UV-free neural material: hashed per-triangle feature hierarchy + MLP, decoded from a visibility buffer",
    FEATURE_HIERARCHY, kinds=(KIND, KIND_GLTF),
    programs=(ProgramSpec("passes/mesh_uvfree_material.frag", geometry="mesh", mesh_attributes=("uv", "tangent"),
                          bundle_kinds=(KIND,), uniforms=UNIFORM_DEFAULTS, validate=_validate, visibility=True,
                          choices=CHOICES),
              ProgramSpec("passes/mesh_uvfree_gltf.frag", geometry="mesh", mesh_attributes=("materials",),
                          bundle_kinds=(KIND_GLTF,), uniforms=GLTF_UNIFORM_DEFAULTS, chunks=_gltf_chunks,
                          validate=_validate_gltf, visibility=True, choices=GLTF_CHOICES)),
    train="fit a hashed per-triangle feature hierarchy + MLP to a uv-textured mesh or a glTF file's materials",
    bench="UV-free material vs its uv textures, BC1/BC7/ASTC at equal bytes: quality, memory, speed")
