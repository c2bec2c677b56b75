"""Render a scene or a bundle without a window: `inshade render ASSET -o shot.png`.

A folder with a ``scene.json`` is rendered as that scene says (scene/description.py); a bundle without
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

from inshade.scene.camera import camera_from_dict
from .context import make_current, shared_context
from inshade.files import atomic_files

from inshade.scene.image_io import sidecar_path, sidecar_text, write_exr, write_png
from inshade.scene.tonemap import presented_tonemap
from .programs import ProgramCache
from .renderer import SceneRenderer
from inshade.scene.description import MAX_SIZE, RenderSpecError, Scene, load_scene, render_spec, scene_from_bundle  # noqa: F401

log = logging.getLogger("inshade")

IMAGE_SUFFIXES = (".png", ".exr")


def render_bundle(bundle, *, width: int | None = None, height: int | None = None, storage: str = "auto",
                  lut_filter: str = "exact", ctx=None, cache: ProgramCache | None = None, spp: int = 1):
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
                        ctx=ctx, cache=cache, bundles=[bundle], spp=spp, _t0=t0)


def render_scene(scene, *, width: int | None = None, height: int | None = None, camera=None, mode=None,
                 split: float | None = None, settings: dict | None = None, ctx=None,
                 cache: ProgramCache | None = None, bundles=None, spp: int = 1, quick: bool = False,
                 sdf_bundle=None, _t0: float | None = None):
    """Render a scene (``Scene`` or anything ``load_scene`` takes) headless, once, through the same
    ``SceneRenderer`` the window app draws with. ``camera`` (a camera object or its dict) defaults to
    the scene's; ``mode``/``split`` to the scene's display settings. ``spp``: samples per pixel
    averaged by an accumulating program (``ProgramSpec.accumulate``; others take only 1). ``quick``:
    at storage ``auto``, draw with the storage that ends this one job sooner (runtime/quick_program.py;
    ``info["storage_choice"]`` says why where it changed). ``bundles`` / ``sdf_bundle``: the networks
    (and a network SDF) to draw instead of the scene's files. Returns ``(image, info)`` as
    ``render_bundle``; ``info["spp"]`` is the sample count."""
    t0 = time.perf_counter() if _t0 is None else _t0
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    width = scene.size[0] if width is None else int(width)
    height = scene.size[1] if height is None else int(height)
    if not (1 <= width <= MAX_SIZE and 1 <= height <= MAX_SIZE):
        raise ValueError(f"render size {width}x{height} out of range 1..{MAX_SIZE}")
    check_spp(scene, spp)
    if camera is None:
        camera = scene.make_camera()
    elif isinstance(camera, dict):
        camera = camera_from_dict(camera)
    ctx = shared_context() if ctx is None else make_current(ctx)
    check_render_size(ctx, width, height)
    t_load = time.perf_counter()
    renderer = SceneRenderer(scene, ctx, cache=cache, settings=settings, bundles=bundles, sdf_bundle=sdf_bundle,
                             quick=(width * height, spp) if quick else None)
    try:
        t_gen = time.perf_counter()
        renderer.accumulate(camera, width, height, spp)   # a deterministic program: its one draw
        renderer.render(camera, width, height, mode=mode, split=split)
        ctx.finish()
        t_read = time.perf_counter()
        image = renderer.read()
        t_end = time.perf_counter()
        info = renderer.info(camera, width, height, mode=mode, split=split)
        if renderer.storage_choice:
            info["storage_choice"] = renderer.storage_choice
    finally:
        renderer.release()
    info["timing_s"] = {"load": round(t_load - t0, 6), "generate": round(t_gen - t_load, 6),
                        "compile": round(renderer.compile_seconds, 6), "draw": round(t_read - t_gen, 6),
                        "read": round(t_end - t_read, 6), "total": round(t_end - t0, 6)}
    return image, info


def check_spp(scene: Scene, spp) -> None:
    """``spp`` is an int >= 1, and 1 unless the scene's program accumulates samples."""
    if isinstance(spp, bool) or not isinstance(spp, int) or spp < 1:
        raise ValueError(f"spp: must be an int >= 1, got {spp!r}")
    if spp > 1 and not scene.spec.accumulate:
        raise ValueError(f"spp {spp}: program {scene.program} of scene '{scene.name}' draws one deterministic "
                         "sample per pixel (it does not accumulate samples); use 1")


# Host bytes per pixel a render needs at its peak: the RGBA float32 readback (16) and write_png's float64
# copy of it (32) plus its float64 intermediates (~48).
HOST_BYTES_PER_PIXEL = 96


def check_render_size(ctx, width: int, height: int) -> None:
    """Refuse, before allocating anything, a render size this context or this machine cannot hold:
    GL_MAX_RENDERBUFFER_SIZE, GL_MAX_VIEWPORT_DIMS, GL_MAX_TEXTURE_SIZE (the targets are RGBA32F
    textures plus a depth renderbuffer), and the host memory the readback and encoding need."""
    info = ctx.info
    viewport = info.get("GL_MAX_VIEWPORT_DIMS") or (None, None)
    limits = [("GL_MAX_RENDERBUFFER_SIZE", info.get("GL_MAX_RENDERBUFFER_SIZE"), info.get("GL_MAX_RENDERBUFFER_SIZE")),
              ("GL_MAX_VIEWPORT_DIMS", viewport[0], viewport[1]),
              ("GL_MAX_TEXTURE_SIZE", info.get("GL_MAX_TEXTURE_SIZE"), info.get("GL_MAX_TEXTURE_SIZE"))]
    for name, max_w, max_h in limits:
        if max_w is None or max_h is None:
            continue
        if width > int(max_w) or height > int(max_h):
            shown = f"{max_w}x{max_h}" if name == "GL_MAX_VIEWPORT_DIMS" else f"{max_w}"
            raise ValueError(f"render size {width}x{height} exceeds {name}={shown} of {info.get('GL_RENDERER')}; "
                             f"at most {min(width, int(max_w))}x{min(height, int(max_h))}")
    need = width * height * HOST_BYTES_PER_PIXEL
    avail = _available_memory()
    if avail is not None and need > avail:
        side = int((avail / HOST_BYTES_PER_PIXEL) ** 0.5)
        raise ValueError(f"render size {width}x{height} needs about {need / 2**30:.1f} GiB of memory to read back "
                         f"and encode; this machine has {avail / 2**30:.1f} GiB available; at most about "
                         f"{side}x{side} pixels")


def _available_memory() -> int | None:
    """MemAvailable (Linux), lowered to this process's address-space limit (RLIMIT_AS) if it has
    one; None if neither is known (not checked)."""
    found = []
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    found.append(int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        pass
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY:
            found.append(soft)
    except (ImportError, OSError, ValueError):
        pass
    return min(found) if found else None


def render_from_sidecar(sidecar, *, ctx=None, cache: ProgramCache | None = None):
    """Re-render the image a screenshot's JSON sidecar describes: same scene, camera, mode, split,
    settings and size. Returns ``(image, info, record)``; warns (log) if a bundle changed since."""
    from inshade.bundle import JSONFileError, read_json

    sidecar = Path(sidecar)
    try:
        record = read_json(sidecar)
    except JSONFileError as exc:
        raise ValueError(f"{sidecar}: not a readable JSON sidecar ({exc})") from None
    scene_path = (record.get("scene") or {}).get("path") if isinstance(record, dict) else None
    view = record.get("view") if isinstance(record, dict) else None
    if not isinstance(scene_path, str) or not scene_path or not isinstance(view, dict):
        raise ValueError(f"{sidecar}: no 'scene.path'/'view' fields; only sidecars written by inshade "
                         "(render or view screenshots) can be re-rendered")
    size = record.get("render", {})
    if not isinstance(size, dict) or not isinstance(view.get("camera"), dict) or not isinstance(
            view["camera"].get("type"), str) or not isinstance(
            view.get("settings", {}), dict) or not isinstance(record.get("bundles", []), list):
        raise ValueError(f"{sidecar}: render/view.camera/view.settings/bundles: malformed; only sidecars "
                         "written by inshade (render or view screenshots) can be re-rendered")
    spp = record.get("spp", 1)   # sidecars from before accumulation have none: one sample
    if isinstance(spp, bool) or not isinstance(spp, int) or spp < 1:
        raise ValueError(f"{sidecar}: spp: must be an int >= 1, got {spp!r}")
    for key in ("width", "height"):
        v = size.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_SIZE):
            raise ValueError(f"{sidecar}: render.{key}: must be an int in 1..{MAX_SIZE}, got {v!r}")
    scene = load_scene(scene_path)
    image, info = render_scene(scene, width=size.get("width"), height=size.get("height"), camera=view["camera"],
                               mode=view.get("mode"), split=view.get("split"), settings=view.get("settings"),
                               ctx=ctx, cache=cache, spp=spp)
    old = {b.get("name"): b.get("digest") for b in record.get("bundles", []) if isinstance(b, dict)}
    for b in info["bundles"]:
        if b["name"] in old and old[b["name"]] != b["digest"]:
            log.warning("bundle %s changed since %s was taken: the image will differ", b["name"], sidecar)
    return image, info, record


def save_render(image: np.ndarray, info: dict, out_path, *, exposure: float = 1.0,
                tonemap: str | None = None) -> tuple[Path, Path]:
    """Write ``image`` (linear, image orientation) by suffix: ``.png`` = exposure, tonemap, sRGB,
    8-bit, with the scene's labels drawn over it (scene/labels.py; the built-in setting ``labels``
    turns them off); ``.exr`` = linear float32, never tone mapped or labelled. ``tonemap`` defaults
    to what the window shows for the recorded view (the ``tonemap`` setting, scene/tonemap.py). A
    sidecar ``<out_path>.json`` records ``info``. Returns ``(image_path, sidecar_path)``."""
    out_path = Path(out_path)
    if tonemap is None:
        view = info.get("view") or {}
        tonemap = presented_tonemap(view.get("settings") or {}, view.get("mode", "final"))
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
            _draw_labels(image_tmp, info)
        else:
            write_exr(image_tmp, image)
        side_tmp.write_text(text)
    return out_path, side


def _draw_labels(png_path, info: dict) -> None:
    """The scene's labels (scene.json ``"labels"``, for the recorded settings and mode) over the 8-bit
    PNG only: the float image and the EXR stay as rendered."""
    from inshade.scene.labels import draw_on_png, labels_for_info

    labels = labels_for_info(info)
    if not labels:
        return
    try:
        camera = camera_from_dict(info["view"]["camera"])
    except Exception:   # noqa: BLE001 - no camera recorded: labels in image space
        camera = None
    draw_on_png(png_path, labels, camera)
