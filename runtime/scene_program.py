"""The scene pass's program, from the scene, its settings and its bundles: each network generated
for this machine's limits, the chunks of its geometry and shading, the defines its settings and
G-buffer set, what the networks need together checked, then assembled and compiled once per
source (runtime/programs.py)."""
from __future__ import annotations

from typing import NamedTuple

import moderngl

from inshade.codegen.network import generate
from inshade.codegen.network_sdf import network_sdf_chunks
from inshade.codegen.sdf import sdf_chunks
from inshade.codegen.spherical_harmonics import sh_chunks
from inshade.shaders import assemble
from inshade.scene.description import NetworkSdfRef, SceneError, codegen_option_path
from inshade.technique import choice_chunks

from .geometry import gbuffer_layout
from .programs import ProgramCache, program_key

VERTEX = "common/fullscreen.vert"
SRGB_SEMANTIC = "srgb"   # an output port whose values are sRGB-encoded (e.g. fitted to sRGB pixels)


class SceneProgram(NamedTuple):
    generated: list     # every network's Generated, a network SDF's last (its GL resources bind alike)
    program: moderngl.Program
    defines: dict       # what it was assembled with (``SceneRenderer.assembled``)
    chunks: dict


def codegen_options(scene, values: dict, gl: dict) -> dict:
    """What codegen plans each network with: the settings bound to codegen options and this
    machine's GL_MAX_* limits, software or not (auto storage)."""
    options = {}
    for n, s in scene.settings.items():
        if s.binding == "codegen":
            component, option = codegen_option_path(s.target)
            options.setdefault(component, {})[option] = values[n]
    return {"limits": dict(gl), "options": options}


def generate_networks(scene, bundles, values: dict, gl: dict, target: str) -> list:
    options = codegen_options(scene, values, gl)
    return [generate(b, prefix=n.prefix, target=target, **options) for b, n in zip(bundles, scene.networks)]


def geometry_chunks(scene, spec, bundles, values: dict, gl: dict, target: str, sdf_bundle) -> tuple[dict, list]:
    """Chunks for the scene's geometry and shading besides the networks': the SDF (analytic, or
    a network SDF with its Generated, returned to get GL resources), the SH basis, the
    program's declared choices (<choices>) and what its technique generates
    (``ProgramSpec.chunks``, e.g. PRT's <prt_network>)."""
    chunks, extra = {}, []
    sdf = scene.sdf
    if isinstance(sdf, NetworkSdfRef):
        sdf_ch, gen = network_sdf_chunks(sdf_bundle, prefix=sdf.prefix, target=target,
                                         **codegen_options(scene, values, gl))
        chunks.update(sdf_ch)
        extra.append(gen)
    elif sdf is not None:
        chunks.update(sdf_chunks(sdf))
    if scene.lit:
        chunks.update(sh_chunks(int(scene.environment["degree"])))
    chunks.update(choice_chunks(spec))
    if spec.chunks is not None:
        try:
            chunks.update(spec.chunks(scene, bundles, scene.networks, codegen_options(scene, values, gl)))
        except ValueError as exc:
            raise SceneError(f"{scene.source or scene.name}: {exc}") from None
    return chunks, extra


def gbuffer_defines(scene, spec) -> dict:
    """What the G-buffer's readers are told of its targets (runtime/geometry.py gbuffer_layout)."""
    if scene.mesh is None:
        return {}
    return gbuffer_layout(scene.mesh.data, spec.visibility)[2]


def program_defines(scene, spec, bundles, values: dict) -> dict:
    """The defines of the scene program: its "define" settings, the G-buffer's layout and which
    lanes of the primary network's output it reads (decoded from sRGB where the port says so)."""
    defines = {s.target: values[n] if s.declared is None else s.index(values[n])
               for n, s in scene.settings.items() if s.binding == "define"}
    defines.update(gbuffer_defines(scene, spec))
    if not bundles:
        return defines
    primary, ref = bundles[0], scene.networks[0]
    name = ref.output or primary.outputs[0].name
    lanes = primary.output_lanes(name)
    if lanes is None:
        raise SceneError(f"scene '{scene.name}': network {primary.name!r} has no output {name!r} "
                         f"(outputs: {', '.join(p.name for p in primary.outputs)})")
    defines.update(FIELD_OUT_OFFSET=lanes[0], FIELD_OUT_DIM=lanes[1])
    port = next(p for p in primary.outputs if p.name == name)
    if port.semantic == SRGB_SEMANTIC:   # the network outputs sRGB-encoded colour: decoded for display
        defines["FIELD_OUT_SRGB"] = 1
    return defines


def check_program_limits(generated, gl: dict, scene) -> None:
    """What the scene's networks need together, checked before compiling: codegen plans each
    network against the limits alone, but one program holds them all (e.g. six networks of three
    uniform blocks each: 18 blocks where llvmpipe allows 15)."""
    from inshade.codegen.glsl import TextureResource, UniformBlockResource
    from inshade.codegen.limits import limit

    blocks = sum(isinstance(r, UniformBlockResource) for g in generated for r in g.resources)
    cap = limit(gl, "GL_MAX_FRAGMENT_UNIFORM_BLOCKS")
    if blocks > cap:
        raise SceneError(f"scene '{scene.name}': its {len(generated)} networks need {blocks} uniform blocks "
                         f"together; GL_MAX_FRAGMENT_UNIFORM_BLOCKS is {cap} (choose storage 'auto', "
                         f"'inline' or 'texture')")
    samplers = sum(isinstance(r, TextureResource) for g in generated for r in g.resources) + len(scene.textures)
    samplers += scene.spec.shadows is not None   # lib/shadow_map: u_shadow_map
    samplers += 2 * ("materials" in scene.spec.mesh_attributes)   # lib/gltf_material's two textures
    cap = limit(gl, "GL_MAX_TEXTURE_IMAGE_UNITS")
    if samplers > cap:
        raise SceneError(f"scene '{scene.name}': its networks and textures need {samplers} texture units "
                         f"together; GL_MAX_TEXTURE_IMAGE_UNITS is {cap}")


def build_scene_program(scene, spec, bundles, *, values: dict, gl: dict, target: str, sdf_bundle,
                        cache: ProgramCache) -> SceneProgram:
    """Generate every network, gather the chunks and defines, check the limits, compile (the
    cache returns the program it has when the sources are the same). Raises on any failure."""
    generated, defines, chunks = plan_scene_program(scene, spec, bundles, values=values, gl=gl, target=target,
                                                    sdf_bundle=sdf_bundle)
    program = cache.get(VERTEX, scene.program, version=target, defines=defines, chunks=chunks)
    return SceneProgram(generated, program, defines, chunks)


def plan_scene_program(scene, spec, bundles, *, values: dict, gl: dict, target: str, sdf_bundle):
    """What build_scene_program compiles: (generated networks, defines, chunks), the limits checked."""
    generated = generate_networks(scene, bundles, values, gl, target)
    chunks = {n.chunk: g.chunk for n, g in zip(scene.networks, generated)}
    geometry, extra = geometry_chunks(scene, spec, bundles, values, gl, target, sdf_bundle)
    chunks.update(geometry)
    generated = generated + extra   # GL resources of a network SDF bind like a network's
    check_program_limits(generated, gl, scene)
    return generated, program_defines(scene, spec, bundles, values), chunks


def planned_program(scene, defines: dict, chunks: dict, target: str) -> tuple[str, str]:
    """The draw history's name of the program these sources make (ProgramCache.key_of's) and its
    fragment stage, assembled, not compiled."""
    fragment = assemble(scene.program, version=target, defines=defines, chunks=chunks)
    return program_key((assemble(VERTEX, version=target, defines=defines, chunks=chunks).key, fragment.key)), \
        fragment.source
