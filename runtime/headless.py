"""Render a scene or a bundle without a window: `inshade render ASSET -o shot.png`.

A folder with a ``scene.json`` is rendered as that scene says (runtime/scene.py); a bundle without
one is rendered as its ``render`` field says (the format before scenes). Both go through
``renderer.SceneRenderer``, the same per-frame render function the window app uses.

The bundle says how it is shown in its optional top-level ``render`` field, e.g.

    {"program": "passes/field2d.frag", "width": 256, "height": 256, "input": "uv", "output": "rgb"}

``program`` is a fragment chunk whose technique lets a bundle name it (``ProgramSpec.field_inputs``),
drawn over a full-screen triangle with the generated network included as ``<network>``; ``width``/``height`` the default size; ``input``/``output`` name the
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
from inshade.files import atomic_files

from .image_io import sidecar_path, sidecar_text, write_exr, write_png
from .programs import ProgramCache
from .renderer import SceneRenderer
from .scene import MAX_SIZE, RenderSpecError, Scene, load_scene, render_spec, scene_from_bundle  # noqa: F401

log = logging.getLogger("inshade")

IMAGE_SUFFIXES = (".png", ".exr")


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
    record = dict(info)
    if suffix == ".png":
        record["file"] = {"format": "png", "encoding": "srgb 8-bit", "exposure": exposure, "tonemap": tonemap}
    else:
        record["file"] = {"format": "exr", "encoding": "linear float32"}
    side = sidecar_path(out_path)
    text = sidecar_text(record)          # a record that cannot be written fails before any file exists
    with atomic_files(out_path, side) as (image_tmp, side_tmp):   # both appear, or neither
        if suffix == ".png":
            write_png(image_tmp, image, exposure=exposure, tonemap=tonemap)
        else:
            write_exr(image_tmp, image)
        side_tmp.write_text(text)
    return out_path, side
