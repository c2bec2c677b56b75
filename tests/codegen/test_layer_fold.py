"""Runs of identical dense layers in the weight texture become one loop over the layers
(components/dense/emit_layer_loop.py): the GLSL still matches torch, the chunk holds the loop once, the plan
keeps a row per layer, and a driver's loop budget leaves a run unfolded when the loop would not fit."""
from __future__ import annotations

import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

from inshade.codegen import generate
from inshade.components.dense.emit_layer_loop import find_runs, fold_runs
from inshade.components.dense.emit_plan import loop_chunks

from parity import (MLPSpec, activation_specs, assert_parity, build_mlp, check_parity, glsl_eval, parity_settings,
                    spec_inputs, torch_reference)

TEXTURE = {"dense": {"storage": "texture"}}
LLVMPIPE = {"renderer": "llvmpipe (LLVM 15.0.6, 256 bits)"}   # a driver capping a pixel's loop iterations


def _layer_loops(chunk: str) -> list[int]:
    """The layer counts of the chunk's loops over layers."""
    return [int(n) for n in re.findall(r"for \(int l = 0; l < (\d+); \+\+l\)", chunk)]


def _folded(gen) -> set[str]:
    return {r.node for r in gen.plan.rows if r.type == "dense" and "folded into one loop over layers" in r.why}


@st.composite
def run_specs(draw):
    """An MLP with a run of 3-5 hidden layers width -> width of one activation after a first
    layer inputs -> width, maybe a tail layer of another width, any activation, maybe a hidden
    layer also an output."""
    inputs = [draw(st.integers(1, 6)) for _ in range(draw(st.integers(1, 2)))]
    width = draw(st.integers(1, 40))
    k = draw(st.integers(3, 5))
    act = draw(activation_specs())
    tail = draw(st.lists(st.integers(1, 24), max_size=1))
    widths = [width] * (k + 1) + tail
    acts = [draw(activation_specs())] + [act] * k + [draw(activation_specs()) for _ in tail]
    run_bias = draw(st.booleans())
    bias = [draw(st.booleans())] + [run_bias] * k + [draw(st.booleans()) for _ in range(len(tail) + 1)]
    out_dim = draw(st.integers(1, 8))
    tappable = [i for i, w in enumerate(widths) if w + out_dim <= 32]   # all outputs <= 8 draw buffers
    tap = draw(st.one_of(st.none(), st.sampled_from(tappable))) if tappable else None
    out_act = draw(st.one_of(st.none(), st.sampled_from([("sigmoid", {}), ("identity", {}), ("relu", {})])))
    return MLPSpec(inputs, widths, acts, out_dim, out_act, tap, bias, draw(st.integers(0, 2**31 - 1)))


@parity_settings(max_examples=6)
@given(spec=run_specs(), precision=st.sampled_from(["f32", "f16", "i8"]))
def test_folded_runs_match_torch(gl, spec, precision):
    """At every precision: an i8 run's codes and its rows' biases and scales are read from textures by
    the loop's layer index as a float run's rows are."""
    from inshade.quantize import quantized

    bundle = quantized(build_mlp(spec).export("mlp"), precision)
    gen = generate(bundle, options=TEXTURE)
    folded = _folded(gen)
    if spec.tap is None:   # else a hidden output may split the run
        assert {"l1", "l2", "l3"} <= folded, f"{spec}: the run was not folded ({sorted(folded)})"
    assert sum(_layer_loops(gen.chunk)) == len(folded)
    check_parity(gl, bundle, spec_inputs(spec, 64), options=TEXTURE, what=f"folded {precision} {spec}")


def _run_spec(width: int, depth: int = 3) -> MLPSpec:
    """3 -> width -> (width -> width) x depth -> 2, relu after every hidden layer."""
    return MLPSpec([3], [width] * (depth + 1), [("relu", {})] * (depth + 1), 2, None, None, [True] * (depth + 2),
                   seed=11)


def test_the_chunk_holds_the_run_once_and_the_plan_a_row_per_layer():
    bundle = build_mlp(_run_spec(24)).export("mlp")
    gen = generate(bundle, options=TEXTURE)
    assert _layer_loops(gen.chunk) == [3]
    assert gen.chunk.count("for (int o = 0; o < 6;") == 2   # the first layer's and the run's, once
    rows = {r.node: r for r in gen.plan.rows}
    assert [n for n in rows if n.startswith(("l", "a"))] == ["l0", "a0", "l1", "a1", "l2", "a2", "l3", "a3", "l4"]
    assert _folded(gen) == {"l1", "l2", "l3"}
    assert "with l2, l3" in rows["l1"].why and "in the loop over layers l1, l2, l3" in rows["a2"].why
    assert rows["l2"].storage == "texture" and rows["l2"].fetches == 6 * (1 + 4 * 6) and rows["l2"].params == 24 * 25
    # inline layers differ in the code itself: nothing to fold
    assert _layer_loops(generate(bundle, storage="inline").chunk) == []


def test_a_run_folds_only_within_the_loop_budget():
    # unfolded: 32 iterations over outputs for each of the first 4 layers (the last has one
    # output block: no loop) = 128; the fold of l1..l3 adds one per layer = 131
    bundle = build_mlp(_run_spec(128)).export("mlp")
    storage = {n.id: ("texture", "") for n in bundle.nodes if n.type == "dense"}
    assert [len(r) for r in find_runs(bundle, storage)] == [3]

    def folds(calls):   # (65535 - calls) // calls iterations per evaluation
        return list(fold_runs(bundle, storage, loop_chunks(bundle, storage, LLVMPIPE, calls), LLVMPIPE, calls))
    assert folds(400) == ["l1"]          # 162 left: folds
    assert folds(508) == []              # 128 left: fits unfolded only
    assert fold_runs(bundle, storage, loop_chunks(bundle, storage, {}, 10**6), {}, 10**6)   # no cap: folds
    gen = generate(bundle, options=TEXTURE, limits=LLVMPIPE, calls=508)
    assert _layer_loops(gen.chunk) == [] and not _folded(gen)
    assert _layer_loops(generate(bundle, options=TEXTURE, limits=LLVMPIPE, calls=400).chunk) == [3]


def test_a_run_unrolled_for_the_budget_still_folds_and_matches_torch(gl):
    # 64 wide: 16 iterations a layer, 64 unfolded; 1820 calls leave 35 an evaluation: every loop
    # over outputs does two blocks a pass (32), and the fold's 3 still fit
    spec = _run_spec(64)
    bundle = build_mlp(spec).export("mlp")
    gen = generate(bundle, options=TEXTURE, limits=LLVMPIPE, calls=1820)
    assert _layer_loops(gen.chunk) == [3] and "o += 2" in gen.chunk
    assert all("unrolled x2" in r.why for r in gen.plan.rows if r.node in ("l1", "l2", "l3"))
    x = spec_inputs(spec, 64)
    assert_parity(glsl_eval(gl, gen, x), torch_reference(bundle, x), what="folded, 2 blocks a pass")
    # 1598 calls leave 40: l0..l2 take two blocks a pass and l3 one, so the run has no one body
    storage = {n.id: ("texture", "") for n in bundle.nodes if n.type == "dense"}
    assert fold_runs(bundle, storage, loop_chunks(bundle, storage, LLVMPIPE, 1598), LLVMPIPE, 1598) == {}


@pytest.mark.parametrize("version", ["330", "es300"])
@pytest.mark.parametrize("precision", ["f32", "i8"])
def test_a_folded_run_compiles_for_every_target(gl, version, precision):
    from inshade.quantize import quantized

    spec = _run_spec(24)
    bundle = quantized(build_mlp(spec).export("mlp"), precision)
    x = spec_inputs(spec, 64)
    assert_parity(glsl_eval(gl, bundle, x, version=version, options=TEXTURE), torch_reference(bundle, x),
                  what=f"folded {precision} run, GLSL {version}")
