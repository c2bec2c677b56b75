"""The page on WebGPU: export-web --api webgpu|auto translates every pass the WebGL2 page runs to WGSL
(web/webgpu.py) and the page draws it with WebGPUBackend. Per asset what test_web checks of the WebGL2
page (one asset per technique; every shipped asset with INSHADE_SLOW=1), plus what only the WebGPU path
has: the API choice, uniform layouts as WGSL lays them out, a lost device, a toolchain that is missing."""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from inshade.cli import main
from inshade.scene.description import load_scene
from inshade.web.browser import Browser, psnr8, serve, srgb8
from inshade.web.export import export_web
from inshade.web.webgpu import translate

from web_pages import ASSETS, MIN_PSNR_DB, check_page, render_record

NEURAL_IMAGE = Path(__file__).resolve().parents[2] / "trained" / "neural_image"


@pytest.fixture(scope="module")
def browser():
    with Browser() as b:
        yield b


@pytest.fixture(scope="module")
def record():
    return render_record()


@pytest.mark.parametrize("asset", ASSETS)
def test_page_on_webgpu_draws_what_inshade_render_draws(gl, browser, record, asset, tmp_path):
    check_page(browser, record, asset, "webgpu", tmp_path)


VERTEX = """#version 300 es
void main() { gl_Position = vec4(vec2(gl_VertexID & 1, gl_VertexID >> 1) * 4.0 - 1.0, 0.0, 1.0); }
"""
FRAGMENT = """#version 300 es
precision highp float;
uniform int u_kinds[4];
uniform float u_scale;
uniform mat3 u_basis;
uniform vec2 u_weights[2];
uniform sampler2D u_table;
layout(location = 0) out vec4 frag_color;
void main() {
    frag_color = vec4(u_basis * vec3(float(u_kinds[2]) * u_scale), u_weights[1].y) + texture(u_table, vec2(0.5));
}
"""


def test_uniforms_are_laid_out_as_the_wgsl_lays_them_out():
    """std140 puts an int[4] 16 bytes apart; the WGSL naga writes packs it 4 apart, and the page fills
    the buffer at the WGSL's offsets (which need the browser's uniform_buffer_standard_layout)."""
    wgsl, interfaces = translate({"p": {"vertex": VERTEX, "fragment": FRAGMENT}})
    frag = interfaces["p"]["fragment"]
    lay = frag["uniforms"]
    assert lay["u_kinds"]["offset"] == 0 and lay["u_kinds"]["stride"] == 4 and lay["u_kinds"]["count"] == 4
    assert lay["u_scale"]["offset"] == 16
    assert lay["u_basis"]["offset"] == 32 and lay["u_basis"]["matrix_stride"] == 16 and lay["u_basis"]["cols"] == 3
    assert lay["u_weights"]["offset"] == 80 and lay["u_weights"]["stride"] == 8
    block = next(r for r in frag["resources"] if r["kind"] == "uniforms")
    assert block["standard_layout"] and block["size"] == 96
    # the texture split into a texture and its sampler, every binding of the group its own
    kinds = {r["name"]: r["kind"] for r in frag["resources"]}
    assert kinds["u_table_image"] == "texture" and kinds["u_table_sampler"] == "sampler"
    assert len({r["binding"] for r in frag["resources"]}) == len(frag["resources"])
    assert "diagnostic(off, derivative_uniformity);" in wgsl["p"]["fragment"]


def test_a_missing_toolchain_is_one_error_line(gl, tmp_path, capsys, monkeypatch):
    import inshade.web.webgpu as webgpu

    monkeypatch.setattr(webgpu, "TOOLCHAIN", tmp_path / "nowhere")
    assert main(["-q", "export-web", "neural_image", "-o", str(tmp_path / "page"), "--api", "webgpu"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("inshade: error: ") and "npm ci --prefix" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "page").exists()


def test_auto_draws_with_webgpu_where_the_browser_has_it_and_each_api_on_request(gl, browser, tmp_path):
    export_web(NEURAL_IMAGE, tmp_path / "auto", width=32, height=32, api="auto")
    export_web(NEURAL_IMAGE, tmp_path / "gpu", width=32, height=32, api="webgpu")
    with serve(tmp_path) as url:
        pictures = {}
        for query, api in (("", "webgpu"), ("?api=webgpu", "webgpu"), ("?api=webgl2", "webgl2")):
            state = browser.open(url + "auto/index.html" + query)
            assert state["ready"] and browser.driver.execute_script("return window.inshade.api;") == api, state
            pictures[query] = browser.canvas()
        assert np.array_equal(pictures["?api=webgpu"], pictures["?api=webgl2"])
        # a page written for WebGPU only does not pretend to have WebGL2 programs
        state = browser.open(url + "gpu/index.html?api=webgl2")
        assert "without webgl2 programs" in state["error"], state
        manifest = json.loads((tmp_path / "gpu" / "manifest.json").read_text())
        assert manifest["apis"] == ["webgpu"] and (tmp_path / "gpu" / "programs" / "scene.frag.wgsl").is_file()


def test_a_lost_device_is_an_error_not_a_blank_page(gl, browser, tmp_path):
    export_web(NEURAL_IMAGE, tmp_path / "page", width=32, height=32, api="webgpu")
    with serve(tmp_path / "page") as url:
        state = browser.open(url + "index.html")
        assert state["ready"] and state["error"] is None, state
        browser.driver.execute_script("window.inshade.viewer.gpu.device.destroy();")
        deadline = time.perf_counter() + 10
        while browser.driver.execute_script("return window.inshade.error") is None and time.perf_counter() < deadline:
            time.sleep(0.05)
        assert "WebGPU device was lost" in str(browser.driver.execute_script("return window.inshade.error"))


def test_your_own_network_on_webgpu(gl, browser, tmp_path):
    """A torch module brought in with inshade.export, its page on WebGPU: inshade render's pixels."""
    import inshade
    from inshade.runtime.headless import render_scene

    torch.manual_seed(0)
    module = torch.nn.Sequential(torch.nn.Linear(2, 32), torch.nn.SiLU(), torch.nn.Linear(32, 3), torch.nn.Sigmoid())
    inshade.export(module, torch.rand(64, 2), tmp_path / "mine", as_="image", quiet=True)
    export_web(tmp_path / "mine", tmp_path / "page", width=48, height=48, api="webgpu")
    with serve(tmp_path / "page") as url:
        state = browser.open(url + "index.html")
        assert state["error"] is None and state["ready"], state
        page = browser.canvas()
    image, _ = render_scene(load_scene(tmp_path / "mine"), width=48, height=48)
    assert psnr8(page, srgb8(image)) >= MIN_PSNR_DB


def test_an_unknown_api_is_refused(tmp_path):
    with pytest.raises(ValueError, match="api"):
        export_web(NEURAL_IMAGE, tmp_path / "page", api="vulkan")
