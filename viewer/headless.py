"""Render a scene or a bundle without a window: `inshade render trained/neural_image -o shot.png`.

A folder with a ``scene.json`` is rendered as that scene says (viewer/scene.py); a bundle without
one is rendered as its ``render`` field says (the format before scenes). Both go through
``renderer.SceneRenderer``, the same per-frame render function the window app uses.

The bundle says how it is shown in its optional top-level ``render`` field, e.g.

    {"program": "passes/field2d.frag", "width": 256, "height": 256, "input": "uv", "output": "rgb"}

``program`` is the fragment chunk drawn over a full-screen triangle, with the generated network
included as ``<network>``; ``width``/``height`` the default size; ``input``/``output`` name the
bundle ports the program feeds and shows. No torch here: codegen + moderngl + numpy only.
"""
from __future__ import annotations

import json
import logging
import time
from pathlib import Path

import numpy as np

from inshade.bundle import Bundle, load

from .camera import camera_from_dict
from .context import make_current, shared_context
from .image_io import write_exr, write_png, write_sidecar
from .programs import ProgramCache
from .renderer import SceneRenderer
from .scene import Scene, load_scene, scene_from_bundle

log = logging.getLogger("inshade")

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
    if program is None and bundle.kind == "transfer":   # models/transfer_net.py: shading needs geometry
        raise RenderSpecError(f"{where}: a transfer bundle is drawn by a PRT scene, not on its own: a scene.json "
                              "with \"program\": \"passes/sdf_prt.frag\" (or mesh_prt.frag), the geometry "
                              "(\"sdf\" or \"mesh\") and \"networks\": [{\"bundle\": ...}] naming this bundle")
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
    lanes = bundle.output_lanes(out_name)
    if lanes is None:
        raise RenderSpecError(f"{where}: render.output: no output named {out_name!r} "
                              f"(outputs: {', '.join(p.name for p in bundle.outputs)})")
    offset, dim = lanes
    if dim not in (1, 3, 4):
        raise RenderSpecError(f"{where}: render.output: {out_name!r} is {dim} wide; 1, 3 or 4 can be shown")
    out.update(program=program, input=in_name, output=out_name, out_offset=offset, out_dim=dim)
    return out


def render_bundle(bundle, *, width: int | None = None, height: int | None = None, storage: str = "auto",
                  lut_filter: str = "exact", ctx=None, cache: ProgramCache | None = None):
    """Render a bundle (folder, bundle.json path, or ``Bundle``) as its ``render`` field says.

    Returns ``(image, info)``: ``image`` is linear RGBA float32 ``[H, W, 4]`` in image orientation
    (row 0 = top, as ``render.read_rgba``); ``info`` records the GL driver, the bundle digest, the
    storage plan, the size and timings (for the sidecar JSON). ``ctx`` defaults to the shared
    headless context. The scene is the one ``scene.scene_from_bundle`` derives from the bundle.
    """
    t0 = time.perf_counter()
    if not isinstance(bundle, Bundle):
        bundle = load(bundle)
    scene = scene_from_bundle(bundle)
    return render_scene(scene, width=width, height=height, settings={"storage": storage, "lut_filter": lut_filter},
                        ctx=ctx, cache=cache, bundles=[bundle], _t0=t0)


def render_scene(scene, *, width: int | None = None, height: int | None = None, camera=None, mode=None,
                 split: float | None = None, settings: dict | None = None, ctx=None,
                 cache: ProgramCache | None = None, bundles=None, _t0: float | None = None):
    """Render a scene (``Scene`` or anything ``load_scene`` takes) headless, once, through the same
    ``SceneRenderer`` the window app draws with. ``camera`` (a camera object or its dict) defaults to
    the scene's; ``mode``/``split`` to the scene's display settings. Returns ``(image, info)`` as
    ``render_bundle``."""
    t0 = time.perf_counter() if _t0 is None else _t0
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    width = scene.size[0] if width is None else int(width)
    height = scene.size[1] if height is None else int(height)
    if not (1 <= width <= MAX_SIZE and 1 <= height <= MAX_SIZE):
        raise ValueError(f"render size {width}x{height} out of range 1..{MAX_SIZE}")
    if camera is None:
        camera = scene.make_camera()
    elif isinstance(camera, dict):
        camera = camera_from_dict(camera)
    ctx = shared_context() if ctx is None else make_current(ctx)
    t_load = time.perf_counter()
    renderer = SceneRenderer(scene, ctx, cache=cache, settings=settings, bundles=bundles)
    try:
        t_gen = time.perf_counter()
        renderer.render(camera, width, height, mode=mode, split=split)
        ctx.finish()
        t_read = time.perf_counter()
        image = renderer.read()
        t_end = time.perf_counter()
        info = renderer.info(camera, width, height, mode=mode, split=split)
    finally:
        renderer.release()
    info["timing_s"] = {"load": round(t_load - t0, 6), "generate": round(t_gen - t_load, 6),
                        "compile": round(renderer.compile_seconds, 6), "draw": round(t_read - t_gen, 6),
                        "read": round(t_end - t_read, 6), "total": round(t_end - t0, 6)}
    return image, info


def render_from_sidecar(sidecar, *, ctx=None, cache: ProgramCache | None = None):
    """Re-render the image a screenshot's JSON sidecar describes: same scene, camera, mode, split,
    settings and size. Returns ``(image, info, record)``; warns (log) if a bundle changed since."""
    sidecar = Path(sidecar)
    try:
        record = json.loads(sidecar.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{sidecar}: not a readable JSON sidecar ({exc})") from None
    scene_path = (record.get("scene") or {}).get("path")
    view = record.get("view")
    if not scene_path or not isinstance(view, dict):
        raise ValueError(f"{sidecar}: no 'scene.path'/'view' fields; only sidecars written by inshade "
                         "(render or view screenshots) can be re-rendered")
    scene = load_scene(scene_path)
    size = record.get("render", {})
    image, info = render_scene(scene, width=size.get("width"), height=size.get("height"), camera=view["camera"],
                               mode=view.get("mode"), split=view.get("split"), settings=view.get("settings"),
                               ctx=ctx, cache=cache)
    old = {b["name"]: b["digest"] for b in record.get("bundles", [])}
    for b in info["bundles"]:
        if b["name"] in old and old[b["name"]] != b["digest"]:
            log.warning("bundle %s changed since %s was taken: the image will differ", b["name"], sidecar)
    return image, info, record


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
