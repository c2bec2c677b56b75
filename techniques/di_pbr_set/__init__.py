"""di_pbr_set: an 8-lane PBR texture set (albedo, normal, roughness, AO) compressed by one DI
cascade and shaded on a lit, uv-mapped mesh; its bundles are DI texture bundles with 8 lanes.

Two programs: passes/mesh_pbr_set.frag draws the procedural bricks set next to its uncompressed
RGBA8 textures; passes/mesh_pbr_set_gltf.frag draws one material of a glTF file (``inshade train
di_pbr_set --gltf FILE``: albedo, a two-lane normal, roughness, occlusion, metallic; gltf_lanes.py)
next to the file's own material shaded the same way (lib/gltf_material, the reference). Its bundle's
``render.uv_domain`` (material, uv origin, extent, repeat) becomes the chunk <pbr_set_gltf_domain>.
"""

from inshade.papers import DIFFERENTIABLE_INDIRECTION
from inshade.technique import Choice, MaterialBake, MaterialChannels, ProgramSpec, Technique, folder_fields

# u_pbr_view's values in index order (the pass's PBR_VIEW_* come from the program's choices)
VIEWS = ("uncompressed", "di", "split")
GLTF_VIEWS = ("reference", "di", "split", "error")
ERROR_SCALE = 4.0    # the error view shows |DI - reference| times this (the "error_scale" setting)
GLTF_PROGRAM = "passes/mesh_pbr_set_gltf.frag"


def _domain(bundles, networks):
    b = next((b for b, n in zip(bundles, networks) if n.prefix == "net"), None)
    if b is None:
        raise ValueError(f"networks: {GLTF_PROGRAM} needs the DI set as the network with prefix \"net\"")
    return _bundle_domain(b)


def _bundle_domain(b):
    from inshade.techniques.di_pbr_set.gltf_lanes import UvDomain

    return UvDomain.from_dict((b.meta.get("render") or {}).get("uv_domain"), f"bundle {b.name!r}")


def _gltf_chunks(scene, bundles, networks, codegen_options) -> dict:
    """<pbr_set_gltf_domain>: the material the lanes replace and the uv rectangle they cover."""
    return _domain_chunks(_domain(bundles, networks), "glsl")


def _domain_chunks(d, language: str) -> dict:
    """<pbr_set_gltf_domain> in ``language`` (glsl: defines, wgsl: constants)."""
    from inshade.codegen.glsl import flt

    flag = {True: "true", False: "false"}
    values = [("PBR_GLTF_MATERIAL", "i32", str(d.material)),
              ("PBR_GLTF_UV_ORIGIN", "vec2<f32>", f"{flt(d.origin[0])}, {flt(d.origin[1])}"),
              ("PBR_GLTF_UV_EXTENT", "vec2<f32>", f"{flt(d.extent[0])}, {flt(d.extent[1])}"),
              ("PBR_GLTF_REPEAT_U", "bool", flag[d.repeat[0]]), ("PBR_GLTF_REPEAT_V", "bool", flag[d.repeat[1]])]
    if language == "wgsl":
        lines = [f"const {n}: {t} = {f'{t}({v})' if t.startswith('vec') else v};" for n, t, v in values]
    else:
        lines = [f"#define {n} {f'vec2({v})' if t.startswith('vec') else v}" for n, t, v in values]
    return {"pbr_set_gltf_domain": "\n".join([
        "// the glTF material and uv rectangle the DI lanes cover (the bundle's render.uv_domain)", *lines, ""])}


def _channels_chunks(bundle, language: str) -> dict:
    return _domain_chunks(_bundle_domain(bundle), language)


def _channels_material(bundle) -> int:
    return _bundle_domain(bundle).material


def _gltf_bake(scene, values, size):
    """The DI lanes decoded by their GLSL at a size x size bake of their uv domain (export-gltf)."""
    from inshade.bundle import load
    from inshade.runtime.network import evaluate_on_pixels
    from inshade.techniques.di_pbr_set.gltf_lanes import decoded_channels

    net = next(n for n in scene.networks if n.prefix == "net")
    bundle = load(net.bundle)
    d = _domain([bundle], [net])
    lanes = evaluate_on_pixels(bundle, size, values.get("lut_filter", "exact"))
    return MaterialBake(decoded_channels(lanes), d.origin, d.extent, d.repeat, d.material)


def _gltf_validate(scene):
    """The DI set (prefix "net": uv[2] -> 8 lanes) with its uv domain, over a glTF mesh."""
    from inshade.bundle import load

    nets = [n for n in scene.networks if n.prefix == "net"]
    if len(nets) != 1:
        raise ValueError(f"networks: {GLTF_PROGRAM} draws one network with prefix \"net\" (the DI set)")
    bundle = load(nets[0].bundle)
    ins, width = [p.dim for p in bundle.inputs], sum(p.dim for p in bundle.outputs)
    if ins != [2] or width < 8:
        raise ValueError(f"bundle {bundle.name!r}: {GLTF_PROGRAM} feeds uv[2] and reads 8 lanes; the bundle has "
                         f"inputs {ins} and {width} output lanes")
    _domain([bundle], nets)


TECHNIQUE = Technique(
    name="di_pbr_set",
    summary="a DI-compressed PBR texture set on a lit, uv-mapped mesh",
    paper=DIFFERENTIABLE_INDIRECTION,
    programs=(ProgramSpec("passes/mesh_pbr_set.frag", geometry="mesh", mesh_attributes=("uv", "tangent"),
                          choices=(Choice("u_pbr_view", "PBR_VIEW", VIEWS),)),
              ProgramSpec(GLTF_PROGRAM, geometry="mesh", mesh_attributes=("materials",),
                          chunks=_gltf_chunks, validate=_gltf_validate, bake=_gltf_bake,
                          channels=MaterialChannels("lib/pbr_set_gltf_channels", _channels_chunks, _channels_material),
                          uniforms={"u_pbr_error_scale": ERROR_SCALE},
                          choices=(Choice("u_pbr_view", "PBR_VIEW", GLTF_VIEWS),))),
    **folder_fields(
        __name__,
        train="a DI-compressed PBR texture set (8 lanes) on a lit mesh, procedural or a glTF file's material",
        shaders=True),
)
