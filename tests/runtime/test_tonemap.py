"""Tone mapping (scene/tonemap.py, lib/tonemap): the present pass the window and the page draw with
against the PNG writer's numpy twin through the real driver, Khronos PBR Neutral against numbers
worked from its definition, and where the tone mapper applies: PNGs and the window follow the
``tonemap`` setting and the display mode, the float image and EXRs stay linear, and the sidecar says
which operator made a PNG."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import moderngl
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from inshade.geometry import gltf_scenes
from inshade.runtime.programs import ProgramCache
from inshade.runtime.render import FullscreenPass
from inshade.scene.image_io import display_pixels, read_exr
from inshade.scene.tonemap import TONEMAPS, glsl_chunk, presented_tonemap, tonemap


@pytest.fixture
def present(gl):
    cache = ProgramCache(gl)
    p = FullscreenPass(gl, cache.get("common/fullscreen.vert", "passes/present.frag",
                                     chunks={"tonemaps": glsl_chunk()}))
    yield gl, p
    p.vao.release()


def _present(gl, p, linear: np.ndarray, op: str) -> np.ndarray:
    """``linear`` [H, W, 3] through the present pass into an RGBA8 target, rows top to bottom."""
    h, w = linear.shape[:2]
    rgba = np.concatenate([linear, np.ones((h, w, 1))], -1).astype("f4")[::-1]
    src = gl.texture((w, h), 4, np.ascontiguousarray(rgba).tobytes(), dtype="f4")
    src.filter = (moderngl.NEAREST, moderngl.NEAREST)
    out = gl.texture((w, h), 4)
    fbo = gl.framebuffer([out])
    try:
        gl.viewport = (0, 0, w, h)
        p.render(fbo, uniforms={"u_origin": (0.0, 0.0), "u_scale": (1.0, 1.0), "u_tonemap": TONEMAPS.index(op)},
                 textures={"u_source": src})
        got = np.frombuffer(fbo.read(components=4), np.uint8).reshape(h, w, 4)[::-1, :, :3]
    finally:
        fbo.release(); out.release(); src.release()   # noqa: E702
    return got


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2 ** 31 - 1), scale=st.sampled_from([0.1, 1.0, 4.0, 40.0]))
@pytest.mark.parametrize("op", TONEMAPS)
def test_the_present_pass_shows_what_the_png_holds(present, op, seed, scale):
    """Every tone mapper in the present pass against display_pixels: the same 8-bit values, but for
    a rounding tie (one level, on few pixels)."""
    gl, p = present
    rng = np.random.default_rng(seed)
    linear = rng.uniform(0.0, 1.0, (16, 16, 3)) ** 3 * scale
    linear[0, :4] = [[0.0, 0.0, 0.0], [0.08, 0.2, 0.9], [1.0, 0.686, 0.0], [0.76, 0.76, 0.76]]
    got = _present(gl, p, linear, op).astype(int)
    want = display_pixels(linear.astype(np.float32), tonemap=op).astype(int)
    diff = np.abs(got - want)
    assert diff.max() <= 1 and (diff > 0).mean() < 0.02, (op, diff.max(), (diff > 0).mean())


def test_pbr_neutral_follows_its_definition():
    """Worked by hand from Khronos PBR Neutral: below the shoulder a colour only loses its small
    offset (0.04, or x - 6.25 x^2 for a darkest channel under 0.08); above it the peak is compressed
    to 1 - d^2 / (peak + d - 0.76), d = 0.24, and mixed towards grey."""
    np.testing.assert_allclose(tonemap([0.5, 0.3, 0.1], "pbr_neutral"), [0.46, 0.26, 0.06], atol=1e-12)
    np.testing.assert_allclose(tonemap([0.5, 0.3, 0.04], "pbr_neutral"),
                               [0.5 - 0.03, 0.3 - 0.03, 0.04 - 0.03], atol=1e-12)
    np.testing.assert_allclose(tonemap([1.0, 1.0, 1.0], "pbr_neutral"), [1 - 0.0576 / 0.44] * 3, atol=1e-12)
    yellow = tonemap([1.0, 0.686, 0.0], "pbr_neutral")
    new_peak = 1 - 0.0576 / 0.48
    g = 1 - 1 / (0.15 * (1.0 - new_peak) + 1)
    np.testing.assert_allclose(yellow, [new_peak, 0.686 * new_peak * (1 - g) + new_peak * g, new_peak * g],
                               atol=1e-12)
    ramp = tonemap(np.linspace(0, 100, 1001)[:, None].repeat(3, 1), "pbr_neutral")[:, 0]
    assert (np.diff(ramp) > 0).all() and ramp.max() < 1.0


def test_only_pictures_of_the_scene_are_tone_mapped():
    values = {"tonemap": "pbr_neutral"}
    assert [presented_tonemap(values, m) for m in ("final", "reference", "split")] == ["pbr_neutral"] * 3
    assert [presented_tonemap(values, m) for m in ("network", "error")] == ["none"] * 2
    assert presented_tonemap({}, "final") == "none"


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "inshade.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=600, env=dict(os.environ))


def test_a_gltf_png_is_tone_mapped_and_says_so_while_its_exr_stays_linear(tmp_path):
    """``inshade render FILE.glb``: the PNG is PBR Neutral of the EXR's linear values (the file's first
    look), its sidecar names the operator; ``--set tonemap=none`` gives the clipped look."""
    glb = gltf_scenes.tiles_torus().write(tmp_path / "tiles.glb")
    size = ("--width", "48", "--height", "48")
    for out, extra in (("look.png", ()), ("look.exr", ()), ("plain.png", ("--set", "tonemap=none"))):
        r = _cli("render", glb, "-o", tmp_path / out, *size, *extra)
        assert r.returncode == 0, r.stderr
    linear = read_exr(tmp_path / "look.exr")
    exr_side = json.loads((tmp_path / "look.exr.json").read_text())
    assert exr_side["file"] == {"format": "exr", "encoding": "linear float32"}
    from PIL import Image

    for name, op in (("look.png", "pbr_neutral"), ("plain.png", "none")):
        side = json.loads((tmp_path / f"{name}.json").read_text())
        assert side["file"]["tonemap"] == op and side["view"]["settings"]["tonemap"] == op
        png = np.asarray(Image.open(tmp_path / name).convert("RGB"))
        np.testing.assert_array_equal(png, display_pixels(linear[..., :3], tonemap=op))
    assert (np.asarray(Image.open(tmp_path / "look.png")) != np.asarray(Image.open(tmp_path / "plain.png"))).any()
