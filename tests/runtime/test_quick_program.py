"""A short job at storage auto on a software driver draws with the storage that ends it sooner: the
weights in a texture where the literals' compile is estimated long and the frames few; the program as
set where it compiles quickly, Mesa's cache holds it, the frames are many, the driver is a GPU's or
the user chose. Both programs draw the same pixels under the parity rule."""
from __future__ import annotations

import json

import numpy as np
import pytest

from inshade.runtime import draw_history, first_draw, quick_program
from inshade.runtime.renderer import SceneRenderer
from inshade.scene.description import load_scene, resolve_asset

SIDE = 256


@pytest.fixture
def history(tmp_path, monkeypatch):
    """An empty draw history, no program drawn in this process yet and Mesa's shader cache off: every
    first draw is a compile."""
    monkeypatch.setenv("INSHADE_CACHE_DIR", str(tmp_path / "history"))
    monkeypatch.setenv("MESA_SHADER_CACHE_DISABLE", "true")
    monkeypatch.setattr(first_draw, "_DRAWN", set())
    return tmp_path


def _renderer(asset: str, **kw) -> SceneRenderer:
    return SceneRenderer(load_scene(resolve_asset(asset)), **kw)


def _dense_storages(r) -> set:
    return {row.storage for g in r.generated for row in g.plan.rows if row.type == "dense"}


def test_one_frame_reads_the_weights_from_a_texture_where_literals_compile_for_long(gl, history):
    r = _renderer("prt_mechanical", quick=(SIDE * SIDE, 1))   # ~35k inlined FLOPs: ~10 s of llvmpipe JIT
    try:
        assert r.values["storage"] == "texture" and _dense_storages(r) == {"texture"}
        assert r.storage_choice.startswith("storage texture for this job") and "storage auto's literals" in (
            r.storage_choice)
    finally:
        r.release()


def test_the_planned_program_is_the_program_built(gl, history):
    """The choice looks programs up in the draw history by the name the built program gets."""
    r = _renderer("prt_mechanical")
    try:
        assert quick_program._planned(r, r.values)[1] == r.program_key != ""
    finally:
        r.release()


@pytest.mark.parametrize("case", ["many pixels", "chosen", "gpu", "in mesa's cache", "texture slow here",
                                  "drawn in this process"])
def test_the_program_as_set_where_it_ends_the_job_sooner(gl, history, monkeypatch, case):
    kw = {"quick": (SIDE * SIDE, 1)}
    if case == "many pixels":   # the texture's gathers over 16M pixels cost more than the compile saved
        kw["quick"] = (4096 * 4096, 1)
    elif case == "chosen":
        kw["settings"] = {"storage": "inline"}
    elif case == "gpu":
        kw["limits"] = {"software": False}
    elif case == "drawn in this process":   # the driver holds it compiled: nothing to save
        plain = _renderer("prt_mechanical")
        first_draw._DRAWN.add(plain.program_key)
        plain.release()
    else:
        plain = _renderer("prt_mechanical", settings={"storage": "auto" if case == "in mesa's cache" else "texture"})
        key, renderer_name = plain.program_key, plain.gl["renderer"]
        plain.release()
        if case == "in mesa's cache":
            monkeypatch.delenv("MESA_SHADER_CACHE_DISABLE")
            draw_history.record(renderer_name, key, first_draw_s=11.0, shader_cache=True, compiled=True)
        else:
            draw_history.record(renderer_name, key, first_draw_s=25.0, shader_cache=False, compiled=True)
    r = _renderer("prt_mechanical", **kw)
    try:
        assert r.storage_choice is None
        assert r.values["storage"] == ("inline" if case == "chosen" else "auto")
        assert _dense_storages(r) == ({"ubo"} if case == "gpu" else {"inline"})   # auto's own choices
    finally:
        r.release()


def test_render_draws_the_quick_program_with_the_pixels_of_the_program_as_set(gl, history, monkeypatch, caplog):
    """neural_image's literals compile in a second: called slow here, so that the render takes the texture."""
    from inshade.cli import main
    from inshade.scene.image_io import read_exr

    monkeypatch.setattr(quick_program, "QUICK_MIN_S", 0.0)
    monkeypatch.setattr(quick_program, "QUICK_FIRST_DRAW_S", 0.0)
    out = history
    common = ["render", "neural_image", "--width", "48", "--height", "40"]
    with caplog.at_level("INFO", logger="inshade"):
        assert main([*common, "-o", str(out / "quick.exr")]) == 0
    assert main([*common, "--storage", "inline", "-o", str(out / "inline.exr")]) == 0
    sidecar = json.loads((out / "quick.exr.json").read_text())
    assert sidecar["render"]["storage"] == "texture" and sidecar["plan"]["storage"]["texture"] == 3
    assert sidecar["storage_choice"].startswith("storage texture for this job")
    assert any("storage texture for this job" in r.getMessage() for r in caplog.records)
    quick, inline = read_exr(out / "quick.exr"), read_exr(out / "inline.exr")
    assert np.abs(quick.astype(np.float64) - inline).max() <= 1e-5   # the parity rule
    # the sidecar re-renders the very pixels it describes
    assert main(["render", "--from", str(out / "quick.exr.json"), "-o", str(out / "again.exr")]) == 0
    assert np.array_equal(read_exr(out / "again.exr"), quick)
