"""A network as one Shadertoy Image pass: ``mainImage`` drawing its colour over the unit square, the
weights as literals (a pasted pass carries no textures or buffers), for shadertoy.com's Image tab;
and its check, run as Shadertoy runs a pass (its uniforms and its ``main`` around the pasted text,
GLSL ES 3.00: passes/shadertoy.frag) on this machine's GL driver, against the network's torch twin.

The check measures two things: the network inside the pasted text against torch under the parity
rule, at every pixel centre of a square view (the uvs ``inshade render`` gives the network); and the
picture mainImage shows, on a wide view (the square centred, the background around it), against
torch's colour put through the same display steps, within half an 8-bit step (what a canvas holds).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from inshade.codegen import LimitError, generate
from inshade.codegen.targets import TargetError
from inshade.runtime.scene_program import SRGB_SEMANTIC
from inshade.shaders import flatten
from inshade.shaders.compact import compact

from .limits import WEBGL2

# inshade's budget for a pasted pass, in characters: a pass is compiled by the visitor's browser
# each time the page opens, and literal-heavy programs are the slow ones to compile
PASS_CHARS = 65536
PASS_CHARS_LIMIT = "SHADERTOY_PASS_CHARS"
CHECK_SIZE = 128                 # the square view of the network check
SHOWN_SIZE = (96, 48)            # the wide view of the picture check
SHOWN_RULE = 0.5 / 255           # half an 8-bit step
BACKGROUND = 0.18                # passes/shadertoy_image.glsl's SHADERTOY_BACKGROUND


@dataclass(frozen=True)
class ShadertoyPass:
    text: str            # the pass to paste
    generated: object    # the network's generated code (codegen.Generated) inside it
    output: str          # the output port it shows
    lanes: tuple         # (offset, width) of that output in the concatenated outputs
    srgb: bool           # the output is sRGB-encoded already (shown as is)
    weights: int         # numbers written as literals

    def report(self, budget: int = PASS_CHARS) -> str:
        colour = "sRGB-encoded, shown as is" if self.srgb else "linear, sRGB-encoded for display"
        return (f"shadertoy image pass: {len(self.text)} characters (budget {budget}), {self.weights} weights as "
                f"literals; shows output {self.output!r} ({self.lanes[1]} lanes, {colour}) over the unit square")


def _ports(bundle) -> str:
    return ", ".join(f"{p.name}[{p.dim}]" for p in bundle.inputs) + " -> " + \
        ", ".join(f"{p.name}[{p.dim}]" for p in bundle.outputs)


def shown_output(bundle):
    """The output port an image pass shows: the one the bundle's ``render`` field names, else the
    first of 1, 3 or 4 lanes; one line naming the ports when the network is no uv -> colour image."""
    if len(bundle.inputs) != 1 or bundle.inputs[0].dim != 2 or bundle.inputs[0].dtype != "float":
        raise TargetError(f"shadertoy: mainImage draws a network of one 2-lane float input (uv) as an image; "
                          f"{bundle.name} is {_ports(bundle)}")
    named = (bundle.meta.get("render") or {}).get("output")
    port = next((p for p in bundle.outputs if p.name == named), None) if named else \
        next((p for p in bundle.outputs if p.dim in (1, 3, 4)), None)
    if port is None or port.dim not in (1, 3, 4):
        raise TargetError(f"shadertoy: no output of 1, 3 or 4 lanes (grey, rgb, rgba) to show; "
                          f"{bundle.name} is {_ports(bundle)}")
    return port


def image_pass(bundle, *, limits: dict | None = None) -> ShadertoyPass:
    """The pass for ``bundle`` (a uv -> colour network), planned against WebGL2's minimums with the
    weights as literals; ``limits`` may raise ``SHADERTOY_PASS_CHARS`` (or any GL limit)."""
    port = shown_output(bundle)
    limits = dict(limits or {})
    budget = int(limits.pop(PASS_CHARS_LIMIT, PASS_CHARS))
    gen = generate(bundle, target="es300", storage="inline", prefix="net", limits={**WEBGL2, **limits})
    if gen.resources:
        raise TargetError(f"shadertoy: {bundle.name} reads {len(gen.resources)} textures or blocks "
                          f"({', '.join(r.name for r in gen.resources)}) and a pasted pass carries only literals; "
                          "use --target es300 (WebGL2) with its resources")
    lanes = bundle.output_lanes(port.name)
    srgb = port.semantic == SRGB_SEMANTIC
    defines = {"FIELD_OUT_OFFSET": lanes[0], "FIELD_OUT_DIM": lanes[1], **({"FIELD_OUT_SRGB": 1} if srgb else {})}
    head = (f"// {bundle.name}: a network as a Shadertoy Image pass, written by inshade from bundle "
            f"{bundle.digest()[:16]}.\n// Paste it into the Image tab: it reads no channels; the weights are "
            "literals.\n")
    body = flatten("passes/shadertoy_image", chunks={"network": gen.chunk}, defines=defines)
    text = head + compact(body, roots=("mainImage",))
    weights = sum(int(np.asarray(t).size) for t in bundle.tensors.values())
    if len(text) > budget:
        raise LimitError(f"shadertoy: the pass is {len(text)} characters ({weights} weights as literals); "
                         f"{PASS_CHARS_LIMIT} is {budget} (inshade's budget for a pasted pass); use a smaller "
                         f"network, raise it with --limit {PASS_CHARS_LIMIT}=N, or --target es300 with the weights "
                         "in a texture")
    return ShadertoyPass(text, gen, port.name, lanes, srgb, weights)


@dataclass(frozen=True)
class ShadertoyCheck:
    network: object        # convert.check.CheckResult of the network in the pass (language "shadertoy")
    shown_max: float       # max |pixel - torch's shown colour| on the wide view
    seconds: float

    @property
    def ok(self) -> bool:
        return self.network.ok and self.shown_max <= SHOWN_RULE

    def lines(self) -> list[str]:
        shown = "ok" if self.shown_max <= SHOWN_RULE else "FAILED"
        return [f"{self.network.line()} ({self.network.rows} pixels, {self.network.gl_renderer})",
                f"as shown: max |pixel - torch's colour| = {self.shown_max * 255:.2g}/255 "
                f"(rule {SHOWN_RULE * 255:g}/255, {SHOWN_SIZE[0]}x{SHOWN_SIZE[1]} view): {shown}"]


def shown_colour(y: np.ndarray, p: ShadertoyPass, uv: np.ndarray) -> np.ndarray:
    """What mainImage shows for network outputs ``y`` [..., out_dim] at ``uv`` [..., 2] (float64):
    the output's colour clamped, sRGB-encoded unless it is already, over the background by its
    alpha; the background outside the unit square."""
    from inshade.metrics import srgb_oetf

    offset, width = p.lanes
    c = np.asarray(y, np.float64)[..., offset:offset + width]
    rgb = np.repeat(c[..., :1], 3, -1) if width == 1 else c[..., :3]
    rgb = np.clip(rgb, 0.0, 1.0)
    if not p.srgb:
        rgb = srgb_oetf(rgb)
    alpha = np.clip(c[..., 3:4], 0.0, 1.0) if width == 4 else np.ones(rgb.shape[:-1] + (1,))
    shown = BACKGROUND + (rgb - BACKGROUND) * alpha
    inside = np.all((uv >= 0.0) & (uv <= 1.0), -1, keepdims=True)
    return np.where(inside, shown, BACKGROUND)


def _run(ctx, p: ShadertoyPass, width: int, height: int, network: bool) -> np.ndarray:
    """The pass drawn at width x height as Shadertoy draws it: [H, W, 4] float32, data orientation."""
    from inshade.runtime.programs import ProgramCache
    from inshade.runtime.render import FullscreenPass, float_target, read_rgba_raw

    cache = ProgramCache(ctx)
    program = cache.get("common/fullscreen.vert", "passes/shadertoy.frag", version="es300",
                        defines={"SHADERTOY_NETWORK": 1} if network else None, chunks={"shadertoy_pass": p.text})
    fbo = float_target(ctx, width, height)
    pass_ = FullscreenPass(ctx, program)
    try:
        ctx.viewport = (0, 0, width, height)
        pass_.render(fbo, uniforms={"iResolution": (float(width), float(height), 1.0)})
        return read_rgba_raw(fbo)
    finally:
        pass_.vao.release()
        for a in fbo.color_attachments:
            a.release()
        fbo.release()
        cache.release()


def _frag_uvs(width: int, height: int) -> np.ndarray:
    """mainImage's uv at each pixel centre, [H, W, 2] in data orientation, computed in float32 as the
    pass does."""
    f32 = np.float32
    side = f32(min(width, height))
    x = ((np.arange(width, dtype=f32) + f32(0.5)) - f32(0.5) * (f32(width) - side)) / side
    y = ((np.arange(height, dtype=f32) + f32(0.5)) - f32(0.5) * (f32(height) - side)) / side
    u, v = np.meshgrid(x, y)
    return np.stack([u, v], -1)


def check_pass(p: ShadertoyPass, source, bundle, *, ctx=None) -> ShadertoyCheck:
    """Run the pasted pass as Shadertoy does and compare it with ``source`` (the bundle's torch twin,
    or the module it was exported from)."""
    import dataclasses

    from inshade.convert.check import compare, judge, source_outputs
    from inshade.runtime.context import shared_context

    ctx = shared_context() if ctx is None else ctx
    start = time.perf_counter()
    uv = _frag_uvs(CHECK_SIZE, CHECK_SIZE).reshape(-1, 2)
    raw = _run(ctx, p, CHECK_SIZE, CHECK_SIZE, network=True).reshape(-1, 4)
    ref = source_outputs(source, [uv], bundle)
    offset, width = p.lanes
    lanes = slice(offset, offset + width)
    network = compare(raw[:, :width], ref[:, lanes], ctx.info["GL_RENDERER"], "inline", time.perf_counter() - start)
    network = judge(dataclasses.replace(network, language="shadertoy"), source, [uv], bundle, raw[:, :width],
                    ref[:, lanes], lanes=lanes)
    w, h = SHOWN_SIZE
    wide = _frag_uvs(w, h)
    shown = _run(ctx, p, w, h, network=False)[..., :3]
    expected = shown_colour(source_outputs(source, [wide.reshape(-1, 2)], bundle).reshape(h, w, -1), p, wide)
    return ShadertoyCheck(network, float(np.abs(shown - expected).max()), time.perf_counter() - start)


# --- an SDF (a scene of passes/sdf_diffuse.frag) -------------------------------------------------
SDF_PROGRAM = "passes/sdf_diffuse.frag"
SDF_CHECK_SIZE = 64
PSNR_RULE = 40.0   # dB, 8-bit sRGB, on the pixels away from edges (stable_pixels)


def sdf_pass(source, *, limits: dict | None = None) -> ShadertoyPass:
    """The pass of an SDF scene (analytic, or a network without textures): its orbit camera, SH
    environment and exposure at the scene's default settings written as constants."""
    from inshade.runtime.context import shared_context
    from inshade.runtime.renderer import SceneRenderer
    from inshade.runtime.scene_program import geometry_chunks
    from inshade.scene.camera import OrbitCamera
    from inshade.scene.description import load_scene

    scene = load_scene(source)
    if scene.program != SDF_PROGRAM:
        raise TargetError(f"shadertoy: {source}: a scene's pass is drawn for {SDF_PROGRAM} (an SDF) or a uv -> "
                          f"colour network; this scene's program is {scene.program}")
    camera = scene.make_camera()
    if not isinstance(camera, OrbitCamera):
        raise TargetError(f"shadertoy: {source}: the pass orbits; this scene's camera is {camera.kind}")
    limits = dict(limits or {})
    budget = int(limits.pop(PASS_CHARS_LIMIT, PASS_CHARS))
    gl = {**WEBGL2, "GL_MAX_FRAGMENT_UNIFORM_BLOCKS": 0, **limits}
    r = SceneRenderer(scene, shared_context(), settings={"labels": False}, limits=gl, target="es300")
    try:
        chunks, generated = geometry_chunks(scene, r.spec, r.bundles, r.values, gl, "es300", r.sdf_bundle)
        sh = np.frombuffer(r.uniform_values(camera, *scene.size)["u_sh"], np.float32).reshape(-1, 3)
        exposure = float(r.values.get("exposure", 1.0))
    finally:
        r.release()
    resources = [res.name for g in generated for res in g.resources]
    if resources:
        raise TargetError(f"shadertoy: {scene.name}'s SDF network reads {len(resources)} textures "
                          f"({', '.join(resources)}) and a pasted pass carries only literals")
    f32 = lambda v: _define_float(v)  # noqa: E731
    defines = {"SHADERTOY_TARGET": f"vec3({', '.join(f32(v) for v in camera.target)})",
               "SHADERTOY_DISTANCE": float(camera.distance), "SHADERTOY_YAW": float(camera.yaw),
               "SHADERTOY_PITCH": float(camera.pitch), "SHADERTOY_FOV_Y": float(camera.fov_y),
               "SHADERTOY_EXPOSURE": exposure,
               "SHADERTOY_SH": "vec3[SH_COEFFS](" + ", ".join(f"vec3({', '.join(f32(v) for v in c)})" for c in sh) + ")"}
    head = (f"// {scene.name}: an SDF as a Shadertoy Image pass, written by inshade (drag to turn the camera).\n"
            "// Paste it into the Image tab: it reads no channels.\n")
    text = head + compact(flatten("passes/shadertoy_sdf", chunks=chunks, defines=defines), roots=("mainImage",))
    weights = sum(int(np.asarray(t).size) for b in ([r.sdf_bundle] if r.sdf_bundle else []) for t in b.tensors.values())
    if len(text) > budget:
        raise LimitError(f"shadertoy: the pass is {len(text)} characters ({weights} weights as literals); "
                         f"{PASS_CHARS_LIMIT} is {budget} (inshade's budget for a pasted pass); raise it with "
                         f"--limit {PASS_CHARS_LIMIT}=N")
    return ShadertoyPass(text, generated[0] if generated else None, "sdf", (0, 3), False, weights)


def _define_float(v) -> str:
    text = "%.9g" % float(np.float32(v))
    return text if any(c in text for c in ".e") else text + ".0"


def stable_pixels(scene, image8: np.ndarray, size: int, tolerance: int = 8, settings: dict | None = None
                  ) -> np.ndarray:
    """The pixels of inshade render's 8-bit picture ``image8`` [size, size, 3] (made with ``settings``)
    that keep their colour (within ``tolerance``) when the scene's orbit camera turns by a tenth of a
    pixel either way: the rest are edges, where a ray computed another way (another rasteriser, another
    camera formula) may land on either side."""
    import dataclasses

    from inshade.runtime.headless import render_scene
    from inshade.web.browser import srgb8

    cam = scene.make_camera()
    step = 0.1 * cam.fov_y / size
    stable = np.ones((size, size), bool)
    for dyaw, dpitch in ((step, 0), (-step, 0), (0, step), (0, -step)):
        nudged = dataclasses.replace(cam, yaw=cam.yaw + dyaw, pitch=cam.pitch + dpitch)
        other, _ = render_scene(scene, width=size, height=size, camera=nudged,
                                settings={"labels": False, **(settings or {})})
        stable &= np.abs(image8.astype(int) - srgb8(other).astype(int)).max(-1) <= tolerance
    return stable


@dataclass(frozen=True)
class SdfCheck:
    psnr: float           # dB on the stable pixels
    stable: float         # their share of the picture
    renderer: str

    @property
    def ok(self) -> bool:
        return self.psnr >= PSNR_RULE

    def lines(self) -> list[str]:
        return [f"as shown: {self.psnr:.1f} dB against inshade render on the {self.stable:.0%} of "
                f"{SDF_CHECK_SIZE}x{SDF_CHECK_SIZE} pixels away from edges (rule {PSNR_RULE:g} dB, {self.renderer}): "
                f"{'ok' if self.ok else 'FAILED'}"]


def check_sdf_pass(p: ShadertoyPass, source, *, ctx=None) -> SdfCheck:
    """The pass drawn as Shadertoy draws it at the scene's camera, against inshade render."""
    from inshade.runtime.context import shared_context
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene
    from inshade.web.browser import psnr8, srgb8

    ctx = shared_context() if ctx is None else ctx
    scene = load_scene(source)
    n = SDF_CHECK_SIZE
    shown = np.clip(np.rint(_run(ctx, p, n, n, network=False)[::-1, :, :3] * 255), 0, 255).astype(np.uint8)
    image8 = srgb8(render_scene(scene, width=n, height=n, settings={"labels": False})[0])
    stable = stable_pixels(scene, image8, n)
    return SdfCheck(psnr8(shown[stable], image8[stable]), float(stable.mean()), ctx.info["GL_RENDERER"])
