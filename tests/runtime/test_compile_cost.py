"""What a program's first draw will cost on a software driver, said before it starts: the inlined
FLOPs times this driver's seconds per FLOP (the default, or the median of this machine's recorded cold
first draws), a program's own recorded cold draw first; nothing on a GPU driver; `inshade codegen`
says it and warns past a few seconds."""
from __future__ import annotations

import pytest

from inshade.runtime import compile_cost, draw_history

LLVMPIPE = {"software": True, "renderer": "llvmpipe (test)"}


@pytest.fixture
def history(tmp_path, monkeypatch):
    monkeypatch.setenv("INSHADE_CACHE_DIR", str(tmp_path))
    return tmp_path


@pytest.fixture(scope="module")
def generated():
    from inshade.bundle import load
    from inshade.codegen import generate
    from inshade.scene.description import load_scene, resolve_asset

    bundle = load(load_scene(resolve_asset("prt_mechanical")).networks[0].bundle)
    return {s: generate(bundle, storage=s, limits=LLVMPIPE) for s in ("inline", "texture")}


def test_the_estimate_counts_the_inlined_flops(history, generated):
    inline, texture = (compile_cost.inline_flops([generated[s]]) for s in ("inline", "texture"))
    assert inline == sum(r.flops for r in generated["inline"].plan.rows if r.type == "dense") > 30000
    assert texture == 0
    assert compile_cost.first_draw_estimate(LLVMPIPE, "", [generated["inline"]]) == pytest.approx(
        inline * compile_cost.DEFAULT_S_PER_INLINE_FLOP)
    assert compile_cost.first_draw_estimate({"software": False, "renderer": "GPU"}, "", [generated["inline"]]) is None


def test_this_machines_cold_first_draws_calibrate_it(history, generated):
    r = LLVMPIPE["renderer"]
    draw_history.record(r, "a", first_draw_s=2.0, shader_cache=False, inline_flops=10000, compiled=True)
    draw_history.record(r, "b", first_draw_s=30.0, shader_cache=True, inline_flops=10000, compiled=True)   # a cache
    draw_history.record(r, "c", first_draw_s=0.1, shader_cache=False, inline_flops=100, compiled=True)   # too small
    # drawn by a process that had drawn the program before: no compile, no measure of the JIT
    draw_history.record(r, "f", first_draw_s=0.02, shader_cache=False, inline_flops=10000)
    assert compile_cost.seconds_per_flop(r) == compile_cost.DEFAULT_S_PER_INLINE_FLOP    # one record is not enough
    draw_history.record(r, "d", first_draw_s=5.0, shader_cache=False, inline_flops=10000, compiled=True)
    draw_history.record(r, "e", first_draw_s=3.0, shader_cache=False, inline_flops=10000, compiled=True)
    assert compile_cost.seconds_per_flop(r) == pytest.approx(3e-4)   # the median of 2, 3, 5 s per 10k
    assert compile_cost.seconds_per_flop("another renderer") == compile_cost.DEFAULT_S_PER_INLINE_FLOP
    # a program drawn cold before: what it took
    draw_history.record(r, "key", first_draw_s=12.5, shader_cache=False, inline_flops=1, compiled=True)
    assert compile_cost.first_draw_estimate(LLVMPIPE, "key", [generated["inline"]]) == 12.5
    draw_history.record(r, "old", first_draw_s=0.03, shader_cache=False, inline_flops=1)   # not known to compile
    assert compile_cost.first_draw_estimate(LLVMPIPE, "old", [generated["inline"]]) != 0.03


def test_codegen_says_it_and_warns(gl, history, tmp_path, capsys, caplog):
    from inshade.cli import main
    from inshade.runtime.context import machine_limits

    assert main(["codegen", "prt_mechanical", "-o", str(tmp_path / "m.glsl")]) == 0
    out = capsys.readouterr().out
    if not machine_limits()["software"]:   # a GPU driver compiles at link: nothing to say
        assert "compile: ~" not in out
        return
    assert "compile: ~" in out and "at the first draw on llvmpipe" in out and "inlined FLOPs)" in out
    assert "--storage texture compiles in seconds" in caplog.text
    caplog.clear()
    assert main(["codegen", "prt_mechanical", "--storage", "texture", "-o", str(tmp_path / "t.glsl")]) == 0
    assert "compile: ~" not in capsys.readouterr().out and "--storage texture compiles" not in caplog.text


@pytest.mark.parametrize("decoder", [16, 64])
def test_only_the_networks_the_program_calls_count(gl, decoder):
    """The neural appearance program carries three decoders and compiles the one its define picks."""
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene, resolve_asset

    r = SceneRenderer(load_scene(resolve_asset("neural_appearance_ceramic")), settings={"decoder": decoder})
    try:
        by_prefix = {g.prefix: compile_cost.inline_flops([g]) for g in r.generated}
        others = {f"dec{d}" for d in (16, 32, 64) if d != decoder}
        assert all(by_prefix[p] > 0 for p in others)
        want = sum(f for p, f in by_prefix.items() if p not in others)
        assert compile_cost.inline_flops(r.generated, r.assembled()["fragment"]) == want > 0
    finally:
        r.release()
