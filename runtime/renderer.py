"""SceneRenderer: the one per-frame render function shared by ``inshade render`` and ``inshade view``.

It owns the GL side of a scene: the generated network(s) and their resources, the scene program
(the network pass), the display pass (modes, compare, heat map), the reference texture and the
float targets. ``render(camera, w, h, mode)`` draws into a linear RGBA32F target; the headless path
reads it back and writes files, the window app blits it to the screen. There is no render code in
the window app.

Cost model (matters on llvmpipe, where the first draw of a network program JIT-compiles for seconds):
the network pass is redrawn only when its inputs change (camera, size, weights, program, network
uniforms); mode, split, exposure and error scale only redraw the cheap display pass. A stochastic
program (``ProgramSpec.accumulate``) is the exception: each call draws one more sample (seeded by
``u_sample_index``) and folds it into the running mean in the "network" target (``samples``), up to
``sample_cap``; a change of those inputs restarts the mean (``accumulate`` draws N samples).
"""
from __future__ import annotations

import hashlib
import json
import logging
import math
from pathlib import Path

import moderngl
import numpy as np
from PIL import Image

from inshade.bundle import Bundle, load
from inshade.codegen.network import generate
from inshade.codegen.network_sdf import network_sdf_chunks
from inshade.codegen.sdf import SDF_CHUNK, environment_sh, sdf_chunks
from inshade.codegen.spherical_harmonics import sh_chunks
from inshade.progress import format_seconds
from inshade.technique import FrameInputs, choice_chunks

from .context import GLContextError, gl_info, make_current, shared_context
from inshade.scene.display import DisplayMode, glsl_chunk, parse_mode
from .environment import EnvironmentSampler, EnvironmentTextures, environment_image, scene_environment
from .geometry import MeshGBuffer, gbuffer_layout
from .materials import MaterialTextures
from inshade.scene.image_io import read_exr
from .network import NetworkResources
from .programs import ProgramCache
from .render import (FullscreenPass, check_gl_error, clear_gl_error, float_target, read_rgba, read_rgba_raw,
                     release_target)
from inshade.scene.description import MAX_LIGHTS, NetworkSdfRef, Scene, SceneError, codegen_option_path
from .shadow import ShadowMaps

VERTEX = "common/fullscreen.vert"
log = logging.getLogger("inshade")


class CapabilityError(GLContextError):
    """The context lacks something the scene needs (GL version, extension, limit)."""


def check_capabilities(ctx: moderngl.Context, scene: Scene) -> None:
    need = scene.requires
    gl = int(need.get("gl", 330))
    if ctx.version_code < gl:
        raise CapabilityError(f"scene '{scene.name}' needs OpenGL {gl // 100}.{gl % 100 // 10}; "
                              f"this context is {ctx.version_code // 100}.{ctx.version_code % 100 // 10} "
                              f"({ctx.info['GL_RENDERER']})")
    missing = [e for e in need.get("extensions", []) if e not in ctx.extensions]
    if missing:
        raise CapabilityError(f"scene '{scene.name}' needs {', '.join(missing)}, which "
                              f"{ctx.info['GL_RENDERER']} does not offer")
    for name, low in need.get("limits", {}).items():
        have = ctx.info.get(name)
        if have is None or int(have) < int(low):
            raise CapabilityError(f"scene '{scene.name}' needs {name} >= {low}; this context has {have}")


def load_reference(path: Path, colour: str = "srgb") -> np.ndarray:
    """Reference image as linear float32 RGB [H, W, 3], image orientation (row 0 = top)."""
    if colour == "linear":
        return np.asarray(read_exr(path), np.float32)[..., :3]
    encoded = np.asarray(Image.open(path).convert("RGB"), np.float64) / 255.0
    linear = np.where(encoded <= 0.04045, encoded / 12.92, ((encoded + 0.055) / 1.055) ** 2.4)
    return linear.astype(np.float32)


class SceneRenderer:
    """GL objects and state to draw one scene; call ``release()`` when done (no GL leaks).

    ``settings`` overrides the scene's defaults (checked against their ranges/choices).
    ``bundles`` gives already-loaded bundles (else each network's bundle is loaded from disk).
    ``owns_programs``: discard replaced programs from ``cache`` on rebuild (a window app with its
    own cache); leave False when the cache is shared with other code.
    ``limits`` overrides the context's GL limits codegen plans against (``gl_info``), e.g. a lowered
    GL_MAX_TEXTURE_SIZE to exercise a layout that fits it.
    ``target`` is the GLSL every program is assembled and generated for ("330", "450", "es300": the
    WebGL2 export draws the ES programs here first; desktop Mesa compiles them).
    """

    def __init__(self, scene: Scene, ctx: moderngl.Context | None = None, *, cache: ProgramCache | None = None,
                 settings: dict | None = None, bundles: list[Bundle] | None = None,
                 owns_programs: bool = False, limits: dict | None = None, target: str = "330"):
        self.ctx = shared_context() if ctx is None else make_current(ctx)
        self.scene = scene
        self.target = target
        self.spec = scene.spec        # what the program needs (its technique's ProgramSpec)
        self.gl = {**gl_info(self.ctx), **(limits or {})}   # `limits` overrides (e.g. lowered on purpose)
        check_capabilities(self.ctx, scene)
        self.cache = cache if cache is not None else ProgramCache(self.ctx)
        self.owns_programs = owns_programs
        self.values = scene.check_settings(settings or {})
        self.bundles = bundles or [load(n.bundle) for n in scene.networks]
        self.sdf_bundle = load(scene.sdf.bundle) if isinstance(scene.sdf, NetworkSdfRef) else None
        self.error = None              # the last failed rebuild (ShaderCompileError ...), cleared on success
        self.weights_version = 0
        self.compile_seconds = 0.0
        self.first_draw_seconds = None  # wall time of the first network draw (llvmpipe JITs there)
        self.first_draw_pending = True
        self.program = None
        self.program_key = ""          # a stable name of the program's sources (the draw history's key)
        self.generated = []
        self.resources: list[NetworkResources] = []
        self._net_pass = None
        self._net_key = None
        self._targets: dict[str, moderngl.Framebuffer] = {}
        self.samples = 0               # samples in the "network" target since the last reset (accumulate)
        self.sample_cap = None         # accumulating programs stop adding samples here (None: one per render)
        self._accumulate_pass = None   # passes/accumulate.frag, built on the first accumulated sample
        self._blend_passes = None      # passes/gltf_blend_layer + gltf_blend_resolve, built on the first peel
        self.gbuffer = None            # mesh scenes: the G-buffer pass drawn before the scene pass
        self.shadow_maps = ShadowMaps(self.ctx)   # ProgramSpec.shadows: GL objects made on first use, then reused
        self._build()
        clear_gl_error(self.ctx, f"the textures of scene '{scene.name}'")
        self.scene_textures = {t.uniform: _scene_texture(self.ctx, t) for t in scene.textures}
        self.materials = None          # MaterialTextures of a glTF mesh's materials (lib/gltf_material)
        if "materials" in self.spec.mesh_attributes:
            self.materials = MaterialTextures(self.ctx, scene.mesh.gltf, self.gl)
            self.scene_textures.update(self.materials.textures)
            if self.materials.blended and not self.blend_layers:
                self.materials.notes.append(f"{scene.program} accumulates samples: its alphaMode BLEND surfaces "
                                            "are drawn opaque")
            for note in [*scene.mesh.gltf.notes, *self.materials.notes]:   # conversions, generated tangents, ...
                log.info("%s: %s", scene.mesh.name, note)
        if scene.mesh is not None:
            self.gbuffer = MeshGBuffer(self.ctx, scene.mesh.data, self.cache, version=target,
                                      visibility=self.spec.visibility, materials=self.materials,
                                      peel=self.blend_layers > 0)
        check_gl_error(self.ctx, f"scene '{scene.name}': textures {[t.image.name for t in scene.textures]}")
        self.environment = None        # EnvironmentTextures while the program samples lib/environment
        self._environment_key = None
        self._sync_environment()
        self.display_program = self.cache.get(VERTEX, "passes/display.frag", version=target,
                                              chunks={"display_modes": glsl_chunk()})
        self._display_pass = FullscreenPass(self.ctx, self.display_program)
        self.reference_image = None
        if scene.reference is not None:
            self.reference_image = load_reference(scene.reference.image, scene.reference.colour)
            self._reference_tex = self.ctx.texture(
                self.reference_image.shape[1::-1], 3,
                np.ascontiguousarray(self.reference_image[::-1]).tobytes(), dtype="f4")  # uv (0,0) = bottom-left
            self._reference_tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        else:
            self._reference_tex = self.ctx.texture((1, 1), 3, np.zeros(3, "f4").tobytes(), dtype="f4")
        self._reference_tex.repeat_x = self._reference_tex.repeat_y = False
        check_gl_error(self.ctx, f"scene '{scene.name}': reference texture")

    # building ---------------------------------------------------------------------------------------
    def _codegen_options(self) -> dict:
        options = {}
        for n, s in self.scene.settings.items():
            if s.binding == "codegen":
                component, option = codegen_option_path(s.target)
                options.setdefault(component, {})[option] = self.values[n]
        return {"limits": dict(self.gl), "options": options}  # GL_MAX_* limits, software or not (auto storage)

    def _generate(self, bundles):
        options = self._codegen_options()
        return [generate(b, prefix=n.prefix, target=self.target, **options)
                for b, n in zip(bundles, self.scene.networks)]

    def _geometry_chunks(self, bundles) -> tuple[dict, list]:
        """Chunks for the scene's geometry and shading besides the networks': the SDF (analytic, or
        a network SDF with its Generated, returned to get GL resources), the SH basis, the
        program's declared choices (<choices>) and what its technique generates
        (``ProgramSpec.chunks``, e.g. PRT's <prt_network>)."""
        chunks, extra = {}, []
        sdf = self.scene.sdf
        if isinstance(sdf, NetworkSdfRef):
            sdf_ch, gen = network_sdf_chunks(self.sdf_bundle, prefix=sdf.prefix, target=self.target,
                                                **self._codegen_options())
            chunks.update(sdf_ch)
            extra.append(gen)
        elif sdf is not None:
            chunks.update(sdf_chunks(sdf))
        if self.scene.lit:
            chunks.update(sh_chunks(int(self.scene.environment["degree"])))
        chunks.update(choice_chunks(self.spec))
        if self.spec.chunks is not None:
            try:
                chunks.update(self.spec.chunks(self.scene, bundles, self.scene.networks, self._codegen_options()))
            except ValueError as exc:
                raise SceneError(f"{self.scene.source or self.scene.name}: {exc}") from None
        return chunks, extra

    def _gbuffer_defines(self) -> dict:
        """What the G-buffer's readers are told of its targets (runtime/geometry.py gbuffer_layout)."""
        if self.scene.mesh is None:
            return {}
        return gbuffer_layout(self.scene.mesh.data, self.spec.visibility)[2]

    def _defines(self, bundles) -> dict:
        defines = {s.target: self.values[n] if s.declared is None else s.index(self.values[n])
                   for n, s in self.scene.settings.items() if s.binding == "define"}
        defines.update(self._gbuffer_defines())
        if not bundles:
            return defines
        primary, ref = bundles[0], self.scene.networks[0]
        name = ref.output or primary.outputs[0].name
        lanes = primary.output_lanes(name)
        if lanes is None:
            raise SceneError(f"scene '{self.scene.name}': network {primary.name!r} has no output {name!r} "
                             f"(outputs: {', '.join(p.name for p in primary.outputs)})")
        defines.update(FIELD_OUT_OFFSET=lanes[0], FIELD_OUT_DIM=lanes[1])
        port = next(p for p in primary.outputs if p.name == name)
        if port.semantic == SRGB_SEMANTIC:   # the network outputs sRGB-encoded colour: decoded for display
            defines["FIELD_OUT_SRGB"] = 1
        return defines

    def _build(self, bundles=None) -> str:
        """(Re)generate and compile. On failure nothing changes (the last good program keeps
        drawing), ``self.error`` is set and the error is raised. Returns "unchanged",
        "reuploaded" or "recompiled"."""
        bundles = bundles or self.bundles
        try:
            generated = self._generate(bundles)
            chunks = {n.chunk: g.chunk for n, g in zip(self.scene.networks, generated)}
            geometry, extra = self._geometry_chunks(bundles)
            chunks.update(geometry)
            generated = generated + extra   # GL resources of a network SDF bind like a network's
            check_program_limits(generated, self.gl, self.scene)
            defines = self._defines(bundles)
            program = self.cache.get(VERTEX, self.scene.program, version=self.target, defines=defines, chunks=chunks)
            self._sources = (defines, chunks)
        except Exception as exc:
            self.error = exc
            raise
        self.error = None
        self.compile_seconds = self.cache.last_compile_seconds
        same_code = [g.chunk for g in generated] == [g.chunk for g in self.generated]
        if self.resources and same_code:
            for res, g in zip(self.resources, generated):
                res.upload(g)   # ubo: rewritten in place; textures: replaced; no recompile
        else:
            for res in self.resources:
                res.release()
            self.resources = [NetworkResources(self.ctx, g) for g in generated]
        outcome = "unchanged" if program is self.program else "recompiled"
        if program is not self.program:
            if self._net_pass is not None:
                self._net_pass.vao.release()
            if self.program is not None and self.owns_programs:
                self.cache.discard(self.program)
            self.program = program
            self.program_key = self.cache.key_of(program)
            self._net_pass = FullscreenPass(self.ctx, program)
            self.first_draw_pending = True
        elif self.bundles is not bundles:
            outcome = "reuploaded"
        self.generated, self.bundles = generated, bundles
        self._net_key = None
        return outcome

    @property
    def pixel_flops(self) -> int:
        """The plans' upper bound on what one pixel of the scene pass spends in its networks."""
        return sum(g.plan.pixel_flops for g in self.generated)

    def assembled(self) -> dict:
        """The scene pass as the driver compiles it, every include resolved: {"vertex": source,
        "fragment": source} (``inshade codegen ASSET --program``)."""
        from inshade.shaders import assemble

        defines, chunks = self._sources
        return {"vertex": assemble(VERTEX, version=self.target, defines=defines, chunks=chunks).source,
                "fragment": assemble(self.scene.program, version=self.target, defines=defines, chunks=chunks).source}

    def uniform_values(self, camera, width: int, height: int) -> dict:
        """The scene pass's uniforms as this renderer sets them for ``camera`` at this size (bytes
        values are float32 arrays), without samplers."""
        return self._uniforms(self.program, camera, width, height)

    def set_setting(self, name: str, value) -> str:
        """Change one setting: "uniform" (takes effect next frame) or what a rebuild did."""
        if name not in self.scene.settings:
            raise SceneError(f"unknown setting {name!r} (this scene has: {', '.join(self.scene.settings)})")
        setting = self.scene.settings[name]
        value = setting.check(value)
        if setting.binding in ("uniform", "environment", "frame", "present"):
            self.values[name] = value
            if setting.binding == "environment" and self.environment is not None:
                self._sync_environment()   # the importance-sampled texture follows sky / rotation
                self._net_key = None
            return "uniform"
        old = self.values[name]
        if old == value:
            return "unchanged"
        self.values[name] = value
        try:
            return self._build()
        except Exception:
            self.values[name] = old
            raise

    def _sync_environment(self) -> EnvironmentTextures | None:
        """(Re)build the environment textures when the program uses them and sky/rotation changed."""
        if self.program is None or "u_env_radiance" not in self.program:
            return self.environment
        try:
            env = scene_environment(self.scene, self.values)
        except ValueError as exc:
            raise SceneError(str(exc)) from None
        key = (env.get("sky"), float(env.get("rotation", 0.0)), env.get("map"))
        if self.environment is None or key != self._environment_key:
            textures = EnvironmentTextures(self.ctx, EnvironmentSampler(environment_image(env)))
            if self.environment is not None:
                self.environment.release()
            self.environment, self._environment_key = textures, key
        return self.environment

    def reload_weights(self) -> str:
        """Re-read every bundle from disk; re-upload without recompiling when the code is unchanged
        (ubo/texture storage), else recompile (inline storage bakes weights into the code)."""
        if isinstance(self.scene.sdf, NetworkSdfRef):
            self.sdf_bundle = load(self.scene.sdf.bundle)
        outcome = self._build([load(n.bundle) for n in self.scene.networks])
        self.weights_version += 1
        return outcome

    def reload_shaders(self) -> str:
        """Re-assemble the programs from the chunk files (after a .glsl edit)."""
        outcome = self._build(self.bundles)
        try:
            display = self.cache.get(VERTEX, "passes/display.frag", version=self.target,
                                     chunks={"display_modes": glsl_chunk()})
        except Exception as exc:
            self.error = exc
            raise
        if display is not self.display_program:
            self._display_pass.vao.release()
            if self.owns_programs:
                self.cache.discard(self.display_program)
            self.display_program = display
            self._display_pass = FullscreenPass(self.ctx, display)
            outcome = "recompiled"
        self._net_key = None
        return outcome

    # drawing ----------------------------------------------------------------------------------------
    def _target(self, name: str, width: int, height: int, attachments: int = 1) -> moderngl.Framebuffer:
        fbo = self._targets.get(name)
        if fbo is not None and fbo.size == (width, height) and len(fbo.color_attachments) == attachments:
            return fbo
        if fbo is not None:
            release_target(fbo)
        fbo = self._targets[name] = float_target(self.ctx, width, height, attachments=attachments)
        return fbo

    def _uniforms(self, program, camera, width, height) -> dict:
        out = {"u_size": (float(width), float(height))}
        out.update(self.spec.uniforms)
        out.update(camera.uniforms(width, height))
        for name, s in self.scene.settings.items():
            if s.binding == "uniform":
                v = self.values[name]
                if isinstance(v, bool):
                    v = int(v)
                elif s.type == "choice":   # a choice drives an int uniform: its (declared) index
                    v = s.index(v)
                out[s.target] = v
        if "u_lights" in program:   # lib/lights.glsl: the scene's lights
            from inshade.scene.description import light_uniforms
            # a program that never calls scene_light (u_light_kinds unused) reads u_lights as positions
            if any(light.kind != "point" for light in self.scene.lights) and "u_light_kinds" not in program:
                raise SceneError(f"lights: {self.scene.program} treats every light as a point light (it reads "
                                 "u_lights without scene_light from lib/lights); use point lights only")
            out.update(light_uniforms(self.scene.lights))
        if self.scene.lit:
            sh = self.environment_sh()
            out["u_sh"] = sh.tobytes()
        if self.spec.frame is not None:   # per-frame CPU work of the technique (e.g. a light matrix)
            out.update(self.spec.frame(FrameInputs(self.scene, self.values, sh if self.scene.lit else None)))
        return {k: v for k, v in out.items() if k in program}

    def environment_sh(self) -> np.ndarray:
        """SDF scenes: the radiance SH [K, 3] float32 of the environment (scene + settings)."""
        env = dict(self.scene.environment)
        for name, s in self.scene.settings.items():
            if s.binding == "environment":
                env[s.target] = self.values[name]
        if env["sky"] == "map":   # environment.map, projected at load time (scene/description.py)
            sh = _rotated_map_sh(self.scene.environment_map, float(env["rotation"]))
        else:
            sh = environment_sh(env["sky"], float(env["rotation"]), int(env["degree"]))
        gain = float(env.get("intensity", 1.0))
        return sh if gain == 1.0 else (sh * np.float32(gain)).astype(np.float32)

    def render_network(self, camera, width: int, height: int, *, force: bool = False) -> moderngl.Framebuffer:
        """The scene pass alone (linear float, alpha = coverage); redrawn only when its inputs change,
        or every call with ``force`` (timing repeated draws of the same view)."""
        make_current(self.ctx)
        fbo = self._target("network", width, height, self.spec.attachments)
        uniforms = self._uniforms(self.program, camera, width, height)
        shadows = self._sync_shadows()
        key = (id(self.program), width, height, self.weights_version, repr(sorted(uniforms.items())), shadows)
        draw_into = fbo
        if self.spec.accumulate:   # stochastic: one more sample per call into a scratch target, folded into the mean
            if force or key != self._net_key:
                self.samples = 0
            if self.sample_cap is not None and self.samples >= self.sample_cap:
                return fbo
            if "u_sample_index" in self.program:
                uniforms["u_sample_index"] = self.samples
            draw_into = self._target("sample", width, height, self.spec.attachments)
        if force or key != self._net_key or self.spec.accumulate:
            self.ctx.scissor = None
            gbuffer = self.gbuffer.draw_camera(camera, width, height) if self.gbuffer is not None else None
            self.ctx.viewport = (0, 0, width, height)
            self._bind_scene_resources(gbuffer)
            if self.blend_layers:
                opaque = self._target("opaque", width, height, self.spec.attachments)
                self._draw_timed(opaque, uniforms, width * height, key)
                self._peel(camera, width, height, uniforms, opaque, draw_into)
            else:
                self._draw_timed(draw_into, uniforms, width * height, key)
            self._net_key = key
            if self.spec.accumulate:
                return self._fold_sample(draw_into, width, height)
            self.samples = 1
        return fbo

    def _bind_scene_resources(self, gbuffer) -> None:
        """Bind what the scene program samples: its networks' resources, the scene's textures, the
        environment, the shadow maps and the G-buffer's textures (``gbuffer``, or none)."""
        unit = 0
        for block, res in enumerate(self.resources):
            unit = res.bind(self.program, first_unit=unit, first_block=block * 16)
        for name, tex in self.scene_textures.items():   # scene.json "textures"
            if name in self.program:
                tex.use(location=unit)
                self.program[name].value = unit
                unit += 1
        if "u_env_radiance" in self.program:   # lib/environment: the importance-sampled environment
            unit = self._sync_environment().bind(self.program, unit)
        if "u_shadow_map" in self.program or "u_shadow_layers" in self.program:   # lib/shadow_map
            unit = self.shadow_maps.bind(self.program, unit)
        if gbuffer is not None:   # deferred mesh pass: texelFetch'ed by the scene program
            for name, tex in zip([f"u_gbuffer_{n}" for n in self.gbuffer.names], gbuffer):
                if name in self.program:
                    tex.use(location=unit)
                    self.program[name].value = unit
                    unit += 1

    @property
    def blend_layers(self) -> int:
        """BLEND surfaces of a glTF mesh are depth-peeled into this many layers, each shaded by the
        scene program and laid under the ones in front (front to back), then over the opaque
        surfaces; 0 where there are none, or where the program accumulates samples (there they are
        drawn opaque, as the G-buffer's one surface a pixel)."""
        blended = self.materials is not None and self.materials.blended and self.scene.mesh is not None
        return BLEND_LAYERS if blended and not self.spec.accumulate and self.spec.attachments == 1 else 0

    def _peel(self, camera, width: int, height: int, uniforms: dict, opaque, out) -> None:
        """The BLEND layers (MeshGBuffer.draw_layer) through the scene program, composited into ``out``."""
        if self._blend_passes is None:
            self._blend_passes = tuple(FullscreenPass(self.ctx, self.cache.get(
                VERTEX, f"passes/{name}.frag", defines=self._gbuffer_defines() or None))
                for name in ("gltf_blend_layer", "gltf_blend_resolve"))
        layer_pass, resolve_pass = self._blend_passes
        accum = [self._target("blend_accum_a", width, height), self._target("blend_accum_b", width, height)]
        accum[0].clear(0.0, 0.0, 0.0, 1.0)
        shaded = self._target("blend_layer", width, height)
        view, proj = camera.view_matrix(), camera.projection(width, height)
        read = [n for n in self.gbuffer.names if n in BLEND_LAYER_READS]   # u_layer_<name>
        for k in range(1, self.blend_layers + 1):
            layer = self.gbuffer.draw_layer(k, view, proj, None, width, height)
            self.ctx.viewport = (0, 0, width, height)
            self._bind_scene_resources(layer)
            self._net_pass.render(shaded, uniforms=uniforms)
            src, dst = accum[(k - 1) % 2], accum[k % 2]
            layer_pass.render(dst, textures={**self.materials.textures, "u_accum": src.color_attachments[0],
                                             "u_layer_colour": shaded.color_attachments[0],
                                             **{f"u_layer_{n}": layer[self.gbuffer.names.index(n)] for n in read}})
        resolve_pass.render(out, textures={"u_accum": accum[self.blend_layers % 2].color_attachments[0],
                                           "u_opaque": opaque.color_attachments[0]})

    def _draw_timed(self, target, uniforms, pixels: int, view_key) -> None:
        """The scene pass, with what to expect said first: on a software renderer the first draw of
        a program JIT-compiles it (the message says what happened last time on this machine, and a
        watcher process shows the seconds going by); a view whose last draw took minutes is warned
        about before it starts. Times are kept in runtime/draw_history.py."""
        from inshade.progress import waiting

        from . import draw_history

        renderer, program_key = self.gl.get("renderer", ""), self.program_key
        view = f"{program_key}:{hash_values(self.values)}"   # a frame's time depends on the settings too
        frame = draw_history.lookup(renderer, view) if program_key else {}
        estimate = frame["frame_s"] * pixels / frame["pixels"] if frame.get("frame_s") and frame.get("pixels") else 0.0
        announce, cached = self._first_draw_note()
        if announce:
            log.info("%s", announce)
        if estimate >= SLOW_FRAME_S and view_key != self._net_key:
            log.warning("this view took about %s to draw last time at these settings (scaled to this size)",
                        format_seconds(estimate))
        what = "compiling" if announce and announce.startswith("compiling") else "drawing"
        marked = self.first_draw_pending and program_key and self.gl.get("software")
        if marked:   # a software driver compiles at the first draw: a crash here is a compile's
            warning = draw_history.compile_started(renderer, program_key, f"{self.scene.name} ({self.scene.program})")
            if warning:
                log.warning("%s", warning)
        try:
            with waiting(f"{what} {self.scene.name}", enabled=bool(announce) or estimate >= SLOW_FRAME_S) as w:
                self._net_pass.render(target, uniforms=uniforms)
                if self.first_draw_pending or w.enabled:
                    self.ctx.finish()
        finally:   # an exception is not a crash: the mark goes either way
            if marked:
                draw_history.compile_finished(renderer, program_key)
        if self.first_draw_pending:
            self.first_draw_seconds = w.seconds
            self.first_draw_pending = False
            _DRAWN.add(program_key)
            if announce and w.seconds >= 2.0:
                # a first draw far past this view's known frame time was a compile the cache missed
                missed = cached and w.seconds > 3.0 * estimate
                log.info("compiled and drawn in %s%s", format_seconds(w.seconds),
                         " (Mesa's shader cache did not have it)" if missed else "")
            if program_key and self.gl.get("software"):
                draw_history.record(renderer, program_key, first_draw_s=round(w.seconds, 3),
                                     shader_cache=draw_history.shader_cache_on())
        elif w.enabled or w.seconds >= 1.0:   # a slow frame is remembered, to warn next time
            if program_key:
                draw_history.record(renderer, view, frame_s=round(w.seconds, 3), pixels=pixels)

    def _first_draw_note(self) -> tuple[str | None, bool]:
        """(what the pending first draw will do on a software renderer, or None; whether Mesa's
        shader cache had this program last time)."""
        from . import draw_history

        if not (self.first_draw_pending and self.gl.get("software")):
            return None, False
        renderer, program_key = self.gl.get("renderer", ""), self.program_key
        if program_key in _DRAWN:   # this process drew it already: the driver has it, nothing to say
            return None, False
        past = draw_history.lookup(renderer, program_key) if program_key else {}
        cached = draw_history.shader_cache_on() and past.get("shader_cache") is True
        return first_draw_message(self.generated, renderer, past.get("first_draw_s"), cached), cached

    @property
    def first_draw_note(self) -> str | None:
        """What the next draw is about to do (a JIT compile, and what it took last time), or None."""
        return self._first_draw_note()[0]

    def _sync_shadows(self) -> int:
        """Redraws the shadow maps if the program's request changed; their version (a redraw key)."""
        if self.spec.shadows is not None:
            request = self.spec.shadows(self.scene, self.bundles, self.values)
            if request is None:
                self.shadow_maps.clear()
            else:
                self.shadow_maps.update(request)
        return self.shadow_maps.version

    def _fold_sample(self, sample: moderngl.Framebuffer, width: int, height: int) -> moderngl.Framebuffer:
        """Running mean of every attachment: "network" (mean of n - 1 samples) + ``sample`` -> the
        spare target, which then becomes "network" (ping-pong: a pass cannot read its own target)."""
        n = self.spec.attachments
        if self._accumulate_pass is None:
            program = self.cache.get(VERTEX, "passes/accumulate.frag", version=self.target,
                                     defines={"ACCUMULATE_ATTACHMENTS": n})
            self._accumulate_pass = FullscreenPass(self.ctx, program)
        mean = self._target("network", width, height, n)
        spare = self._target("network_spare", width, height, n)
        self.samples += 1
        textures = {}
        for k in range(n):
            textures[f"u_mean{k}"] = mean.color_attachments[k]
            textures[f"u_sample{k}"] = sample.color_attachments[k]
        self._accumulate_pass.render(spare, uniforms={"u_count": self.samples}, textures=textures)
        self._targets["network"], self._targets["network_spare"] = spare, mean
        return spare

    def accumulate(self, camera, width: int, height: int, spp: int, *, progress: bool | None = None
                   ) -> moderngl.Framebuffer:
        """Draw samples of this view until its running mean holds ``spp`` (the sample cap is set to
        ``spp``, so later renders of the same view add none). A deterministic program draws once
        and only ``spp == 1`` is allowed for it. ``progress``: inshade/progress.py (None: auto)."""
        from inshade.progress import Progress

        if isinstance(spp, bool) or not isinstance(spp, int) or spp < 1:
            raise ValueError(f"spp: must be an int >= 1, got {spp!r}")
        if spp > 1 and not self.spec.accumulate:
            raise ValueError(f"spp {spp}: program {self.scene.program} draws one deterministic sample per pixel "
                             f"(its technique does not accumulate samples); use 1")
        self.sample_cap = spp
        fbo = self.render_network(camera, width, height, force=self.samples > spp)   # more than asked: restart
        if self.samples >= spp:
            return fbo
        with Progress(total=spp, initial=self.samples, desc=f"{self.scene.name} spp", unit="spp",
                      enabled=progress) as bar:
            while self.samples < spp:
                fbo = self.render_network(camera, width, height)
                bar.update(1)
        return fbo

    def render(self, camera, width: int, height: int, *, mode=None, split: float | None = None,
               target: str = "output") -> moderngl.Framebuffer:
        """Network pass (if stale) + display pass into a linear RGBA32F target; returns it."""
        mode = self.scene.display_mode if mode is None else parse_mode(mode)
        split = self.scene.split if split is None else float(split)
        net = self.render_network(camera, width, height)
        out = self._target(target, width, height)
        ref_view = (0.0, 0.0, 1.0, 1.0)
        if self.scene.reference is not None and self.scene.reference.space == "field":
            ref_view = camera.uniforms(width, height).get("u_view", ref_view)
        uniforms = self._uniforms(self.display_program, camera, width, height)
        uniforms.update({k: v for k, v in {"u_mode": int(mode), "u_split": split, "u_ref_view": tuple(ref_view),
                                           "u_has_reference": int(self.scene.reference is not None)}.items()
                         if k in self.display_program})
        for name, default in (("u_exposure", 1.0), ("u_error_scale", 4.0)):
            if name in self.display_program and name not in uniforms:
                uniforms[name] = default
        self.ctx.scissor = None
        self.ctx.viewport = (0, 0, width, height)
        self._display_pass.render(out, uniforms=uniforms,
                                  textures={"u_network": net.color_attachments[0], "u_reference": self._reference_tex})
        return out

    def read(self, target: str = "output", attachment: int = 0) -> np.ndarray:
        """The last render as linear float32 RGBA [H, W, 4], image orientation; ``target="network"``
        with ``attachment`` reads the scene pass's other outputs (``ProgramSpec.attachments``)."""
        return read_rgba(self._targets[target], attachment)

    def psnr(self, camera, width: int, height: int) -> float | None:
        """PSNR (dB, linear RGB, peak 1) of the network vs the reference over the covered pixels
        of this view; None without a reference or coverage."""
        if self.scene.reference is None:
            return None
        fbo = self.render(camera, width, height, mode=DisplayMode.SQUARED_ERROR, target="stats")
        data = read_rgba_raw(fbo)
        mask = data[..., 3] > 0
        if not mask.any():
            return None
        from inshade.metrics import psnr_from_mse

        return psnr_from_mse(float(data[mask][:, :3].mean()))

    def info(self, camera, width: int, height: int, *, mode=None, split=None) -> dict:
        """What a sidecar records: enough to re-render the same pixels (``inshade render --from``)."""
        mode = self.scene.display_mode if mode is None else parse_mode(mode)
        common = {
            "gl": {k: self.gl[k] for k in ("vendor", "renderer", "version", "glsl_version", "software")},
            "spp": self.samples,   # samples averaged (accumulating programs; else 1)
            "render": {"program": self.scene.program, "width": width, "height": height,
                       "colour": "linear rgb, float32", "uv": "(0,0) bottom-left, pixel centres"},
            "scene": {"name": self.scene.name,
                      "path": str(Path(self.scene.source).resolve()) if self.scene.source else None},
            "view": {"camera": camera.to_dict(), "mode": mode.name.lower(),
                     "split": self.scene.split if split is None else float(split),
                     "settings": json.loads(json.dumps(self.values))},
        }
        if not self.bundles:
            return {**common, "bundle": None, "bundles": [], **self._geometry_info()}
        primary = self.bundles[0]
        storages = {}
        for g in self.generated:
            for row in g.plan.rows:
                if row.storage and row.storage != "-":
                    storages[row.storage] = storages.get(row.storage, 0) + 1
        totals = {}
        for g in self.generated:
            for k, v in g.plan.totals().items():
                totals[k] = totals.get(k, 0) + v
        ref = self.scene.networks[0]
        return {
            "bundle": {"name": primary.name, "kind": primary.kind,
                       "path": str(primary.path) if primary.path else None, "digest": primary.digest()},
            "bundles": [{"name": b.name, "digest": b.digest(), "prefix": n.prefix}
                        for b, n in zip(self.bundles, self.scene.networks)],
            **common,
            "render": {**common["render"], "input": primary.inputs[0].name,
                       "output": ref.output or primary.outputs[0].name,
                       "storage": self.values.get("storage", "auto"),
                       "lut_filter": self.values.get("lut_filter", "exact")},
            "plan": {"storage": storages, "totals": totals},
            **(self._geometry_info() if self.scene.lit else {}),
        }

    def _geometry_info(self) -> dict:
        """Sidecar record of the lit geometry (SDF or mesh) and its environment."""
        sdf = self.scene.sdf
        env = dict(self.scene.environment)
        for name, s in self.scene.settings.items():
            if s.binding == "environment":
                env[s.target] = self.values[name]
        if sdf is None:
            mesh = self.scene.mesh
            # a built-in shape is recorded by name and parameters (geometry/shapes.py rebuilds it)
            source = {"path": str(mesh.path)} if mesh.path is not None else \
                {"path": None, "shape": mesh.shape, **mesh.params}
            return {"mesh": {**source, "name": mesh.name, "vertices": int(len(mesh.data.vertices)),
                             "faces": int(len(mesh.data.faces))}, "environment": env}
        if isinstance(sdf, NetworkSdfRef):
            record = {"path": str(sdf.path), "name": self.sdf_bundle.name, "network": True,
                      "digest": self.sdf_bundle.digest()}
        else:
            record = {"path": str(sdf.path) if sdf.path else None, "name": sdf.name, **sdf.to_dict(),
                      "chunk_sha256": hashlib.sha256(sdf_chunks(sdf)[SDF_CHUNK].encode()).hexdigest()}
        return {"sdf": record, "environment": env}

    def release(self, keep=()) -> None:
        """Release every GL object this renderer created (programs stay with the cache unless owned;
        ``keep``: programs another renderer on the same cache still uses)."""
        for fbo in self._targets.values():
            release_target(fbo)
        self._targets.clear()
        for res in self.resources:
            res.release()
        self.resources = []
        programs = [self.program, self.display_program]
        if self.gbuffer is not None:
            programs.append(self.gbuffer.program)
            self.gbuffer.release()
            self.gbuffer = None
        if self._accumulate_pass is not None:
            programs.append(self._accumulate_pass.program)
        for p in (self._net_pass, self._display_pass, self._accumulate_pass, *(self._blend_passes or ())):
            if p is not None:
                p.vao.release()
        self._net_pass = self._display_pass = self._accumulate_pass = self._blend_passes = None
        self._reference_tex.release()
        for tex in self.scene_textures.values():
            tex.release()
        self.scene_textures = {}
        if self.environment is not None:
            self.environment.release()
            self.environment = None
        self.shadow_maps.release()
        if self.owns_programs:
            for p in programs:
                if p is not None and not any(p is k for k in keep):
                    self.cache.discard(p)
        self.program = None


_DRAWN: set[str] = set()   # program keys this process has drawn (their first draw is said once)
SRGB_SEMANTIC = "srgb"   # an output port whose values are sRGB-encoded (e.g. fitted to sRGB pixels)
SLOW_FRAME_S = 30.0   # a view whose last draw took this long is warned about before it starts
BLEND_LAYERS = 4      # BLEND surfaces peeled per pixel: a fifth one behind four others is not drawn
BLEND_LAYER_READS = ("uv", "uv_grad", "uv1", "uv1_dy")   # a layer's G-buffer targets passes/gltf_blend_layer reads


def hash_values(values) -> str:
    return hashlib.sha256(repr(sorted((k, repr(v)) for k, v in dict(values).items())).encode()).hexdigest()[:16]


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


def first_draw_message(generated, renderer: str = "", previous: float | None = None,
                       shader_cache: bool = False) -> str | None:
    """What a software renderer's first draw of these networks is about to do, from their plans
    and what this machine recorded (``previous``: the seconds of the last first draw of this
    program, None if never; ``shader_cache``: it was compiled with Mesa's shader cache on, and the
    cache is on now): "compiling a network of 4 dense layers up to 64 wide (inline) (llvmpipe JIT at
    the first draw: seconds to minutes; ...)". None when no network has a dense layer."""
    nets = []
    for g in generated:
        plan = getattr(g, "plan", None)
        dense = [r for r in (plan.rows if plan is not None else []) if r.type == "dense"]
        if not dense:
            continue
        dims = [int(d) for r in dense for d in str(r.shape).split("->")[-1:]]
        storage = "+".join(sorted({r.storage for r in dense}))
        nets.append(f"{len(dense)} dense layers up to {max(dims)} wide ({storage})")
    if not nets:
        return None
    what = f"a network of {nets[0]}" if len(nets) == 1 else f"{len(nets)} networks: {'; '.join(nets)}"
    name = str(renderer).split(" ")[0] or "software renderer"
    if previous is not None and shader_cache:
        return f"drawing {what} (compiled before on this machine; Mesa's shader cache should make it quick)"
    if previous is not None:
        return f"compiling {what} ({name} JIT at the first draw; {format_seconds(previous)} last time)"
    return (f"compiling {what} ({name} JIT at the first draw: seconds to minutes; Mesa's shader cache keeps "
            "it for later runs)")


def _rotated_map_sh(coeffs: np.ndarray, rotation_deg: float) -> np.ndarray:
    """An environment map's SH rotated about +y, float32, as codegen.sdf.environment_sh does for
    the sky presets."""
    from inshade.sh import rotate_sh, rotation_matrix

    if rotation_deg:
        coeffs = rotate_sh(coeffs, rotation_matrix([0.0, 1.0, 0.0], math.radians(rotation_deg)))
    return np.asarray(coeffs, np.float32)


def _scene_texture(ctx: moderngl.Context, t) -> moderngl.Texture:
    """A scene.json texture: RGBA8 bytes as stored (no sRGB decode), uv (0,0) = bottom-left."""
    data = np.asarray(Image.open(t.image).convert("RGBA"), np.uint8)[::-1]
    tex = ctx.texture(data.shape[1::-1], 4, np.ascontiguousarray(data).tobytes(), alignment=1)
    if t.mipmaps:
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        tex.anisotropy = min(t.anisotropy, ctx.max_anisotropy)
    else:
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = t.repeat
    return tex

