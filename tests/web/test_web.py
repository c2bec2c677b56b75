"""inshade export-web: the exported page in headless Chromium (SwiftShader's WebGL2 and WebGPU without a
GPU) against ``inshade render`` (8-bit sRGB, >= 40 dB: different rasterisers), on each API, and its
network evaluation pages against torch (the 1e-5 rule, tests/parity.py); the folder, the CLI and the
WebGL2 limits.

One asset per technique runs here; INSHADE_SLOW=1 runs every shipped asset. The render each page is
compared with is the shipped-render record (tests/shipped_renders.py: ``inshade render`` at a quarter
of the scene's size, checked bit for bit by test_shipped_renders) when this machine's renderer made
it, else a fresh ``render_scene``.
"""
from __future__ import annotations

import json
import os
import time

import numpy as np
import pytest
import torch

from inshade.bundle import load
from inshade.cli import main
from inshade.scene.description import NetworkSdfRef, load_scene, resolve_asset
from inshade.web.browser import Browser, psnr8, serve, srgb8
from inshade.web.export import WebLimitError, export_web

from parity import TOL, assert_parity, glsl_eval, scaled_error, torch_reference
from shipped_renders import size
from web_pages import ASSETS, MIN_PSNR_DB, TRAINED, check_page, errors, exported, render_record

# The evaluation page is held to the parity rule, or where the desktop driver itself misses it on the
# same batch, to within this factor of the desktop's error (the browser no less exact than the desktop).
DESKTOP_MARGIN = 1.25
# Frequency encodings take sin / cos of arguments up to 2^k pi, and SwiftShader's sin / cos are off by up
# to 2e-4 even within [-pi, pi] (measured): the shipped PRT and prefiltering networks reach 1.2e-4 ..
# 9.7e-3 (prt_mechanical; 2.9e-3 under Chromium 156.0.8078.73, 9.7e-3 under .129) in Chromium, on
# WebGL2 and WebGPU alike, where llvmpipe holds ~1e-5 on the same batch. A sin / cos of the shader's own
# (Cody-Waite reduction + Cephes polynomials) brought prt_mechanical to 7.6e-6 but made the grove's
# march compile for minutes in SwiftShader, so those networks are held to this bound instead.
BROWSER_SIN_TOL = 1e-2
@pytest.fixture(scope="module")
def browser():
    with Browser() as b:
        yield b


@pytest.fixture(scope="module")
def record():
    return render_record()


APIS = ("webgl2", "webgpu")


@pytest.mark.parametrize("asset", ASSETS)
def test_page_draws_what_inshade_render_draws(gl, browser, record, asset, tmp_path):
    check_page(browser, record, asset, "webgl2", tmp_path)   # on WebGPU: test_webgpu_page.py


@pytest.mark.parametrize("api", APIS)
def test_the_first_frame_is_a_quarter_of_the_size_shown_enlarged(gl, browser, api, tmp_path):
    """The page's first frame: every pass at 1/4 of the size, each of its pixels shown as a 4 x 4 block, the
    picture inshade render draws at that size; the full frame after it as if it had been the first."""
    asset = "sdf_creature"
    folder, (w, h) = exported(asset, tmp_path, api)
    with serve(folder) as url:
        state = browser.open(url + "index.html")
        assert state["ready"], state
        full = browser.canvas()
        browser.driver.execute_script("return window.inshade.viewer.render({preview: 4});")
        preview = browser.canvas()
        browser.driver.execute_script("return window.inshade.viewer.render();")
        again = browser.canvas()
    assert np.array_equal(again, full)
    assert w % 4 == 0 and h % 4 == 0, (w, h)
    small = preview[3::4, ::4]   # rows from the top: the block's bottom-left pixel is its source texel
    assert np.array_equal(np.repeat(np.repeat(small, 4, 0), 4, 1), preview)
    from inshade.runtime.headless import render_scene

    image, _ = render_scene(load_scene(resolve_asset(asset)), width=w // 4, height=h // 4)
    db = psnr8(small, srgb8(image))
    assert db >= MIN_PSNR_DB, f"the preview is {db:.2f} dB from inshade render at a quarter of the size"


@pytest.mark.parametrize("api", APIS)
@pytest.mark.parametrize("asset,mode", [("di_texture_astronaut", "reference"), ("di_texture_astronaut", "split"),
                                        ("hash_grid_radiance_field", "reference"), ("neural_image", "error")])
def test_reference_views_match_inshade_render(gl, browser, asset, mode, api, tmp_path):
    """The display modes that show the reference (an sRGB PNG decoded by the browser's texture unit,
    or linear half floats), against ``inshade render --mode`` of the same view."""
    from inshade.runtime.headless import render_scene
    from inshade.scene.display import parse_mode

    folder, (w, h) = exported(asset, tmp_path, api)
    with serve(folder) as url:
        state = browser.open(url + "index.html")
        assert state["error"] is None, state
        browser.driver.execute_script(f"const v = window.inshade.viewer; v.mode = {int(parse_mode(mode))}; return v.render();")
        page = browser.canvas()
    image, _ = render_scene(load_scene(resolve_asset(asset)), width=w, height=h, mode=mode)
    db = psnr8(page, srgb8(image))
    assert db >= MIN_PSNR_DB, f"{asset} {mode} ({api}): {db:.2f} dB"


def _network_of(asset: str, name: str):
    scene = load_scene(resolve_asset(asset))
    bundles = [load(n.bundle) for n in scene.networks]
    if isinstance(scene.sdf, NetworkSdfRef):
        bundles.append(load(scene.sdf.bundle))
    return next(b for b in bundles if b.name == name)


# the evaluation pages: WebGL2 (passes/evaluate.frag) and WebGPU (the WGSL compute harness)
EVALUATION_PAGES = {"webgl2": ("evaluate.html", "evaluate"), "webgpu": ("evaluate_webgpu.html", "evaluate_webgpu")}


@pytest.mark.parametrize("api", EVALUATION_PAGES)
@pytest.mark.parametrize("asset", ASSETS)
def test_evaluation_page_matches_torch(gl, browser, asset, api, tmp_path):
    page, key = EVALUATION_PAGES[api]
    folder, _ = exported(asset, tmp_path)
    manifest = json.loads((folder / "manifest.json").read_text())
    e = manifest[key]
    if e is None:   # an analytic scene: there is no network to run
        assert load_scene(resolve_asset(asset)).networks == [] and not isinstance(
            load_scene(resolve_asset(asset)).sdf, NetworkSdfRef)
        return
    with serve(folder) as url:
        state = browser.open(url + page)
        assert state["error"] is None and not errors(state["console"]), f"{asset}: {state}"
        out = browser.evaluation()
    x = np.fromfile(folder / "data.bin", np.float32, e["count"] * e["in_dim"], offset=e["inputs"][0])
    bundle = _network_of(asset, e["bundle"])
    x = x.reshape(e["count"], e["in_dim"])
    ref = torch_reference(bundle, x)
    tol, what = TOL, f"{asset}: {e['bundle']} in Chromium ({api})"
    if any(n.type == "frequency" for n in bundle.nodes):
        tol = BROWSER_SIN_TOL
    elif float(np.nanmax(scaled_error(out, ref))) > TOL:
        # a network this driver holds to the rule only as closely as the desktop one does: the deep
        # tanh PRT networks reach 1.04e-5 .. 1.19e-5 on llvmpipe at the envelope's input ranges
        desktop = float(np.nanmax(scaled_error(_desktop(gl, bundle, x), ref)))
        tol, what = max(TOL, DESKTOP_MARGIN * desktop), f"{what} (llvmpipe on the same batch: {desktop:.3g})"
    assert_parity(out, ref, tol, what=what)


def _desktop(gl, bundle, x) -> np.ndarray:
    """The same ES 3.00 network as the page runs, planned the same way, on this machine's driver."""
    from inshade.web.limits import WEBGL2

    return glsl_eval(gl, bundle, x, version="es300", limits=WEBGL2)


def test_your_own_network_exports_through_the_same_path(gl, browser, tmp_path):
    """A torch module brought in with inshade.export becomes a page, and the page's numbers are torch's."""
    import inshade

    torch.manual_seed(0)
    module = torch.nn.Sequential(torch.nn.Linear(2, 32), torch.nn.SiLU(), torch.nn.Linear(32, 3), torch.nn.Sigmoid())
    inshade.export(module, torch.rand(64, 2), tmp_path / "mine", as_="image", quiet=True)
    folder = tmp_path / "page"
    export_web(tmp_path / "mine", folder, width=48, height=48)
    with serve(folder) as url:
        state = browser.open(url + "index.html")
        assert state["error"] is None and not errors(state["console"]), state
        page = browser.canvas()
        state = browser.open(url + "evaluate.html")
        assert state["error"] is None, state
        out = browser.evaluation()
    from inshade.runtime.headless import render_scene

    image, _ = render_scene(load_scene(tmp_path / "mine"), width=48, height=48)
    assert psnr8(page, srgb8(image)) >= MIN_PSNR_DB
    e = json.loads((folder / "manifest.json").read_text())["evaluate"]
    x = np.fromfile(folder / "data.bin", np.float32, e["count"] * e["in_dim"], offset=e["inputs"][0])
    with torch.no_grad():
        ref = module(torch.from_numpy(x.reshape(e["count"], e["in_dim"]))).numpy()
    assert_parity(out, ref, what="a torch module's page")


def test_a_lost_context_is_an_error_not_a_blank_page(browser, tmp_path):
    """A browser that drops the page's WebGL context (a GPU process reset) leaves draws and reads
    blank without a GL error; the viewer and the evaluation page say so instead."""
    export_web(TRAINED / "neural_image", tmp_path / "page", width=32, height=32)
    lose = "document.getElementById('canvas').getContext('webgl2').getExtension('WEBGL_lose_context').loseContext();"
    with serve(tmp_path / "page") as url:
        for page in ("index.html", "evaluate.html"):
            state = browser.open(url + page)
            assert state["error"] is None and state["ready"], state
            browser.driver.execute_script(lose)
            deadline = time.perf_counter() + 10
            while browser.driver.execute_script("return window.inshade.error") is None and time.perf_counter() < deadline:
                time.sleep(0.05)
            assert "WebGL context was lost" in str(browser.driver.execute_script("return window.inshade.error")), page


def test_camera_uniforms_match_the_runtime(browser, tmp_path):
    """The page's cameras give the uniforms scene/camera.py gives, at random poses."""
    from inshade.scene.camera import camera_from_dict

    export_web(TRAINED / "neural_image", tmp_path / "page", width=32, height=32)
    rng = np.random.default_rng(1)
    cameras = [{"type": "orbit", "target": rng.normal(size=3).tolist(), "distance": float(rng.uniform(0.5, 9)),
                "yaw": float(rng.uniform(0, 360)), "pitch": float(rng.uniform(-80, 80)), "fov_y": float(rng.uniform(20, 90)),
                "near": 0.05, "far": 100.0} for _ in range(8)]
    cameras += [{"type": "fly", "position": rng.normal(size=3).tolist(), "yaw": float(rng.uniform(0, 360)),
                 "pitch": float(rng.uniform(-80, 80)), "fov_y": 45.0, "near": 0.1, "far": 50.0} for _ in range(4)]
    cameras += [{"type": "plane2d", "center": rng.random(2).tolist(), "zoom": float(rng.uniform(0.2, 20)),
                 "aspect": float(rng.uniform(0.5, 2))} for _ in range(4)]
    with serve(tmp_path / "page") as url:
        browser.open(url + "index.html")
        for record in cameras:
            py = camera_from_dict(record).uniforms(200, 120)
            js = browser.driver.execute_script(
                "const c = new window.inshade.viewer.camera.constructor(arguments[0]);"
                "return JSON.parse(JSON.stringify(c.uniforms(200, 120)));", record)
            assert set(js) == set(py), record
            if record["type"] == "fly":   # a step of the page's keys, as the viewer's
                cam = camera_from_dict(record)
                cam.move(1.0, -1.0, 1.0, 0.25)
                py = cam.uniforms(200, 120)
                js = browser.driver.execute_script(
                    "const c = new window.inshade.viewer.camera.constructor(arguments[0]); c.move(1, -1, 1, 0.25);"
                    "return JSON.parse(JSON.stringify(c.uniforms(200, 120)));", record)
            for name, value in py.items():
                want = np.frombuffer(value, np.float32) if isinstance(value, bytes) else np.asarray(value, np.float32)
                np.testing.assert_allclose(np.asarray(js[name], np.float32), want, rtol=1e-5, atol=1e-5,
                                           err_msg=f"{record['type']}: {name}")


@pytest.mark.parametrize("asset", ["neural_image", "di_pbr_set_bricks", "sdf_creature"])
def test_es300_programs_draw_what_desktop_programs_draw(gl, asset):
    """The page's GLSL ES 3.00 programs, planned against WebGL2's limits, drawn by this driver:
    the same pixels as the desktop programs (the browser then only adds its own rasteriser)."""
    from inshade.runtime.headless import render_scene
    from inshade.runtime.renderer import SceneRenderer
    from inshade.web.limits import WEBGL2

    scene = load_scene(resolve_asset(asset))
    w, h = size(scene.size)
    desktop, _ = render_scene(scene, width=w, height=h)
    renderer = SceneRenderer(scene, gl, limits=WEBGL2, target="es300")
    try:
        camera = scene.make_camera()
        renderer.render(camera, w, h)
        es = renderer.read()
    finally:
        renderer.release()
    np.testing.assert_array_equal(es, desktop)


def test_export_refuses_a_folder_that_holds_files_and_force_replaces_it(gl, tmp_path, capsys):
    out = tmp_path / "page"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    assert main(["-q", "export-web", "neural_image", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("inshade: error: ") and "--force" in err and len(err.splitlines()) == 1
    assert (out / "mine.txt").read_text() == "keep"
    assert main(["-q", "export-web", "neural_image", "-o", str(out), "--force", "--width", "32", "--height", "32"]) == 0
    assert not (out / "mine.txt").exists()
    files = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
    assert {"index.html", "evaluate.html", "inshade.js", "manifest.json", "data.bin",
            "programs/scene.frag.glsl", "programs/display.frag.glsl"} <= files
    mode = 0o666 & ~_umask()
    assert all((p.stat().st_mode & 0o777) == mode for p in out.rglob("*") if p.is_file())
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["format"] == "inshade-web 1" and manifest["size"] == [32, 32]
    assert all(src.startswith("#version 300 es") for src in
               [(out / "programs" / f).read_text() for f in ("scene.frag.glsl", "scene.vert.glsl")])


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def test_settings_are_live_or_say_why_they_are_fixed(gl, tmp_path):
    page = export_web(TRAINED / "prt_creature", tmp_path / "page", width=32, height=32)
    settings = {s["name"]: s for s in page.manifest["settings"]}
    assert settings["exposure"]["uniform"] == "u_exposure" and "fixed" not in settings["exposure"]
    assert settings["shading"]["indices"] == [0, 1]
    assert "--set sky=VALUE" in settings["sky"]["fixed"]             # the environment is data
    assert "--set storage=VALUE" in settings["storage"]["fixed"]     # compiled in


def test_an_asset_past_webgl2s_limits_is_refused_naming_the_limit(gl, tmp_path, monkeypatch):
    from inshade.web import export

    monkeypatch.setitem(export.WEBGL2, "GL_MAX_TEXTURE_SIZE", 16)
    monkeypatch.setitem(export.WEBGL2, "GL_MAX_UNIFORM_BLOCK_SIZE", 64)
    with pytest.raises(WebLimitError, match="WebGL2: .*GL_MAX_"):
        export_web(TRAINED / "hash_grid_image", tmp_path / "page")
    assert not (tmp_path / "page").exists()


def test_a_gltf_file_exports_as_a_page_of_its_reference_shading(gl, browser, tmp_path):
    """A .glb opened as a scene (the gltf_pbr reference pass): its materials travel as the same two
    textures the runtime binds (a parameter table and a mipmapped image array)."""
    from inshade.geometry import gltf_scenes
    from inshade.runtime.headless import render_scene

    path = gltf_scenes.tiles_torus().write(tmp_path / "tiles.glb")
    folder = tmp_path / "page"
    export_web(path, folder, width=128, height=128)
    with serve(folder) as url:
        state = browser.open(url + "index.html")
        assert state["error"] is None, state
        assert not errors(state["console"]), state["console"]
        page = browser.canvas()
    image, info = render_scene(load_scene(path), width=128, height=128)
    assert info["view"]["settings"]["tonemap"] == "pbr_neutral"   # the page presents it as the PNG does
    db = psnr8(page, srgb8(image, tonemap="pbr_neutral"))
    assert db >= MIN_PSNR_DB, f"tiles.glb: the page is {db:.2f} dB from inshade render's"


@pytest.mark.parametrize("precision,storage", [("f16", "auto"), ("i8", "auto"), ("i8", "texture")])
def test_a_page_draws_a_network_stored_at_a_lower_precision(gl, browser, precision, storage, tmp_path):
    """A 64 x 4 image network exported at f16 / i8: the page plans its layers into uniform blocks, which
    hold the precision's bytes (float16 pairs, int8 codes) unpacked in the shader, or at storage texture
    an i8 network's codes in an RGBA8UI texture and its rows' biases and scales beside it, on both APIs."""
    import inshade
    from inshade.runtime.headless import render_scene

    torch.manual_seed(0)
    layers = [torch.nn.Linear(2, 64), torch.nn.SiLU()]
    for _ in range(3):
        layers += [torch.nn.Linear(64, 64), torch.nn.SiLU()]
    module = torch.nn.Sequential(*layers, torch.nn.Linear(64, 3), torch.nn.Sigmoid())
    inshade.export(module, torch.rand(64, 2), tmp_path / "net", as_="image", colour="srgb", precision=precision,
                   quiet=True)
    settings = {"labels": False, **({"storage": storage} if storage != "auto" else {})}
    image, _ = render_scene(load_scene(tmp_path / "net"), width=64, height=64, settings=settings)
    for api in APIS:
        page = export_web(tmp_path / "net", tmp_path / api, width=64, height=64, api=api,
                          settings={"storage": storage} if storage != "auto" else None)
        assert ("ubo" if storage == "auto" else storage) in {r.storage for g in page.renderer.generated
                                                              for r in g.plan.rows}
        with serve(tmp_path / api) as url:
            state = browser.open(url + "index.html")
            assert state["error"] is None and not errors(state["console"]), state
            db = psnr8(browser.canvas(), srgb8(image))
        assert db >= MIN_PSNR_DB, f"{precision} on {api}: {db:.2f} dB from inshade render"
