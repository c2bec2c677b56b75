"""prt: learnt-transfer precomputed radiance transfer. A transfer MLP maps a surface point and its
normal to 16 SH coefficients of cosine-weighted visibility; diffuse and glossy (triple-product
light matrix) shading on sphere-traced SDFs and rasterised meshes (a glTF file's with its base
colour, next to its reference shading)."""

from inshade.papers import LEARNT_TRANSFER
from inshade.technique import Choice, ProgramSpec, Technique, folder_fields


def _chunks(scene, bundles, networks, codegen_options):
    """``<prt_network>``: the transfer network's eval function and its frame (codegen.py)."""
    from .codegen import KINDS, PrtError, prt_chunks, transfer_frame

    found = [(b, n) for b, n in zip(bundles, networks) if b.kind in KINDS]
    if not found:
        kinds = ", ".join(f"{b.name} ({b.kind})" for b in bundles)
        raise ValueError(f"networks: {scene.program} needs a transfer network (bundle kind \"{KINDS[0]}\"); "
                         f"this scene has {kinds or 'none'}")
    from .regions import RegionError, is_region_bundle, region_chunks

    try:
        if any(is_region_bundle(b) for b, _ in found):   # sub-scene networks selected by region (regions.py)
            return region_chunks([b for b, _ in found], [n.prefix for _, n in found],
                                 [transfer_frame(b) for b, _ in found])
        return prt_chunks(found[0][0], prefix=found[0][1].prefix)
    except (PrtError, RegionError) as exc:
        raise ValueError(f"networks: {exc}") from None


def _frame(inputs):
    """The glossy light matrix of the current lighting (cached per lighting in codegen.py)."""
    from .codegen import light_matrix_uniform

    return {"u_prt_light": light_matrix_uniform(inputs.environment_sh)}


def _validate(scene):
    """A transfer network (the u_shading setting is checked against SHADING_MODES by the runtime)."""
    if not scene.networks:
        raise ValueError(f"networks: a PRT scene ({scene.program}) needs a transfer network: "
                         "[{\"bundle\": \"transfer\"}] naming a bundle of kind \"prt\"")


# u_shading's values in index order: lib/prt.glsl's PRT_DIFFUSE, PRT_GLOSSY come from the programs' choices
SHADING_MODES = ("diffuse", "glossy")
# u_prt_view's values in index order (passes/mesh_prt_gltf.frag's PRT_VIEW_* come from the program's choices)
GLTF_VIEWS = ("prt", "reference", "split", "albedo")
# Values of the PRT passes' uniforms a scene does not bind to a setting (twin.py PrtShading's defaults).
UNIFORM_DEFAULTS = {"u_shading": SHADING_MODES.index("diffuse"), "u_phong_exponent": 16.0, "u_albedo": 1.0,
                    "u_kd": 1.0, "u_ks": 0.5, "u_prt_debug": 0}
_PRT = dict(bundle_kinds=("prt", "transfer"), uniforms=UNIFORM_DEFAULTS, chunks=_chunks, frame=_frame,
            validate=_validate, environment_degree=4, choices=(Choice("u_shading", "PRT", SHADING_MODES),))


def _texture_chunks(scene, bundles, networks, codegen_options):
    """<prt_texture_network> + the network stub of the texture-space PRT pass (texture_codegen.py)."""
    from .texture_codegen import chunks_hook

    return chunks_hook(scene, bundles, networks, codegen_options)


def _texture_validate(scene):
    from .texture_codegen import validate_hook

    validate_hook(scene)


TECHNIQUE = Technique(
    name="prt",
    summary="learnt-transfer PRT: a transfer MLP, diffuse + glossy SH shading on SDFs and meshes",
    paper=LEARNT_TRANSFER,
    kinds=("prt", "prt_texture"),
    old_kinds={"transfer": "prt"},
    programs=(ProgramSpec("passes/sdf_prt.frag", geometry="sdf", **_PRT),
              ProgramSpec("passes/mesh_prt.frag", geometry="mesh", **_PRT),
              # the paper's baseline: transfer baked into a uv texture (texture_prt.py), same shading
              ProgramSpec("passes/mesh_prt_texture.frag", geometry="mesh", mesh_attributes=("uv",),
                          **{**_PRT, "bundle_kinds": ("prt_texture",), "chunks": _texture_chunks,
                             "validate": _texture_validate}),
              # a glTF file: PRT with its base colour next to its reference shading (lib/gltf_material)
              ProgramSpec("passes/mesh_prt_gltf.frag", geometry="mesh", mesh_attributes=("materials",),
                          **{**_PRT, "uniforms": {**UNIFORM_DEFAULTS, "u_prt_view": GLTF_VIEWS.index("prt")},
                             "choices": (*_PRT["choices"], Choice("u_prt_view", "PRT_VIEW", GLTF_VIEWS))})),
    **folder_fields(
        __name__,
        train="a complete PRT asset: ground-truth transfer (cached), transfer MLP, scene, previews, quality",
        bench="learnt-transfer PRT frame times (k, size, shading, geometry) vs torch",
        shaders=True),
)
