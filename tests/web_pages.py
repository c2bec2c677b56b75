"""What the page tests share (tests/web/test_web.py: WebGL2, test_webgpu_page.py: WebGPU): the assets
checked, an asset's page exported at the size it is compared at, and ``inshade render``'s picture of
it (the shipped-render record where this machine's renderer made it, else a fresh render)."""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from inshade.scene.description import load_scene, resolve_asset
from inshade.web.browser import psnr8, serve, srgb8
from inshade.web.export import export_web

from shipped_renders import MADE_BY, ONE_PER_TECHNIQUE, RECORD, key, size

MIN_PSNR_DB = 40.0
# Compared at the scene's own size, not the record's quarter: its bricks repeat every few pixels there,
# so the two rasterisers' attribute interpolation (uv apart by ~1e-4) aliases differently
# (38.1 dB at half size, 35.4 at a quarter, 41.1 at its own 256x256).
AT_OWN_SIZE = {"di_pbr_set_bricks"}
TRAINED = Path(__file__).resolve().parent.parent / "trained"
ASSETS = sorted(p.name for p in TRAINED.iterdir() if p.is_dir()) if os.environ.get("INSHADE_SLOW") \
    else ONE_PER_TECHNIQUE


def render_record():
    """The shipped-render record, where this machine's renderer made it (else None)."""
    from inshade.runtime.context import shared_context

    info = shared_context().info
    made_by = json.loads(MADE_BY.read_text())
    same = made_by["gl_renderer"] == info["GL_RENDERER"] and made_by["gl_version"] == info["GL_VERSION"]
    return np.load(RECORD) if same else None


def inshade_render(asset: str, record) -> np.ndarray:
    """``inshade render`` of the asset at the record's size, as the 8-bit sRGB a PNG holds."""
    from inshade.runtime.headless import render_scene

    if record is not None and key(asset, {}) in record and asset not in AT_OWN_SIZE:
        return srgb8(record[key(asset, {})])
    scene = load_scene(resolve_asset(asset))
    w, h = scene.size if asset in AT_OWN_SIZE else size(scene.size)
    image, _ = render_scene(scene, width=w, height=h)
    return srgb8(image)


def exported(asset, tmp_path, api: str = "webgl2") -> tuple[Path, tuple[int, int]]:
    scene = load_scene(resolve_asset(asset))
    w, h = scene.size if asset in AT_OWN_SIZE else size(scene.size)
    folder = tmp_path / "page"
    export_web(resolve_asset(asset), folder, width=w, height=h, api=api)
    return folder, (w, h)


def errors(console: list[str]) -> list[str]:
    return [line for line in console if line.startswith("SEVERE")]


def check_page(browser, record, asset: str, api: str, tmp_path) -> None:
    """The asset's page on ``api``: no error, progress said before the first frame (the compile, then
    the draw; then that the quarter-size first frame is up while the full one is drawn), and the
    picture inshade render draws."""
    folder, (w, h) = exported(asset, tmp_path, api)
    with serve(folder) as url:
        state = browser.open(url + "index.html")
        assert state["error"] is None, f"{asset} ({api}): the page says: {state['error']}"
        assert not errors(state["console"]), f"{asset} ({api}): console errors: {state['console']}"
        assert browser.driver.execute_script("return window.inshade.api;") == api
        page = browser.canvas()
        progress = browser.driver.execute_script("return window.inshade.progress;")
    compiled, first = progress[-2:]
    assert compiled["text"].startswith("compiled ") and compiled["ms"] <= state["first_frame_ms"], progress
    assert first["text"].startswith("first frame at 1/4 size") and first["ms"] == state["first_frame_ms"], progress
    assert state["first_frame_ms"] <= state["full_frame_ms"]
    assert page.shape == (h, w, 3)
    db = psnr8(page, inshade_render(asset, record))
    assert db >= MIN_PSNR_DB, f"{asset} ({api}): the page's first frame is {db:.2f} dB from inshade render's"
