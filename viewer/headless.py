"""Render a bundle without a window: `inshade render trained/neural_image -o shot.png`.

The bundle says how it is shown in its optional top-level ``render`` field, e.g.

    {"program": "passes/field2d.frag", "width": 256, "height": 256, "input": "uv", "output": "rgb"}

``program`` is the fragment chunk drawn over a full-screen triangle, with the generated network
included as ``<network>``; ``width``/``height`` the default size; ``input``/``output`` name the
bundle ports the program feeds and shows. No torch here: codegen + moderngl + numpy only.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from inshade.bundle import Bundle, load
from inshade.codegen.network import generate

from .context import gl_info, make_current, shared_context
from .image_io import write_exr, write_png, write_sidecar
from .network import NetworkResources
from .programs import ProgramCache
from .render import FullscreenPass, float_target, read_rgba

PROGRAMS = {"passes/field2d.frag": {"input_dim": 2}}  # programs a `render` field may name
MAX_SIZE = 16384
IMAGE_SUFFIXES = (".png", ".exr")


class RenderSpecError(ValueError):
    """A bundle cannot be rendered headless: no or malformed `render` field."""


def render_spec(bundle: Bundle) -> dict:
    """The bundle's ``render`` field, checked against the bundle's ports; adds the output's
    lane offset and width as ``out_offset``/``out_dim``."""
    where = _where(bundle)
    spec = bundle.meta.get("render")
    if spec is None:
        raise RenderSpecError(f"bundle '{bundle.name}' ({where}) has no 'render' field, so it does not say "
                              "how to render it headless; add one, e.g. {\"program\": "
                              "\"passes/field2d.frag\", \"width\": 256, \"height\": 256, "
                              "\"input\": \"uv\", \"output\": \"rgb\"}")
    if not isinstance(spec, dict):
        raise RenderSpecError(f"{where}: render: must be an object")
    program = spec.get("program")
    if program not in PROGRAMS:
        raise RenderSpecError(f"{where}: render.program: unknown program {program!r} "
                              f"(known: {', '.join(PROGRAMS)})")
    out = dict(spec)
    for key in ("width", "height"):
        v = spec.get(key, 256)
        if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_SIZE:
            raise RenderSpecError(f"{where}: render.{key}: must be an int in 1..{MAX_SIZE}, got {v!r}")
        out[key] = v
    need = PROGRAMS[program]["input_dim"]
    in_name = spec.get("input", bundle.inputs[0].name)
    if len(bundle.inputs) != 1 or bundle.inputs[0].name != in_name or bundle.inputs[0].dim != need:
        have = ", ".join(f"{p.name}[{p.dim}]" for p in bundle.inputs)
        raise RenderSpecError(f"{where}: render.input: {program} needs the bundle's only input to be "
                              f"{in_name!r} of width {need}; the bundle has {have}")
    out_name = spec.get("output", bundle.outputs[0].name)
    offset = 0
    for p in bundle.outputs:
        if p.name == out_name:
            break
        offset += p.dim
    else:
        raise RenderSpecError(f"{where}: render.output: no output named {out_name!r} "
                              f"(outputs: {', '.join(p.name for p in bundle.outputs)})")
    if p.dim not in (1, 3, 4):
        raise RenderSpecError(f"{where}: render.output: {out_name!r} is {p.dim} wide; 1, 3 or 4 can be shown")
    out.update(program=program, input=in_name, output=out_name, out_offset=offset, out_dim=p.dim)
    return out


def render_bundle(bundle, *, width: int | None = None, height: int | None = None, storage: str = "auto",
                  lut_filter: str = "exact", ctx=None, cache: ProgramCache | None = None):
    """Render a bundle (folder, bundle.json path, or ``Bundle``) as its ``render`` field says.

    Returns ``(image, info)``: ``image`` is linear RGBA float32 ``[H, W, 4]`` in image orientation
    (row 0 = top, as ``render.read_rgba``); ``info`` records the GL driver, the bundle digest, the
    storage plan, the size and timings (for the sidecar JSON). ``ctx`` defaults to the shared
    headless context.
    """
    t0 = time.perf_counter()
    if not isinstance(bundle, Bundle):
        bundle = load(bundle)
    spec = render_spec(bundle)
    width = spec["width"] if width is None else int(width)
    height = spec["height"] if height is None else int(height)
    if not (1 <= width <= MAX_SIZE and 1 <= height <= MAX_SIZE):
        raise ValueError(f"render size {width}x{height} out of range 1..{MAX_SIZE}")
    ctx = shared_context() if ctx is None else make_current(ctx)
    gl = gl_info(ctx)
    t_load = time.perf_counter()

    generated = generate(bundle, storage=storage, lut_filter=lut_filter, prefix="net",
                         limits={k: v for k, v in gl.items() if k.startswith("GL_MAX_")})
    t_gen = time.perf_counter()
    cache = cache or ProgramCache(ctx)
    program = cache.get("common/fullscreen.vert", spec["program"], chunks={"network": generated.chunk},
                        defines={"FIELD_OUT_OFFSET": spec["out_offset"], "FIELD_OUT_DIM": spec["out_dim"]})
    compile_seconds = cache.last_compile_seconds
    resources = NetworkResources(ctx, generated)
    pass_ = FullscreenPass(ctx, program)
    fbo = float_target(ctx, width, height)
    try:
        t_draw = time.perf_counter()
        ctx.viewport = (0, 0, width, height)
        resources.bind(program, first_unit=0)
        uniforms = {"u_size": (float(width), float(height))} if "u_size" in program else {}
        pass_.render(fbo, uniforms=uniforms)
        ctx.finish()
        t_read = time.perf_counter()
        image = read_rgba(fbo)
        t_end = time.perf_counter()
    finally:
        for a in fbo.color_attachments:
            a.release()
        fbo.release()
        pass_.vao.release()
        resources.release()

    storages = {}
    for row in generated.plan.rows:
        if row.storage and row.storage != "-":
            storages[row.storage] = storages.get(row.storage, 0) + 1
    info = {
        "bundle": {"name": bundle.name, "kind": bundle.kind, "path": str(bundle.path) if bundle.path else None,
                   "digest": bundle.digest()},
        "gl": {"vendor": gl["vendor"], "renderer": gl["renderer"], "version": gl["version"],
               "glsl_version": gl["glsl_version"], "software": gl["software"]},
        "render": {"program": spec["program"], "width": width, "height": height, "input": spec["input"],
                   "output": spec["output"], "storage": storage, "lut_filter": lut_filter,
                   "colour": "linear rgb, float32", "uv": "(0,0) bottom-left, pixel centres"},
        "plan": {"storage": storages, "totals": generated.plan.totals()},
        "timing_s": {"load": round(t_load - t0, 6), "generate": round(t_gen - t_load, 6),
                     "compile": round(compile_seconds, 6), "draw": round(t_read - t_draw, 6),
                     "read": round(t_end - t_read, 6), "total": round(t_end - t0, 6)},
    }
    return image, info


def save_render(image: np.ndarray, info: dict, out_path, *, exposure: float = 1.0,
                tonemap: str = "none") -> tuple[Path, Path]:
    """Write ``image`` (linear, image orientation) by suffix: ``.png`` = exposure, tonemap, sRGB,
    8-bit; ``.exr`` = linear float32. A sidecar ``<out_path>.json`` records ``info``.
    Returns ``(image_path, sidecar_path)``."""
    out_path = Path(out_path)
    suffix = out_path.suffix.lower()
    if suffix not in IMAGE_SUFFIXES:
        raise ValueError(f"{out_path}: unknown image type {suffix or '(none)'!r}; use .png or .exr")
    out_path.parent.mkdir(parents=True, exist_ok=True)
    record = dict(info)
    if suffix == ".png":
        write_png(out_path, image, exposure=exposure, tonemap=tonemap)
        record["file"] = {"format": "png", "encoding": "srgb 8-bit", "exposure": exposure, "tonemap": tonemap}
    else:
        write_exr(out_path, image)
        record["file"] = {"format": "exr", "encoding": "linear float32"}
    return out_path, write_sidecar(out_path, record)


def _where(bundle: Bundle) -> str:
    return str(bundle.path) if bundle.path is not None else "<bundle in memory>"
