"""neural_appearance: Real-Time Neural Appearance Models (NVIDIA 2024) in plain GLSL.

A layered reference material (material.py: a clear coat over a normal-mapped diffuse/anisotropic
conductor base, 12 procedurally textured channels) is baked into an 8-channel latent mip pyramid
(two RGBA16F chains) decoded by small MLPs with a learned shading-frame layer (2x16, 2x32, 3x64),
plus a 3x32 importance-sampling decoder driving an analytic two-lobe proxy (tilted cosine +
anisotropic non-centred GGX). One asset folder holds one bundle per network (kind
``neural_appearance``): ``latents``, ``decoder_2x16``, ``decoder_2x32``, ``decoder_3x64``,
``sampler`` and ``sampler_isotropic`` (the paper's isotropic baseline), the material description
(``material.json``) and its parameter textures (``param0..2.png``) for the reference shader.

Trained from a glTF file's material instead (``--gltf FILE``), the asset holds the same bundles, the
file as the scene's mesh (``source.glb``) and ``gltf_material.json`` (which material is neural, its
uv box); its scene draws ``passes/mesh_neural_appearance_gltf.frag``: the neural material next to the
file's own shading (lib/gltf_material), views ``GLTF_VIEWS``.
"""

from inshade.papers import NEURAL_APPEARANCE
from inshade.technique import Choice, ProgramSpec, folder_technique

KIND = "neural_appearance"
# (bundle folder in the asset, GLSL prefix): the pass includes <network_PREFIX> for each.
NETWORKS = (("latents", "latents"), ("decoder_2x16", "dec16"), ("decoder_2x32", "dec32"),
            ("decoder_3x64", "dec64"), ("sampler", "smp"), ("sampler_isotropic", "iso"))
DECODERS = {"2x16": "decoder_2x16", "2x32": "decoder_2x32", "3x64": "decoder_3x64"}
# the pass's views, lighting modes and BRDF samplings in index order: its NA_VIEW_*, NA_LIGHTING_* and
# NA_SAMPLING_* come from the program's choices (CHOICES)
VIEWS = ("neural", "reference", "split", "error", "level", "latents")
LIGHTING = ("lights", "environment")
SAMPLING = ("learned", "isotropic", "cosine")
CHOICES = (Choice("u_na_view", "NA_VIEW", VIEWS), Choice("u_na_lighting", "NA_LIGHTING", LIGHTING),
           Choice("u_na_sampling", "NA_SAMPLING", SAMPLING))
# the glTF pass's views and lightings (GLTF_PROGRAM; NA_VIEW_* and NA_LIGHTING_* of its own <choices>)
GLTF_PROGRAM = "passes/mesh_neural_appearance_gltf.frag"
GLTF_VIEWS = ("split", "reference", "neural", "error")
GLTF_LIGHTING = ("shaded", "lights")
GLTF_CHOICES = (Choice("u_na_view", "NA_VIEW", GLTF_VIEWS), Choice("u_na_lighting", "NA_LIGHTING", GLTF_LIGHTING),
                Choice("u_na_sampling", "NA_SAMPLING", SAMPLING))
GLTF_UNIFORM_DEFAULTS = {"u_na_view": 0, "u_na_lighting": 0, "u_na_sampling": 0, "u_na_mis": 1,
                         "u_na_level_bias": 0.0, "u_na_error_scale": 4.0, "u_light_count": 2}
UNIFORM_DEFAULTS = {"u_na_view": 0, "u_na_lighting": 0, "u_na_sampling": 0, "u_na_mis": 1, "u_na_level_bias": 0.0,
                    "u_na_error_scale": 4.0, "u_na_latent_page": 0, "u_light_count": 4}


def _validate_networks(scene):
    have = {n.prefix: n for n in scene.networks}
    missing = [f"{folder} (prefix {prefix})" for folder, prefix in NETWORKS if prefix not in have]
    if missing:
        raise ValueError(f"networks: a neural appearance scene needs {', '.join(missing)} "
                         f"(one entry per network: {', '.join(f for f, _ in NETWORKS)})")


def _validate(scene):
    """Every network role at its prefix; a lit (environment) scene."""
    from .material_uniforms import material_path

    _validate_networks(scene)
    if not material_path(scene).is_file():
        raise ValueError(f"material: {material_path(scene)}: missing (the reference material's description)")


def _chunks(scene, bundles, networks, codegen_options):
    """``<na_latents_info>``: the latent pyramid's finest side and level count (lib/na_neural)."""
    for bundle, ref in zip(bundles, networks):
        if ref.prefix != "latents":
            continue
        nodes = [n for n in bundle.nodes if n.type == "latent_pyramid"]
        if len(nodes) != 1:
            raise ValueError(f"networks: {bundle.name}: the latents bundle needs one latent_pyramid node, "
                             f"has {len(nodes)}")
        p = nodes[0].params
        return {"na_latents_info": f"#define NA_LATENT_RES {int(p['resolution'])}\n"
                                   f"#define NA_LATENT_LEVELS {int(p['levels'])}\n"}
    raise ValueError("networks: no latents bundle (prefix \"latents\")")


def _validate_gltf(scene):
    """Every network role; gltf_material.json naming a material of the scene's glTF mesh."""
    from .gltf_info import info_path, read_info

    _validate_networks(scene)
    info = read_info(info_path(scene))
    count = len(scene.mesh.gltf.materials)
    if info["material"] >= count:
        raise ValueError(f"{info_path(scene)}: material: {info['material']} is not a material of "
                         f"{scene.mesh.name} (it has {count})")


def _gltf_chunks(scene, bundles, networks, codegen_options):
    """``<na_latents_info>`` as for the layered pass, and ``<na_gltf_info>``: the neural material's
    index and its uv -> latent map (gltf_info.py)."""
    from .gltf_info import info_chunk, info_path, read_info

    return {**_chunks(scene, bundles, networks, codegen_options),
            "na_gltf_info": info_chunk(read_info(info_path(scene)))}


def _frame(inputs):
    """The reference material's constants (the asset's material.json) as uniforms."""
    from .material_uniforms import material_uniforms

    return material_uniforms(inputs.scene)


TECHNIQUE = folder_technique(
    __name__, "neural materials: latent mip pyramid + MLP decoders with learned frames and a learned sampler",
    NEURAL_APPEARANCE,
    programs=(ProgramSpec("passes/mesh_neural_appearance.frag", geometry="mesh", mesh_attributes=("uv", "tangent"),
                          bundle_kinds=(KIND,), uniforms=UNIFORM_DEFAULTS, chunks=_chunks, frame=_frame, validate=_validate,
                          accumulate=True, choices=CHOICES),
              ProgramSpec(GLTF_PROGRAM, geometry="mesh", mesh_attributes=("uv", "tangent", "materials"),
                          bundle_kinds=(KIND,), uniforms=GLTF_UNIFORM_DEFAULTS, chunks=_gltf_chunks,
                          validate=_validate_gltf, accumulate=True, choices=GLTF_CHOICES)),
    train="bake a layered material or a glTF file's material into a latent pyramid + decoders + sampler",
    bench="neural vs reference layered material: quality, speed, sampler variance, memory")
