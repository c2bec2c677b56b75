"""``inshade export-three``: a network as a three.js material for an app of your own. The folder holds
``network.json`` (the two GLSL ES 3.00 stages of a ``ShaderMaterial``, the textures' records, the
uniforms, and for a WebGPURenderer the network's WGSL), ``network.bin`` (the texels),
``inshade-three.js`` (imports ``three``: ``loadNetworkMaterial``, ``loadNetworkMesh``, ``applyNetworkMaterial``),
``inshade-three-webgpu.js`` (imports ``three/webgpu`` and ``three/tsl``: ``loadNetworkNodeMaterial``,
``loadNetworkNodeMesh``, ``applyNetworkNodeMaterial``) and ``inshade-three-data.js`` (what both read the
data with). The network is planned against WebGL2's guaranteed limits with its weights as
literals or in a texture (three.js binds no uniform blocks of ours) and ends as three's own materials
do (tone mapping, output colour space).

Drawn today: an image (a uv -> colour network, a scene of ``passes/field2d.frag``) on a plane or any
mesh with uvs, an SDF (a scene of ``passes/sdf_diffuse.frag``, analytic or a network) sphere traced
inside a box around its bound, and a radiance field (``passes/imported_field.frag``) marched inside its
box and laid over the scene behind it; on a WebGPURenderer, each of the three from the network's WGSL
(SDFs: network SDFs only). A glTF material a network decodes (a program with ``MaterialChannels``) goes
onto the user's own glTF scene (``applyNetworkMaterial``): three's PBR shades the network's channels.
Other kinds are refused in one line.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

from inshade.codegen import generate
from inshade.codegen.glsl import SAMPLER_SUFFIX, TextureResource
from inshade.codegen.limits import LimitError
from inshade.codegen.printers.base import Unprintable, library_source
from inshade.codegen.printers.wgsl import WGSLPrinter, thread_textures
from inshade.codegen.targets import TargetError
from inshade.runtime.scene_program import SRGB_SEMANTIC
from inshade.scene.description import load_scene
from inshade.shaders import find_chunk, flatten

from .export import PAGE, _Blob, _texture
from .folders import claim_folder, write_folder
from .limits import WEBGL2, WebLimitError

FORMAT = "inshade-three 1"
MODULE = "inshade-three.js"             # WebGLRenderer (imports "three")
NODE_MODULE = "inshade-three-webgpu.js"  # WebGPURenderer (imports "three/webgpu" and "three/tsl")
DATA_MODULE = "inshade-three-data.js"    # what both read network.json and network.bin with (imports "three")
# three.js binds textures and plain uniforms, not uniform blocks of the shader's own
LIMITS = {**WEBGL2, "GL_MAX_FRAGMENT_UNIFORM_BLOCKS": 0}
_ARGUMENTS = WGSLPrinter(textures_as_arguments=True)   # a node material's textures are three's to bind


# what a scene's program draws -> the material that draws it
KINDS = {"passes/field2d.frag": "image", "passes/sdf_diffuse.frag": "sdf", "passes/imported_field.frag": "field"}


class ThreeExportError(ValueError):
    """A scene the three.js material cannot draw yet; the message says which and why."""


def material(source) -> tuple[dict, bytes]:
    """(network.json, network.bin) of the scene or bundle ``source``, by what its program draws."""
    scene = load_scene(source)
    kind = KINDS.get(scene.program) or ("material" if _channels(scene) else None)
    if kind is None or (kind == "image" and not scene.networks):
        raise ThreeExportError(f"{source}: export-three draws an image (a uv -> colour network, program "
                               f"passes/field2d.frag), an SDF (passes/sdf_diffuse.frag), a radiance field "
                               f"(passes/imported_field.frag) or a glTF material a network decodes (a program "
                               f"with material channels) for now; this scene's program is {scene.program}")
    blob = _Blob()
    manifest = {"format": FORMAT, "name": scene.name, "kind": kind,
                **{"image": _image, "sdf": _sdf, "field": _field, "material": _material}[kind](scene, blob)}
    return manifest, blob.bytes()


def _channels(scene):
    """The scene's program's MaterialChannels, if it has them."""
    from inshade.technique import program_spec

    return program_spec(scene.program)[1].channels


def _textures(blob, resources) -> list[dict]:
    return [_texture(blob, r.name, r) for r in resources if isinstance(r, TextureResource)]


def _image(scene, blob) -> dict:
    """An image: the network at the mesh's uv."""
    from inshade.bundle import load

    ref = scene.networks[0]
    bundle = load(ref.bundle)
    port = next(p for p in bundle.outputs if p.name == (ref.output or bundle.outputs[0].name))
    try:
        g = generate(bundle, prefix="net", target="es300", limits=LIMITS)
    except LimitError as exc:
        raise WebLimitError(f"WebGL2: {exc}") from None
    lanes = bundle.output_lanes(port.name)
    srgb = port.semantic == SRGB_SEMANTIC
    consts = "\n".join([f"const FIELD_OUT_OFFSET: i32 = {lanes[0]};", f"const FIELD_OUT_DIM: i32 = {lanes[1]};",
                        f"const FIELD_OUT_SRGB: bool = {'true' if srgb else 'false'};"])
    defines = {"FIELD_OUT_OFFSET": lanes[0], "FIELD_OUT_DIM": lanes[1],
               **({"FIELD_OUT_SRGB": 1} if srgb else {})}
    return {"bundle_digest": bundle.digest(), "output": port.name, "alpha": lanes[1] == 4,
            "vertexShader": flatten("passes/three_image_vertex"),
            "fragmentShader": flatten("passes/three_image", chunks={"network": g.chunk}, defines=defines),
            "textures": _textures(blob, g.resources), "uniforms": {},
            **_wgsl(blob, lambda: (generate(bundle, prefix="net", target="wgsl", storage="inline"), [consts]),
                    ["lib/colour"], "passes/three_image")}


def _sdf(scene, blob) -> dict:
    """An SDF (analytic or a network), sphere traced in a box around its bound sphere under the scene's
    SH environment (u_sh at the scene's default settings)."""
    import numpy as np

    from inshade.codegen.network_sdf import NetworkSdfScene
    from inshade.runtime.context import shared_context
    from inshade.runtime.renderer import SceneRenderer
    from inshade.runtime.scene_program import geometry_chunks
    from inshade.scene.description import NetworkSdfRef

    try:
        r = SceneRenderer(scene, shared_context(), settings={"labels": False}, limits=LIMITS, target="es300")
    except LimitError as exc:
        raise WebLimitError(f"WebGL2: {exc}") from None
    try:
        chunks, generated = geometry_chunks(scene, r.spec, r.bundles, r.values, LIMITS, "es300", r.sdf_bundle)
        sh = np.frombuffer(r.uniform_values(scene.make_camera(), *scene.size)["u_sh"], np.float32)
    finally:
        r.release()
    bound = NetworkSdfScene.from_bundle(r.sdf_bundle) if isinstance(scene.sdf, NetworkSdfRef) else scene.sdf
    return {"bundle_digest": r.sdf_bundle.digest() if r.sdf_bundle is not None else None, "alpha": False,
            "bound": {"center": [float(c) for c in bound.center], "radius": float(bound.radius)},
            "vertexShader": flatten("passes/three_box_vertex"),
            "fragmentShader": flatten("passes/three_sdf", chunks=chunks),
            "textures": _textures(blob, [res for g in generated for res in g.resources]),
            "uniforms": {"u_sh": sh.reshape(-1, 3).tolist()},
            **_sdf_wgsl(blob, scene, r.sdf_bundle, sh.reshape(-1, 3))}


def _sdf_wgsl(blob, scene, bundle, sh) -> dict:
    """A network SDF's WGSL: lib/sdf's trace of the network, shaded under the environment ``sh`` (its
    radiance coefficients as constants)."""
    from inshade.codegen.constants import literal
    from inshade.codegen.network_sdf import network_sdf_chunks
    from inshade.codegen.sdf import SDF_CHUNK
    from inshade.codegen.spherical_harmonics import sh_chunk_wgsl
    from inshade.scene.description import NetworkSdfRef

    if not isinstance(scene.sdf, NetworkSdfRef):
        return {"wgsl_unavailable": "an analytic SDF has no WGSL yet: the WebGPURenderer material draws network "
                                    "SDFs (use loadNetworkMaterial with a WebGLRenderer)"}
    environment = (f"const SH_ENVIRONMENT: array<vec3<f32>, SH_COEFFS> = array<vec3<f32>, SH_COEFFS>("
                   f"{', '.join(literal('vec3', c, 'wgsl') for c in sh)});")

    def network():
        chunks, g = network_sdf_chunks(bundle, prefix=scene.sdf.prefix, target="wgsl", storage="inline")
        return g, [chunks[SDF_CHUNK], sh_chunk_wgsl(int(scene.environment["degree"])), environment]
    return _wgsl(blob, network, ["lib/sdf", "lib/spherical_harmonics"], "passes/three_sdf")


def _field(scene, blob) -> dict:
    """A radiance field, marched in its box as inshade render marches it; premultiplied by its coverage."""
    from inshade.bundle import load
    from inshade.codegen.field import field_chunks, field_settings

    bundle = load(scene.networks[0].bundle)
    try:
        g = generate(bundle, prefix="net", target="es300", limits=LIMITS)
    except LimitError as exc:
        raise WebLimitError(f"WebGL2: {exc}") from None
    settings = field_settings(bundle)
    return {"bundle_digest": bundle.digest(), "alpha": True, "box": settings["box"],
            "vertexShader": flatten("passes/three_box_vertex"),
            "fragmentShader": flatten("passes/three_field", chunks={"network": g.chunk, **field_chunks(bundle)}),
            "textures": _textures(blob, g.resources), "uniforms": {},
            **_wgsl(blob, lambda: (generate(bundle, prefix="net", target="wgsl", storage="inline"),
                                   list(field_chunks(bundle, "wgsl").values())),
                     ["lib/field_march"], "passes/three_field")}


def _material(scene, blob) -> dict:
    """A glTF material decoded by the network per fragment (its program's MaterialChannels): the
    declarations three's MeshStandardMaterial / MeshPhysicalMaterial program gets before its main, and
    the index of the file's material the network replaces."""
    from inshade.bundle import load

    channels = _channels(scene)
    bundle = load(next(n for n in scene.networks if n.prefix == "net").bundle)
    try:
        g = generate(bundle, prefix="net", target="es300", limits=LIMITS)
    except LimitError as exc:
        raise WebLimitError(f"WebGL2: {exc}") from None
    decoder = {"material_decoder": f"#include <{channels.chunk}>\n"}
    return {"bundle_digest": bundle.digest(), "material": channels.material(bundle),
            "declarations": flatten("passes/three_material", chunks={"network": g.chunk, **decoder,
                                                                     **channels.chunks(bundle, "glsl")}),
            "textures": _textures(blob, g.resources), "uniforms": {},
            **_wgsl(blob, lambda: (generate(bundle, prefix="net", target="wgsl", storage="inline"),
                                   list(channels.chunks(bundle, "wgsl").values())),
                    [channels.chunk], "passes/three_material")}


def _wgsl(blob, network, libraries: list[str], function: str) -> dict:
    """The WGSL a WebGPURenderer's node material calls (``wgslFn``): {"wgsl": {"include", "function",
    "textures"}}, or {"wgsl_unavailable": why}. ``network()`` generates the network for WGSL with its
    dense weights inline: (its Generated, the chunks it needs); the include is the network, those chunks
    and the ``libraries``; the function ``function``'s. Lookup arrays and grids stay textures, which
    three binds: the network takes them as arguments, threaded through every function on the way
    (``thread_textures``); "textures" are their records, each function parameter's texture by name."""
    try:
        g, chunks = network()
        parameters = _ARGUMENTS.texture_parameters(g.module)
    except (TargetError, LimitError, Unprintable) as exc:
        return {"wgsl_unavailable": str(exc)}
    include = "\n".join([_ARGUMENTS.module(g.module).rstrip("\n"), *(c.rstrip("\n") for c in chunks),
                         *library_source(libraries, (".wgsl",))])
    return {"wgsl": {"include": thread_textures(include, parameters) + "\n",
                     "function": thread_textures(find_chunk(function, ".wgsl").read_text(), parameters),
                     "arguments": {n: n.removesuffix(SAMPLER_SUFFIX) for n, _ in parameters},
                     "textures": _textures(blob, g.resources)}}


def export_three(source, out, *, force: bool = False) -> dict:
    """Write the material of ``source`` into the folder ``out`` (atomically; a folder holding files is
    replaced only with ``force``); returns network.json's content."""
    claim_folder(out, force)
    manifest, data = material(source)

    def fill(folder: Path) -> None:
        folder.mkdir()
        (folder / "network.json").write_text(json.dumps(manifest, indent=1) + "\n")
        (folder / "network.bin").write_bytes(data)
        for module in (MODULE, NODE_MODULE, DATA_MODULE):
            shutil.copyfile(PAGE / module, folder / module)

    write_folder(out, fill)
    return manifest
