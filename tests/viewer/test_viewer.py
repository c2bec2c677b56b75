"""The interactive viewer: camera math, scene files, and the window app under Xvfb.

The window tests start their own Xvfb on a free display number (Xvfb is a test requirement:
they fail, saying to install xvfb, where it is missing). One app at 320x240 is shared by the module, with
`texture` weight storage (llvmpipe JIT-compiles a network program at its first draw: ~8 s for this
storage vs ~35 s for `ubo`), so the network program is compiled once.
"""
import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from inshade.scene.description import list_scenes
from inshade.scene.camera import CameraError, FlyCamera, OrbitCamera, Plane2DCamera, camera_from_dict
from inshade.scene.display import DisplayMode, UI_MODES, glsl_chunk, parse_mode
from inshade.scene.description import SceneError, load_scene
from shipped_renders import ONE_PER_TECHNIQUE

ROOT = Path(__file__).resolve().parents[2]
ASSET = ROOT / "trained" / "neural_image"
SIZE = (320, 240)
STORAGE = {"storage": "texture"}


# camera math (pyrr) -------------------------------------------------------------------------------
def test_plane2d_default_view_is_exact_identity():
    cam = Plane2DCamera()
    assert cam.view(256, 256) == (0.0, 0.0, 1.0, 1.0)
    assert cam.uniforms(64, 64) == {"u_view": (0.0, 0.0, 1.0, 1.0)}


def test_plane2d_fits_the_square_in_wide_and_tall_targets():
    cam = Plane2DCamera()
    ox, oy, sx, sy = cam.view(200, 100)      # wide: full height, wider uv range
    assert (sy, sx) == (1.0, 2.0) and (ox, oy) == (-0.5, 0.0)
    ox, oy, sx, sy = cam.view(100, 200)      # tall: full width
    assert (sx, sy) == (1.0, 2.0) and (ox, oy) == (0.0, -0.5)


def test_plane2d_zoom_keeps_the_point_under_the_cursor():
    cam = Plane2DCamera()
    before = cam.uv_at(30, 70, 160, 120)
    cam.zoom_at(3.0, 30, 70, 160, 120)
    assert cam.zoom == 3.0
    np.testing.assert_allclose(cam.uv_at(30, 70, 160, 120), before, atol=1e-12)


def test_plane2d_pan_follows_the_cursor():
    cam = Plane2DCamera()
    uv = cam.uv_at(50, 50, 100, 100)
    cam.pan(10, -20, 100, 100)               # drag right 10 px and up 20 px
    np.testing.assert_allclose(cam.uv_at(60, 30, 100, 100), uv, atol=1e-12)


def test_orbit_camera_looks_at_its_target():
    cam = OrbitCamera(target=(1.0, 2.0, 3.0), distance=4.0, yaw=30.0, pitch=20.0)
    assert np.linalg.norm(cam.eye() - np.array(cam.target)) == pytest.approx(4.0)
    target_view = np.append(cam.target, 1.0) @ cam.view_matrix()   # pyrr: row vectors
    np.testing.assert_allclose(target_view[:3], [0.0, 0.0, -4.0], atol=1e-12)  # straight ahead, -z
    default = OrbitCamera(distance=2.0)
    np.testing.assert_allclose(default.eye(), [0.0, 0.0, 2.0], atol=1e-12)     # looks down -z


def test_orbit_drag_clamps_pitch_and_zoom_scales_distance():
    cam = OrbitCamera()
    cam.orbit(0, -10_000)
    assert cam.pitch == pytest.approx(cam.max_pitch)
    cam.zoom(0.5)
    assert cam.distance == pytest.approx(1.5)


def test_orbit_pan_moves_the_target_across_the_view():
    cam = OrbitCamera(distance=5.0, yaw=40.0, pitch=10.0)
    fwd = cam.forward()
    cam.pan(12, -7, 200, 100)
    moved = np.array(cam.target)
    assert np.linalg.norm(moved) > 0 and abs(moved @ fwd) < 1e-12


def test_frame_fits_the_bounding_sphere_in_the_field_of_view():
    cam = OrbitCamera(fov_y=60.0)
    cam.frame((-1, -1, -1), (3, 1, 1))
    np.testing.assert_allclose(cam.target, (1, 0, 0))
    radius = math.sqrt(4**2 + 2**2 + 2**2) / 2
    assert math.asin(radius / cam.distance) == pytest.approx(math.radians(30.0))


def test_projection_maps_near_and_far_planes_to_ndc():
    cam = OrbitCamera(near=0.5, far=20.0)
    proj = cam.projection(300, 200)
    for z, ndc in ((-0.5, -1.0), (-20.0, 1.0)):
        clip = np.array([0.0, 0.0, z, 1.0]) @ proj
        assert clip[2] / clip[3] == pytest.approx(ndc)
    u = cam.uniforms(300, 200)
    assert len(u["u_view_matrix"]) == 64 and len(u["u_inv_view_proj"]) == 64


def test_fly_camera_moves_where_it_looks():
    cam = FlyCamera(position=(0.0, 0.0, 3.0))
    cam.move(1.0, 0.0, 0.0, dt=0.5)
    np.testing.assert_allclose(cam.position, (0.0, 0.0, 2.5), atol=1e-12)   # forward = -z
    cam.move(0.0, 1.0, 0.0, dt=1.0)
    np.testing.assert_allclose(cam.position, (1.0, 0.0, 2.5), atol=1e-12)   # right = +x
    cam.look(-90 / cam.look_speed, 0)
    np.testing.assert_allclose(cam.forward(), (1.0, 0.0, 0.0), atol=1e-12)  # turned right


@pytest.mark.parametrize("cam", [Plane2DCamera(center=(0.3, 0.6), zoom=2.5),
                                 OrbitCamera(target=(1, 2, 3), yaw=10, pitch=-5, distance=7),
                                 FlyCamera(position=(1, 1, 1), yaw=3, speed=2)])
def test_camera_json_round_trip(cam):
    again = camera_from_dict(json.loads(json.dumps(cam.to_dict())))
    assert again.to_dict() == cam.to_dict()


@pytest.mark.parametrize("data, match", [
    ({"type": "perspective"}, "camera.type: unknown camera 'perspective'"),
    ({"type": "orbit", "distnace": 3}, "camera.distnace: not a field of a orbit camera"),
    ({"type": "orbit", "target": [0, 0]}, "camera.target: must be 3 numbers"),
    ({"type": "plane2d", "zoom": "big"}, "camera.zoom: must be a finite number"),
])
def test_bad_camera_is_one_clear_error(data, match):
    with pytest.raises(CameraError, match=match):
        camera_from_dict(data)


# display modes: one Python enum, the GLSL constants generated from it --------------------------
def test_display_modes_are_mirrored_in_glsl():
    defines = dict(line.split()[1:] for line in glsl_chunk().splitlines() if line.startswith("#define"))
    assert defines == {f"DISPLAY_{m.name}": str(int(m)) for m in DisplayMode}
    source = (ROOT / "shaders" / "passes" / "display.frag.glsl").read_text()
    assert all(f"DISPLAY_{m.name}" in source for m in DisplayMode)
    assert parse_mode("split") is DisplayMode.SPLIT and parse_mode(3) is DisplayMode.ERROR
    with pytest.raises(ValueError, match="unknown display mode 'bogus'"):
        parse_mode("bogus")


# scene files -------------------------------------------------------------------------------------
def test_shipped_scene_parses():
    scene = load_scene(ASSET)
    assert scene.path == ASSET / "scene.json" and scene.program == "passes/field2d.frag"
    assert scene.reference is not None and scene.reference.image.name == "reference.png"
    assert scene.make_camera().to_dict()["type"] == "plane2d" and "face" in scene.bookmarks
    assert tuple(scene.display_modes) == UI_MODES
    assert {"exposure", "error_scale", "storage"} <= {k for k, s in scene.settings.items() if s.exposed}


def _good_scene() -> dict:
    return json.loads((ASSET / "scene.json").read_text())


def _edit(data, path, value):
    *keys, last = path
    for k in keys:
        data = data[k]
    if value is KeyError:
        del data[last]
    else:
        data[last] = value


@pytest.mark.parametrize("path, value, match", [
    (["format"], "nope", r"format: expected \"inshade.scene\""),
    (["version"], 2, "version: this inshade reads version 1"),
    (["colour"], "red", "colour: unknown field"),
    (["program"], "passes/nothing.frag", "program: no technique draws program 'passes/nothing.frag'"),
    (["size"], [256, 0], r"size: must be \[width, height\]"),
    (["networks"], [], "networks: must be a non-empty list"),
    (["networks", 0, "bundle"], "../missing", r"networks\[0\].bundle: no bundle at"),
    (["reference", "image"], "nope.png", "reference.image: no file"),
    (["reference", "space"], "world", "reference.space: must be one of"),
    (["camera"], {"type": "orbit", "yaw": "left"}, "camera.yaw: must be a finite number"),
    (["bookmarks", "face"], {"type": "pinhole"}, "bookmarks.face.type: unknown camera"),
    (["display", "mode"], "normals", "display: unknown display mode 'normals'"),
    (["settings", "exposure", "default"], 99.0, r"settings.exposure.default: 'exposure': 99.0 is outside"),
    (["settings", "exposure", "max"], KeyError, "a float setting needs a range"),
    (["settings", "storage", "choices"], ["auto", "gpu"], "'gpu' is not a storage option"),
    (["settings", "storage", "uniform"], "u_storage", "needs exactly one of"),
])
def test_bad_scene_file_is_one_clear_error(tmp_path, path, value, match):
    data = _good_scene()
    for name in ("bundle.json", "weights.safetensors", "reference.png"):
        shutil.copy(ASSET / name, tmp_path / name)
    _edit(data, path, value)
    (tmp_path / "scene.json").write_text(json.dumps(data))
    with pytest.raises(SceneError, match=match) as info:
        load_scene(tmp_path)
    assert str(info.value).startswith(str(tmp_path / "scene.json") + ": ")
    assert "\n" not in str(info.value)


def test_unreadable_scene_files(tmp_path):
    (tmp_path / "scene.json").write_text("{ not json")
    with pytest.raises(SceneError, match=r"scene.json: not valid JSON: .* line 1"):
        load_scene(tmp_path)
    with pytest.raises(SceneError, match="neither scene.json nor bundle.json"):
        load_scene(tmp_path / "..")
    with pytest.raises(SceneError, match="no such file or folder"):
        load_scene(tmp_path / "missing")


# the window app under Xvfb ---------------------------------------------------------------------------
WINDOW_NEEDS_ITS_OWN_GL = ("the window draws through glfw's GL context and this run's headless contexts through "
                           "OSMesa (--gl-backend osmesa); PyOpenGL serves one of them per process, so the window "
                           "tests run without it (pytest tests/viewer/test_viewer.py)")


@pytest.fixture(scope="module")
def xvfb():
    from inshade.runtime.context import BACKEND_ENV, pyopengl_bound_to_osmesa

    if os.environ.get(BACKEND_ENV) == "osmesa" or pyopengl_bound_to_osmesa():   # either order fails
        pytest.skip(WINDOW_NEEDS_ITS_OWN_GL)
    from inshade.viewer.virtual_display import VirtualDisplayError, start_xvfb

    try:
        proc, display = start_xvfb()
    except VirtualDisplayError as exc:
        pytest.fail(f"{exc}, as .ci/run does", pytrace=False)
    old = os.environ.get("DISPLAY")
    os.environ["DISPLAY"] = display
    yield display
    if old is None:
        os.environ.pop("DISPLAY", None)
    else:
        os.environ["DISPLAY"] = old
    proc.terminate()
    proc.wait(timeout=10)


@pytest.fixture(scope="module")
def app(xvfb, tmp_path_factory):
    from inshade.viewer.app import ViewerApp

    viewer = ViewerApp(ASSET, size=SIZE, settings=STORAGE, vsync=False,
                       screenshot_dir=tmp_path_factory.mktemp("shots"))
    viewer.step(1)
    assert viewer.compiling            # first frame: "compiling..." while nothing was drawn yet
    viewer.step(2)                     # JIT draw, then a normal frame
    assert not viewer.compiling and viewer.renderer.first_draw_seconds is not None
    yield viewer
    viewer.close()


def _encode(linear: np.ndarray) -> np.ndarray:
    from inshade.scene.image_io import srgb_oetf
    return np.rint(srgb_oetf(linear[..., :3]) * 255).astype(np.int16)


def _scene_pixels(app, window: np.ndarray) -> np.ndarray:
    x, y, w, h = app.scene_rect()
    fh = window.shape[0]
    return window[fh - (y + h):fh - y, x:x + w].astype(np.int16)


def _reset(app, mode="final"):
    app.reset_camera()
    app.set_mode(mode)
    app.split = 0.5


def test_scene_and_panel_are_drawn_where_expected(app):
    _reset(app)
    window = app.read_window()
    assert window.shape == (SIZE[1], SIZE[0], 3)
    x, _, w, h = app.scene_rect()
    assert x == app.panel_width and w == SIZE[0] - x and h == SIZE[1]
    # the scene region holds exactly the renderer's image (sRGB-encoded, +-1 level)
    expected = _encode(app.renderer.read())
    assert np.abs(_scene_pixels(app, window) - expected).max() <= 1
    # ... which is the picture (not the clear colour): the centre row is varied and bright somewhere
    assert _scene_pixels(app, window).std() > 20
    # the panel: imgui's dark window background with bright text on it
    panel = window[:, : app.panel_width].astype(np.int16)
    assert np.median(panel) < 80 and (panel > 200).all(axis=2).sum() > 200
    assert not np.array_equal(panel, window[:, x: x + app.panel_width])


def test_camera_path_moves_the_picture_and_reset_restores_it(app):
    _reset(app)
    first = _scene_pixels(app, app.read_window())
    app.scroll(2)                       # zoom in about the centre
    assert app.camera.zoom == pytest.approx(1.15 ** 2)
    for _ in range(5):                  # a short drag path
        app.drag(4, -3)
        app.step(1)
    zoomed = _scene_pixels(app, app.read_window())
    assert np.abs(zoomed - first).mean() > 5
    app.go_to_bookmark("face")
    assert app.camera.zoom == 4.0
    app.step(1)
    app.reset_camera()
    assert np.array_equal(_scene_pixels(app, app.read_window()), first)


def test_split_view_differs_from_the_network_where_expected(app):
    _reset(app, "final")
    final = _scene_pixels(app, app.read_window())
    app.set_mode("reference")
    reference = _scene_pixels(app, app.read_window())
    app.set_mode("split")
    split = _scene_pixels(app, app.read_window())
    w = split.shape[1]
    left, right = slice(0, w // 2 - 2), slice(w // 2 + 2, w)
    assert np.abs(split[:, left] - final[:, left]).max() <= 1
    assert np.abs(split[:, right] - reference[:, right]).max() <= 1
    assert np.abs(final[:, left] - reference[:, left]).mean() > 1.0   # the network is not the reference
    assert (split[:, w // 2 - 1: w // 2 + 1] == 255).all(axis=2).mean() > 0.9  # the split line
    # toggle and error heat map, and the live PSNR of this view
    app.toggle_reference()
    assert app.mode is DisplayMode.REFERENCE
    app.set_mode("error")
    heat = _scene_pixels(app, app.read_window())
    assert heat.mean() < final.mean()
    assert 18.0 < app.psnr < 40.0


def test_uniform_settings_do_not_recompile(app):
    _reset(app)
    program = app.renderer.program
    assert app.set_setting("exposure", 2.0) == "uniform"
    brighter = _scene_pixels(app, app.read_window())
    assert app.set_setting("exposure", 1.0) == "uniform"
    normal = _scene_pixels(app, app.read_window())
    assert app.renderer.program is program and brighter.mean() > normal.mean() + 10
    assert app.set_setting("exposure", 99.0) == "failed" and "outside" in app.messages[-1]


def test_screenshot_is_reproduced_by_render_from(app, tmp_path):
    from inshade.cli import main
    from inshade.scene.image_io import read_exr

    _reset(app, "split")
    app.scroll(3)
    app.drag(-10, 6)
    app.set_setting("exposure", 1.5)
    app.step(1)
    shot = app.screenshot(tmp_path / "shot.png")
    app.set_setting("exposure", 1.0)
    for key in ("png", "exr", "sidecar", "window"):
        assert shot[key].is_file()
    record = json.loads(shot["sidecar"].read_text())
    assert record["view"]["mode"] == "split" and record["view"]["settings"]["exposure"] == 1.5
    assert record["render"]["width"] == app.scene_rect()[2]
    assert main(["-q", "render", "--from", str(shot["sidecar"]), "-o", str(tmp_path / "again.exr")]) == 0
    ours, again = read_exr(shot["exr"]), read_exr(tmp_path / "again.exr")
    assert ours.shape == again.shape
    np.testing.assert_array_equal(again, ours)   # same program, same uvs: bit-exact
    assert main(["-q", "render", "--from", str(shot["sidecar"])]) == 0   # default: shot.from.png
    from PIL import Image
    a = np.asarray(Image.open(shot["png"]))
    b = np.asarray(Image.open(tmp_path / "shot.from.png"))
    assert np.array_equal(a, b)


def test_missing_capability_is_a_message_not_a_crash(app, tmp_path):
    data = _good_scene()
    data["requires"] = {"gl": 330, "extensions": ["GL_INSHADE_imaginary_feature"]}
    data["networks"][0]["bundle"] = str(ASSET)
    data["reference"]["image"] = str(ASSET / "reference.png")
    (tmp_path / "scene.json").write_text(json.dumps(data))
    before = app.renderer
    assert app.open(tmp_path) is False
    assert app.renderer is before and "GL_INSHADE_imaginary_feature" in app.messages[-1]
    app.step(2)   # still drawing the previous scene, message in the panel


def test_hot_reload_weights_and_shaders(app, tmp_path, monkeypatch):
    from safetensors.numpy import load_file, save_file

    import inshade.shaders.library as library

    asset = tmp_path / "asset"
    shutil.copytree(ASSET, asset, ignore=shutil.ignore_patterns("preview.png"))
    shaders = tmp_path / "shaders"
    shutil.copytree(library.LIBRARY_DIR, shaders, ignore=shutil.ignore_patterns("*.py", "__pycache__"))
    monkeypatch.setattr(library, "LIBRARY_DIR", shaders)
    assert app.open(asset)
    app.step(3)
    _reset(app)
    before = _scene_pixels(app, app.read_window())
    program = app.renderer.program

    # weights: same shapes -> re-upload, no recompile (texture storage keeps weights out of the code)
    tensors = load_file(str(asset / "weights.safetensors"))
    tensors["l2.bias"] = tensors["l2.bias"] + np.float32(0.2)
    time.sleep(0.01)
    save_file(tensors, str(asset / "weights.safetensors"))
    assert app.check_reload(force=True) == "weights reuploaded"
    assert app.renderer.program is program
    after = _scene_pixels(app, app.read_window())
    assert after.mean() > before.mean() + 5

    # a broken chunk: keep drawing the last good program, report chunk + line
    display = shaders / "passes" / "display.frag.glsl"
    good = display.read_text()
    lines = good.splitlines()
    bad_line = next(i for i, s in enumerate(lines) if s.startswith("void main()")) + 2
    lines.insert(bad_line - 1, "    this_is_not_glsl;")
    display.write_text("\n".join(lines) + "\n")
    outcome = app.check_reload(force=True)
    assert outcome.startswith("failed")
    err = app.renderer.error
    assert err.chunk == "passes/display.frag" and err.line == bad_line
    assert np.array_equal(_scene_pixels(app, app.read_window()), after)
    display.write_text(good + "\n// touched\n")
    assert app.check_reload(force=True) == "shaders recompiled"
    assert app.renderer.error is None
    assert np.array_equal(_scene_pixels(app, app.read_window()), after)
    monkeypatch.undo()
    assert app.open(ASSET)
    app.step(3)


def test_soak_gl_objects_stay_flat(app):
    """2,000 frames: camera moves (network redrawn every 10th frame), modes and split cycle, PSNR
    updates, two resizes (targets reallocated). Live GL names are counted with glIs* before/after."""
    import glfw

    from inshade.viewer.app import PSNR_INTERVAL

    _reset(app)
    glfw.set_window_size(app.window, 200, 120)
    app.step(5)
    # the live PSNR's target is made lazily, at most every PSNR_INTERVAL: make it exist before
    # counting, so the count does not depend on how fast this machine ran the earlier frames
    time.sleep(PSNR_INTERVAL)
    app.drag(1, 0)
    app.step(1)
    assert app.renderer._targets.get("stats") is not None
    start = app.gl_object_counts()
    modes = list(UI_MODES)
    t0 = time.perf_counter()
    frames = 2000
    for i in range(frames):
        if i % 10 == 0:
            app.drag(1 if (i // 10) % 2 else -1, 0)
        app.set_mode(modes[i % len(modes)])
        app.split = (i % 100) / 100
        if i in (700, 1400):
            glfw.set_window_size(app.window, 200 + (i == 700) * 24, 120)
        app.step(1)
    seconds = time.perf_counter() - t0
    end = app.gl_object_counts()
    print(f"\nsoak: {frames} frames in {seconds:.1f} s ({frames / seconds:.0f} fps) at "
          f"{app.framebuffer_size}; GL objects start {start} end {end}")
    assert end == start
    glfw.set_window_size(app.window, *SIZE)
    app.step(2)


def test_modes_a_scene_lacks_are_refused_with_the_reason(app):
    """Point 3 of "the first hour": on a scene without a reference, T and keys 3-5 say why in the
    viewport instead of showing a blank checkerboard or doing nothing."""
    import glfw

    try:
        assert app.open(ROOT / "trained" / "prt_mesh"), app.messages[-1:]
        app.step(3)
        assert app.mode is DisplayMode.FINAL
        for mode in ("reference", "error", "split"):
            assert "no reference image" in app.mode_unavailable(mode)
        assert "not a display mode of this scene" in app.mode_unavailable("network")
        assert app.mode_unavailable("final") is None
        plain = _scene_pixels(app, app.read_window())
        app._on_key(app.window, glfw.KEY_T, 0, glfw.PRESS, 0)          # the real key path
        app._on_key(app.window, glfw.KEY_T, 0, glfw.RELEASE, 0)
        assert app.mode is DisplayMode.FINAL and "no reference image" in app.flash_shown
        app.step(1)                 # imgui sizes a new auto-resizing window in its first frame
        told = _scene_pixels(app, app.read_window())                    # the message is in the viewport
        assert np.abs(told - plain).max() > 100
        app._on_key(app.window, glfw.KEY_4, 0, glfw.PRESS, 0)
        app._on_key(app.window, glfw.KEY_4, 0, glfw.RELEASE, 0)
        assert app.mode is DisplayMode.FINAL and app.flash_shown.startswith("error:")
        assert app.set_mode("split") is False and app.mode is DisplayMode.FINAL
        app._flash_until = 0.0                                          # a few seconds later: gone
        assert app.flash_shown is None
        assert np.array_equal(_scene_pixels(app, app.read_window()), plain)
    finally:
        assert app.open(ASSET)
        app.step(3)
    assert app.set_mode("split") and app.toggle_reference() and app.mode is DisplayMode.REFERENCE
    _reset(app)


def test_named_int_settings_are_combos_and_ranges_stay_sliders():
    from inshade.viewer.ui import setting_widget

    ggx = load_scene(ROOT / "trained" / "di_brdf_ggx").settings
    assert setting_widget(ggx["view"]) == ("combo", "view", [(0, "analytic"), (1, "learned"),
                                                             (2, "side by side"), (3, "diffuse baseline")])
    assert setting_widget(ggx["model"]) == ("fixed", "model", [(1, "GGX")])
    assert setting_widget(ggx["cols"])[0] == "fixed"
    assert setting_widget(ggx["lights"]) == ("slider", "point lights", [])
    assert setting_widget(ggx["exposure"]) == ("slider", "exposure", [])
    assert setting_widget(ggx["lut_filter"]) == ("combo", "LUT filtering", [("exact", "exact"), ("fast", "fast")])
    sampler = setting_widget(load_scene(ROOT / "trained" / "di_footprint").settings["mode"])
    assert sampler[:2] == ("combo", "sampler") and sampler[2][1] == (1, "trilinear")


def test_side_panel_fits_its_longest_label(app):
    import glfw
    from inshade.viewer.app import WIDGET_WIDTH

    try:
        assert app.open(ROOT / "trained" / "di_brdf_ggx"), app.messages[-1:]
        glfw.set_window_size(app.window, 1280, 800)
        app.step(4)
        from imgui_bundle import imgui
        assert app.label_width >= imgui.calc_text_size("LUT filtering").x
        assert app.panel_width >= app.label_width + WIDGET_WIDTH
        assert app.active_labels()                       # "analytic | learned" over the viewport
        with_labels = _scene_pixels(app, app.read_window())
        assert app.set_setting("labels", False) == "uniform"
        without = _scene_pixels(app, app.read_window())
        assert np.abs(with_labels - without).max() > 100
    finally:
        glfw.set_window_size(app.window, *SIZE)
        assert app.open(ASSET)
        app.step(3)


@pytest.mark.parametrize("scene", [
    pytest.param(p.name, marks=pytest.mark.skipif(
        p.name not in ONE_PER_TECHNIQUE and not os.environ.get("INSHADE_SLOW"),
        reason="one asset per technique opens in the window here (every one renders headless in "
               "test_shipped_renders); set INSHADE_SLOW=1"))
    for p in list_scenes(ROOT / "trained")])
def test_every_shipped_scene_opens_and_draws(app, scene):
    """The promise: every asset in trained/ opens in the window and shows a picture."""
    try:
        assert app.open(ROOT / "trained" / scene), app.messages[-1:]
        app.step(3)
        assert app.renderer.error is None, app.renderer.error
        pixels = _scene_pixels(app, app.read_window())
        assert pixels.std() > 5, f"{scene}: the scene region is flat"
    finally:
        assert app.open(ASSET)
        app.step(3)


def test_stochastic_scene_accumulates_while_still_and_restarts_on_change(app, tmp_path):
    """An accumulating program (tests/plugins/toy_noise, see tests/runtime/test_accumulation.py) adds one
    sample per frame up to the app's cap; a camera drag or a setting change restarts the mean."""
    from test_accumulation import _toy, expected_mean, mean_tol

    from inshade.runtime.render import read_rgba_raw

    asset = _toy().write(tmp_path / "noise", size=(8, 6))
    cap = app.max_spp
    app.max_spp = 4
    try:
        assert app.open(asset), app.messages[-1:]
        app.step(1)   # the "compiling..." frame draws nothing
        assert app.renderer.samples == 0
        for n in (1, 2, 3, 4, 4, 4):
            app.step(1)
            assert app.renderer.samples == n
        _, _, w, h = app.scene_rect()
        np.testing.assert_allclose(read_rgba_raw(app.renderer._targets["network"], 0),
                                   expected_mean(app.camera, w, h, 4)[0], atol=mean_tol(4), rtol=0)
        app.drag(3, 0)
        app.step(1)
        assert app.renderer.samples == 1
        app.step(1)
        assert app.renderer.samples == 2
        assert app.set_setting("gain", 0.5) == "uniform"
        app.step(1)
        assert app.renderer.samples == 1
    finally:
        app.max_spp = cap
        assert app.open(ASSET)
        app.step(3)


def test_view_without_display_exits_2():
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = subprocess.run([sys.executable, "-m", "inshade.cli", "view", str(ASSET)], env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.startswith("inshade: error:") and "xvfb-run" in proc.stderr
    assert proc.stderr.count("\n") == 1


def test_uvfree_material_views_channels_and_overlay_in_the_window(app):
    """A UV-free material asset in the window: decoded | reference split, the error view, a channel as
    a debug view and the triangle / level overlay are settings the panel drives; each changes the picture."""
    try:
        assert app.open(ROOT / "trained" / "uvfree_material_stump_low_balanced"), app.messages[-1:]
        app.step(3)
        # long setting labels: either a usable widget beside each, or the label above a full-width widget
        from inshade.viewer.ui import WIDGET_MIN
        assert app.labels_on_top or app.panel_width - app.label_width >= WIDGET_MIN
        pictures = {}
        for name, value in [("view", "split"), ("view", "error"), ("view", "decoded"), ("channel", "normal"),
                            ("wireframe", "triangles"), ("wireframe", "level")]:
            assert app.set_setting(name, value) == "uniform", app.messages[-1:]
            app.step(1)
            pictures[f"{name}={value}"] = _scene_pixels(app, app.read_window())
        keys = list(pictures)
        for a, b in zip(keys, keys[1:]):
            assert np.abs(pictures[a] - pictures[b]).max() > 40, (a, b)
    finally:
        assert app.open(ASSET)
        app.step(3)
    _reset(app)


@pytest.mark.parametrize("as_", ["image", "sdf", "field"])
def test_exported_networks_open_in_the_window(app, tmp_path, as_):
    """A user's own network, exported with as_=..., opens and draws in the window like a shipped asset.
    (Exported in another process, as a user does before `inshade view`: the export's check makes its
    own headless context current, which this window's context must not share a process with.)"""
    import sys

    name = {"image": "siren", "sdf": "sdf", "field": "nerf"}[as_]
    code = (f"import sys; sys.path.insert(0, {str(Path(__file__).parents[1])!r}); import inshade; from zoo import zoo; "
            f"m, x = zoo()[{name!r}]; inshade.export(m, x, {str(tmp_path / as_)!r}, as_={as_!r}, quiet=True)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    try:
        assert app.open(tmp_path / as_), app.messages[-1:]
        app.step(3)
        expected = _encode(app.renderer.read())
        pixels = _scene_pixels(app, app.read_window())
        assert np.abs(pixels - expected).max() <= 1 and pixels.std() > 5
    finally:
        assert app.open(ASSET)
        app.step(3)
    _reset(app)


def test_a_costly_scene_is_drawn_smaller_on_a_software_renderer(app, tmp_path, monkeypatch):
    """Past the frame budget a software renderer draws the scene pass smaller (never below the
    scene's own size) and the window shows it enlarged, texel for block; screenshots save what was drawn."""
    import sys

    from inshade.viewer import app as app_module

    code = (f"import sys; sys.path.insert(0, {str(Path(__file__).parents[1])!r}); import inshade; from zoo import zoo; "
            f"m, x = zoo()['sdf']; inshade.export(m, x, {str(tmp_path / 'sdf')!r}, as_='sdf', quiet=True)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    try:
        assert app.open(tmp_path / "sdf"), app.messages[-1:]
        _, _, w, h = app.scene_rect()
        assert app.draw_size(w, h) == (w, h)             # a small network: the viewport's own size
        assert app.renderer.gl["software"] and app.renderer.pixel_flops > 0
        monkeypatch.setattr(app_module, "SOFTWARE_FRAME_FLOPS", app.renderer.pixel_flops * w * h / 2)
        app.scene.size = (w // 4, h // 4)
        assert app.draw_size(w, h) == (round(w / 2 ** 0.5), round(h / 2 ** 0.5))   # what the budget allows
        monkeypatch.setattr(app_module, "SOFTWARE_FRAME_FLOPS", 1.0)
        assert app.draw_size(w, h) == (w // 4, h // 4)   # never below the scene's own size
        app.step(3)
        drawn = _encode(app.renderer.read())
        assert drawn.shape[:2] == (h // 4, w // 4) and drawn.std() > 5
        pixels = _scene_pixels(app, app.read_window())
        enlarged = np.repeat(np.repeat(drawn, 4, axis=0), 4, axis=1)
        assert np.abs(pixels - enlarged).max() <= 1
        shot = app.screenshot(tmp_path / "shot.png")
        render = json.loads(Path(shot["sidecar"]).read_text())["render"]
        assert (render["width"], render["height"]) == (w // 4, h // 4)
    finally:
        monkeypatch.undo()
        assert app.open(ASSET)
        app.step(3)
    _reset(app)


def test_window_after_the_osmesa_backend_is_one_clear_error():
    """A process that used the osmesa backend cannot open the window (PyOpenGL's platform is fixed):
    ViewerApp says so before touching GL."""
    code = ("import os; os.environ['INSHADE_GL_BACKEND'] = 'osmesa'\n"
            "from inshade.runtime.context import shared_context; shared_context()\n"
            "from inshade.viewer.app import NoDisplayError, ViewerApp\n"
            "try:\n    ViewerApp(visible=False)\nexcept NoDisplayError as e:\n    print('refused:', e)\n")
    env = {k: v for k, v in os.environ.items() if k not in ("INSHADE_GL_BACKEND", "PYOPENGL_PLATFORM")}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "refused: the window draws through its own GL context" in r.stdout


def test_a_slow_program_compiles_behind_a_quick_one(app, tmp_path, monkeypatch):
    """A program whose first draw would take long on a software driver: the window draws with its weights
    in a texture while another process compiles the program as set (Mesa's shader cache carries it over),
    then switches to it; both pictures the same within a step of 8-bit. The user's own storage choice
    ends the wait."""
    import time as clock

    from inshade.runtime import quick_program
    from inshade.viewer import warm_up

    monkeypatch.setattr(warm_up, "WARM_UP_MIN_S", 0.0)   # neural_image compiles in a second: call it slow
    monkeypatch.setattr(quick_program, "QUICK_FIRST_DRAW_S", 0.0)   # and its texture variant quicker
    monkeypatch.setenv("MESA_SHADER_CACHE_DIR", str(tmp_path / "mesa"))
    monkeypatch.setenv("INSHADE_CACHE_DIR", str(tmp_path / "history"))
    monkeypatch.setattr(app, "overrides", {"storage": "inline"})
    try:
        assert app.open(ASSET)
        assert app.warm_up is not None and app.renderer.values["storage"] == "texture"
        assert "while storage inline compiles behind" in app.flash_shown
        assert app.warm_up.process is None   # behind only once the quick frame is on screen
        app.step(3)
        assert app.warm_up.process is not None
        quick = _encode(app.renderer.read())   # the scene pass's picture (the viewport also shows the message)
        deadline = clock.monotonic() + 300
        while not app.warm_up.done():
            assert clock.monotonic() < deadline, "the program as set did not compile behind within 300 s"
            clock.sleep(0.1)
        app.step(2)
        assert app.warm_up is None and app.renderer.values["storage"] == "inline", app.messages[-1:]
        assert app.flash_shown.startswith("storage inline ready (compiled behind in")
        full = _encode(app.renderer.read())
        assert np.abs(full - quick).max() <= 1 and full.std() > 5
        assert app.open(ASSET) and app.warm_up is not None
        assert app.set_setting("storage", "ubo") != "failed"
        assert app.warm_up is None and app.renderer.values["storage"] == "ubo"
    finally:
        monkeypatch.undo()
        assert app.open(ASSET)
        app.step(3)
    _reset(app)
