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

import logging

import moderngl
import numpy as np

from inshade.bundle import Bundle, load
from inshade.scene.description import NetworkSdfRef, Scene, SceneError
from inshade.scene.display import DisplayMode, glsl_chunk, parse_mode

from .context import GLContextError, gl_info, make_current, shared_context
from .environment import EnvironmentTextures
from .first_draw import draw_timed, first_draw_note
from .geometry import MeshGBuffer
from .materials import MaterialTextures
from .network import NetworkResources
from .programs import ProgramCache
from .quick_program import quick_storage
from .render import FullscreenPass, check_gl_error, clear_gl_error, read_rgba, read_rgba_raw
from .scene_inputs import (SceneEnvironment, bind_scene_resources, environment_sh, reference_texture, scene_texture,
                           scene_uniforms, sync_shadows)
from .scene_passes import BLEND_LAYERS, Accumulation, BlendPeel, RenderTargets
from .scene_program import VERTEX, build_scene_program, codegen_options, gbuffer_defines
from .shadow import ShadowMaps
from .sidecar import render_info

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
    ``quick``: (pixels, frames) of a short job: at storage ``auto`` the program is built at the storage
    that ends the job sooner (runtime/quick_program.py; ``storage_choice`` says why when it changed).

    The parts: runtime/scene_program.py builds the scene program, runtime/scene_inputs.py binds
    what it reads, runtime/scene_passes.py holds the targets and the passes around it,
    runtime/first_draw.py says what a draw will cost, runtime/sidecar.py records a render.
    """

    def __init__(self, scene: Scene, ctx: moderngl.Context | None = None, *, cache: ProgramCache | None = None,
                 settings: dict | None = None, bundles: list[Bundle] | None = None,
                 owns_programs: bool = False, limits: dict | None = None, target: str = "330",
                 quick: tuple[int, int] | None = None, sdf_bundle: Bundle | None = None):
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
        self.sdf_bundle = sdf_bundle or (load(scene.sdf.bundle) if isinstance(scene.sdf, NetworkSdfRef) else None)
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
        self._targets = RenderTargets(self.ctx)
        self.samples = 0               # samples in the "network" target since the last reset (accumulate)
        self.sample_cap = None         # accumulating programs stop adding samples here (None: one per render)
        self._accumulation = None      # passes/accumulate.frag, built on the first accumulated sample
        self._blend_peel = None        # passes/gltf_blend_layer + gltf_blend_resolve, built on the first peel
        self.gbuffer = None            # mesh scenes: the G-buffer pass drawn before the scene pass
        self.shadow_maps = ShadowMaps(self.ctx)   # ProgramSpec.shadows: GL objects made on first use, then reused
        self.storage_choice = None     # why a short job draws at another storage than auto (quick_program.py)
        if quick is not None and "storage" in scene.settings:
            self.values["storage"], self.storage_choice = quick_storage(self, *quick)
            if self.storage_choice:
                log.info("%s", self.storage_choice)
        self._build()
        self._init_textures()
        self._environment = SceneEnvironment(self.ctx)   # while the program samples lib/environment
        self._sync_environment()
        self.display_program = self._compile_display()
        self._display_pass = FullscreenPass(self.ctx, self.display_program)
        self.reference_image, self._reference_tex = reference_texture(self.ctx, scene)
        check_gl_error(self.ctx, f"scene '{scene.name}': reference texture")

    def _init_textures(self) -> None:
        """The scene's textures, a glTF mesh's materials and its G-buffer."""
        scene = self.scene
        clear_gl_error(self.ctx, f"the textures of scene '{scene.name}'")
        self.scene_textures = {t.uniform: scene_texture(self.ctx, t) for t in scene.textures}
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
            self.gbuffer = MeshGBuffer(self.ctx, scene.mesh.data, self.cache, version=self.target,
                                       visibility=self.spec.visibility, materials=self.materials,
                                       peel=self.blend_layers > 0)
        check_gl_error(self.ctx, f"scene '{scene.name}': textures {[t.image.name for t in scene.textures]}")

    # building ---------------------------------------------------------------------------------------
    def _compile_display(self) -> moderngl.Program:
        """passes/display.frag: modes, compare, heat map (the cache has it when nothing changed)."""
        return self.cache.get(VERTEX, "passes/display.frag", version=self.target,
                              chunks={"display_modes": glsl_chunk()})

    def _codegen_options(self) -> dict:
        return codegen_options(self.scene, self.values, self.gl)

    def _build(self, bundles=None) -> str:
        """(Re)generate and compile. On failure nothing changes (the last good program keeps
        drawing), ``self.error`` is set and the error is raised. Returns "unchanged",
        "reuploaded" or "recompiled"."""
        bundles = bundles or self.bundles
        try:
            built = build_scene_program(self.scene, self.spec, bundles, values=self.values, gl=self.gl,
                                        target=self.target, sdf_bundle=self.sdf_bundle, cache=self.cache)
            self._sources = (built.defines, built.chunks)
        except Exception as exc:
            self.error = exc
            raise
        self.error = None
        self.compile_seconds = self.cache.last_compile_seconds
        generated, program = built.generated, built.program
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

    @property
    def environment(self) -> EnvironmentTextures | None:
        """The importance-sampled environment textures while the program samples lib/environment."""
        return self._environment.textures

    def _sync_environment(self) -> EnvironmentTextures | None:
        """(Re)build the environment textures when the program uses them and sky/rotation changed."""
        if self.program is None or "u_env_radiance" not in self.program:
            return self.environment
        return self._environment.sync(self.scene, self.values)

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
            display = self._compile_display()
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
    def _uniforms(self, program, camera, width, height) -> dict:
        """What ``program`` is set for ``camera`` at this size (runtime/scene_inputs.py scene_uniforms)."""
        return scene_uniforms(self.scene, self.spec, self.values, program, camera, width, height, self.environment_sh)

    def environment_sh(self) -> np.ndarray:
        """SDF scenes: the radiance SH [K, 3] float32 of the environment (scene + settings)."""
        return environment_sh(self.scene, self.values)

    def render_network(self, camera, width: int, height: int, *, force: bool = False) -> moderngl.Framebuffer:
        """The scene pass alone (linear float, alpha = coverage); redrawn only when its inputs change,
        or every call with ``force`` (timing repeated draws of the same view)."""
        make_current(self.ctx)
        fbo = self._targets.target("network", width, height, self.spec.attachments)
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
            draw_into = self._targets.target("sample", width, height, self.spec.attachments)
        if force or key != self._net_key or self.spec.accumulate:
            self.ctx.scissor = None
            gbuffer = self.gbuffer.draw_camera(camera, width, height) if self.gbuffer is not None else None
            self.ctx.viewport = (0, 0, width, height)
            self._bind_scene_resources(gbuffer)
            if self.blend_layers:
                opaque = self._targets.target("opaque", width, height, self.spec.attachments)
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
        """Bind what the scene program samples (runtime/scene_inputs.py); ``gbuffer``: the G-buffer's
        textures, or none."""
        bind_scene_resources(self.program, self.resources, self.scene_textures, self._sync_environment,
                             self.shadow_maps, self.gbuffer.names if self.gbuffer is not None else (), gbuffer)

    def _sync_shadows(self) -> int:
        """Redraws the shadow maps if the program's request changed; their version (a redraw key)."""
        return sync_shadows(self.spec, self.scene, self.bundles, self.values, self.shadow_maps)

    @property
    def blend_layers(self) -> int:
        """BLEND surfaces of a glTF mesh are depth-peeled into this many layers, each shaded by the
        scene program and laid under the ones in front (front to back), then over the opaque
        surfaces; 0 where there are none, or where the program accumulates samples (there they are
        drawn opaque, as the G-buffer's one surface a pixel)."""
        blended = self.materials is not None and self.materials.blended and self.scene.mesh is not None
        return BLEND_LAYERS if blended and not self.spec.accumulate and self.spec.attachments == 1 else 0

    def _peel(self, camera, width: int, height: int, uniforms: dict, opaque, out) -> None:
        """The BLEND layers (runtime/scene_passes.py BlendPeel) through the scene program, composited into ``out``."""
        if self._blend_peel is None:
            self._blend_peel = BlendPeel(self.ctx, self.cache, gbuffer_defines(self.scene, self.spec))

        def shade(layer, into):
            self.ctx.viewport = (0, 0, width, height)
            self._bind_scene_resources(layer)
            self._net_pass.render(into, uniforms=uniforms)

        self._blend_peel.draw(self._targets, camera, width, height, gbuffer=self.gbuffer, layers=self.blend_layers,
                              material_textures=self.materials.textures, shade=shade, opaque=opaque, out=out)

    def _draw_timed(self, target, uniforms, pixels: int, view_key) -> None:
        """The scene pass, with what to expect said first (runtime/first_draw.py draw_timed)."""
        seconds = draw_timed(lambda: self._net_pass.render(target, uniforms=uniforms), self.ctx,
                             scene=self.scene, gl=self.gl, program_key=self.program_key, values=self.values,
                             generated=self.generated, first=self.first_draw_pending,
                             new_view=view_key != self._net_key, pixels=pixels,
                             source=self.assembled()["fragment"] if self.first_draw_pending else None)
        if self.first_draw_pending:
            self.first_draw_seconds = seconds
            self.first_draw_pending = False

    @property
    def first_draw_note(self) -> str | None:
        """What the next draw is about to do (a JIT compile, and what it took last time), or None."""
        return first_draw_note(self.gl, self.program_key, self.generated, self.first_draw_pending)[0]

    def _fold_sample(self, sample: moderngl.Framebuffer, width: int, height: int) -> moderngl.Framebuffer:
        """One more sample into the running mean in "network" (runtime/scene_passes.py Accumulation)."""
        if self._accumulation is None:
            self._accumulation = Accumulation(self.ctx, self.cache, self.target, self.spec.attachments)
        self.samples += 1
        return self._accumulation.fold(self._targets, sample, width, height, self.samples)

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
        out = self._targets.target(target, width, height)
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
        return render_info(self.scene, self.values, self.gl, samples=self.samples, bundles=self.bundles,
                           generated=self.generated, sdf_bundle=self.sdf_bundle, camera=camera,
                           width=width, height=height, mode=mode, split=split)

    def release(self, keep=()) -> None:
        """Release every GL object this renderer created (programs stay with the cache unless owned;
        ``keep``: programs another renderer on the same cache still uses)."""
        self._targets.release()
        for res in self.resources:
            res.release()
        self.resources = []
        programs = [self.program, self.display_program]
        if self.gbuffer is not None:
            programs.append(self.gbuffer.program)
            self.gbuffer.release()
            self.gbuffer = None
        if self._accumulation is not None:
            programs.append(self._accumulation.program)
        for p in (self._net_pass, self._display_pass):
            if p is not None:
                p.vao.release()
        for part in (self._accumulation, self._blend_peel):
            if part is not None:
                part.release()
        self._net_pass = self._display_pass = self._accumulation = self._blend_peel = None
        self._reference_tex.release()
        for tex in self.scene_textures.values():
            tex.release()
        self.scene_textures = {}
        self._environment.release()
        self.shadow_maps.release()
        if self.owns_programs:
            for p in programs:
                if p is not None and not any(p is k for k in keep):
                    self.cache.discard(p)
        self.program = None
