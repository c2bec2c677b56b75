"""Dense networks: random architectures through the real driver in every weight placement,
and the mat4 / std140 / weight-texture layouts against numpy.

Tolerance: tests/parity.py's rule, |glsl - torch| <= 1e-5 * max(1, |torch|), everywhere
(the fp16 weight texture is compared with a reference whose weights are rounded to fp16).
"""
from __future__ import annotations

import re

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.codegen import generate
from inshade.codegen.glsl import blocks, mat4
from inshade.components import ACTIVATIONS
from inshade.components.dense.emit_plan import WeightTexture, choose_storage, pack, std140
from inshade.models import GraphModule, mlp_graph

from parity import (TOL, MLPSpec, activation_specs, assert_parity, build_mlp, check_parity, glsl_eval,
                    mlp_specs, parity_settings, round_weights_fp16, spec_inputs, torch_reference,
                    uniform_inputs)

N = 64  # samples per example: enough lanes to hit every branch, small enough to draw quickly

# Per-mode block budgets (see parity.mlp_specs): llvmpipe's first-draw JIT time is what limits
# them. `ubo` is the tightest: the generated code indexes the uniform block with constants in
# fully unrolled sums, and llvmpipe's compile time for that grows steeply (measured: a 32x32
# layer ~20 s, a 64x64 layer > 7 min; looped code is unrolled by the compiler and no better:
# 64 -> 68 > 200 s), so random ubo nets stay at width <= 16 and the big-layer case is opt-in.
MODES = {
    "inline": dict(max_width=128, block_budget=250),
    "texture": dict(max_width=128, block_budget=300),
    "ubo": dict(max_width=16, block_budget=64),
    # auto with the driver's limits: small nets only (a > 4096-float net goes to unrolled ubo,
    # see above); the mixed ubo/texture choice is exercised with constrained limits below.
    "auto": dict(max_width=24, block_budget=120),
}


@pytest.mark.parametrize("storage", list(MODES))
@parity_settings(max_examples=15)
@given(data=st.data())
def test_random_mlp_parity(gl, gl_limits, storage, data):
    spec = data.draw(mlp_specs(**MODES[storage]), label="spec")
    bundle = build_mlp(spec).export("mlp")
    limits = gl_limits if storage == "auto" else None
    check_parity(gl, bundle, spec_inputs(spec, N), storage=storage, limits=limits,
                 what=f"{storage} {spec}")


DEEP_PARAMS = {"leaky_relu": {"slope": -0.3}, "sin": {"omega0": 30.0}, "cos": {"omega0": 30.0},
               "softplus": {"beta": 2.0, "threshold": 20.0}, "gelu": {"approximate": "none"}, "elu": {"alpha": 0.7},
               "clamp": {"min": -0.5, "max": 0.25}}


@pytest.mark.parametrize("act", [a for a in ACTIVATIONS if a != "expm1"] + ["softplus_plain", "gelu_tanh"])
def test_every_activation_deep(gl, act):
    """Each activation alone through 4 hidden layers of odd widths (several blocks, padding)."""
    act, params = {"softplus_plain": ("softplus", {}), "gelu_tanh": ("gelu", {"approximate": "tanh"})}.get(
        act, (act, DEEP_PARAMS.get(act, {})))
    spec = MLPSpec([3, 2], [13, 7, 22, 5], [(act, params)] * 4, 6, None, 1, [True] * 5, seed=7)
    bundle = build_mlp(spec).export("mlp")
    x = spec_inputs(spec, 256)
    # also large inputs: the activations must stay finite and match (softplus/tanh/sigmoid
    # forms that cannot overflow), except where the generator's small-range promise is the point.
    if act not in ("exp", "sin", "cos"):
        x = np.concatenate([x, 40.0 * x], 0)
    check_parity(gl, bundle, x, storage="inline")


@parity_settings(max_examples=8)
@given(spec=mlp_specs(max_width=64, block_budget=300))
def test_auto_mixed_ubo_and_texture(gl, spec):
    """auto with limits that force the per-layer choice: small layers take a uniform block, big
    ones the weight texture, and at most 2 layers get a block; all in one program."""
    limits = {"GL_MAX_UNIFORM_BLOCK_SIZE": 16 * 64 + 4 * 16, "GL_MAX_FRAGMENT_UNIFORM_BLOCKS": 4}
    bundle = build_mlp(spec).export("mlp")
    gen = generate(bundle, storage="auto", limits=limits)
    modes = [r.storage for r in gen.plan.rows if r.type == "dense"]
    floats = sum(blocks(n.in_dim) * blocks(n.out_dim) * 16 + blocks(n.out_dim) * 4
                 for n in bundle.nodes if n.type == "dense")
    if floats > 4096:
        assert set(modes) <= {"ubo", "texture"} and modes.count("ubo") <= 2
    ref = torch_reference(bundle, spec_inputs(spec, N))
    assert_parity(glsl_eval(gl, gen, spec_inputs(spec, N)), ref, what=f"auto {modes} {spec}")


@parity_settings(max_examples=8)
@given(spec=mlp_specs(max_width=64, block_budget=300))
def test_texture_f16(gl, spec):
    """RGBA16F weight texture. The shader computes in fp32 on fp16-rounded weights, so it is
    compared, under the same 1e-5 rule, with torch on the same fp16-rounded weights. (Against
    the fp32 weights the error is the fp16 rounding itself, 2^-11 relative per weight; that is
    a property of the format, not of the code, and is not asserted.)"""
    bundle = build_mlp(spec).export("mlp")
    x = spec_inputs(spec, N)
    ref = torch_reference(round_weights_fp16(bundle), x)
    out = glsl_eval(gl, bundle, x, storage="texture", texture_format="f2")
    assert_parity(out, ref, what=f"texture f2 {spec}")


def test_multiple_inputs_and_outputs_blocks(gl):
    """3 input ports (2 + 3 + 1 = 6 lanes), outputs y (30 wide = 8 blocks, every draw buffer
    llvmpipe has) and a hidden tap: outputs gathered across unaligned lanes."""
    spec = MLPSpec([2, 3, 1], [9, 11], [("tanh", {}), ("softplus", {})], 21, ("sigmoid", {}), 1,
                   [True, False, True], seed=3)
    bundle = build_mlp(spec).export("mlp")
    assert bundle.out_dim == 32 and bundle.in_dim == 6
    for storage in ("inline", "texture"):
        check_parity(gl, bundle, spec_inputs(spec, 300), storage=storage)


@pytest.mark.parametrize("width", [256, 512])
def test_wide_texture(gl, width):
    """Widths beyond 128 (where the Learnt Transfer paper's GLSL path failed) in texture mode:
    a width-wide hidden layer between 3 inputs and 8 outputs (a weight-texture row of
    1 + width texels), small batch. The square 256x256 / 512x512 layers are below."""
    torch.manual_seed(width)
    g = mlp_graph(3, [width], 8, "relu")
    bundle = g.export("wide")
    check_parity(gl, bundle, uniform_inputs(width, 16, 3), storage="texture")


@pytest.mark.parametrize("width", [256, 512])
def test_wide_square_texture(gl, width):
    """width x width layers (4096 / 16384 mat4 blocks) in texture mode (2 s and 9 s of llvmpipe JIT)."""
    torch.manual_seed(width)
    bundle = mlp_graph(3, [width, width], 5, "relu").export("wide")
    check_parity(gl, bundle, uniform_inputs(3, 8, 3), storage="texture")


def test_ubo_big_layer(gl, gl_limits):
    """A uniform-block layer of 272 mat4 blocks (64 -> 68), looped: its output array's spare block
    keeps Mesa from unrolling the loop over outputs (it took over 200 s to JIT unrolled, 4 s looped)."""
    torch.manual_seed(4)
    bundle = mlp_graph(64, [68], 4, "tanh").export("ubo_big")
    check_parity(gl, bundle, uniform_inputs(5, 32, 64), storage="ubo", limits=gl_limits)


# --- layouts against numpy (no GL) ------------------------------------------------------------

@given(out_dim=st.integers(1, 23), in_dim=st.integers(1, 23), with_bias=st.booleans(), seed=st.integers(0, 99))
def test_pack_blocks_are_padded_torch_blocks(out_dim, in_dim, with_bias, seed):
    rng = np.random.default_rng(seed)
    w = rng.normal(size=(out_dim, in_dim)).astype(np.float32)
    b = rng.normal(size=out_dim).astype(np.float32) if with_bias else None
    wb, bb = pack(w, b)
    ob, ib = blocks(out_dim), blocks(in_dim)
    assert wb.shape == (ob, ib, 4, 4) and bb.shape == (ob, 4)
    full = np.zeros((4 * ob, 4 * ib), np.float32)
    full[:out_dim, :in_dim] = w
    for o in range(ob):
        for i in range(ib):
            np.testing.assert_array_equal(wb[o, i], full[4 * o:4 * o + 4, 4 * i:4 * i + 4])
    np.testing.assert_array_equal(bb.reshape(-1)[:out_dim], b if b is not None else 0)
    assert not bb.reshape(-1)[out_dim:].any()
    # the block sum reproduces W x + b
    x = rng.normal(size=in_dim).astype(np.float32)
    xp = np.zeros(4 * ib, np.float32)
    xp[:in_dim] = x
    y = np.stack([bb[o] + sum(wb[o, i] @ xp[4 * i:4 * i + 4] for i in range(ib)) for o in range(ob)]).reshape(-1)
    np.testing.assert_allclose(y[:out_dim], w @ x + (b if b is not None else 0), rtol=1e-5, atol=1e-5)


@given(seed=st.integers(0, 99))
def test_mat4_literal_is_column_major(seed):
    block = np.random.default_rng(seed).normal(size=(4, 4)).astype(np.float32)
    nums = np.array([float(v) for v in re.findall(r"[-+0-9.e]+", mat4(block)[5:-1])], np.float32)
    # GLSL mat4(c0.xyzw, c1.xyzw, ...): element k is column k // 4, row k % 4
    np.testing.assert_array_equal(nums.reshape(4, 4).T, block)  # and %.9g round-trips exactly


@given(out_dim=st.integers(1, 19), in_dim=st.integers(1, 19), seed=st.integers(0, 99))
def test_std140_layout(out_dim, in_dim, seed):
    """std140: mat4 W[OB*IB] (64 B each, 4 columns of 16 B), then vec4 b[OB] (16 B each)."""
    rng = np.random.default_rng(seed)
    w = rng.normal(size=(out_dim, in_dim)).astype(np.float32)
    b = rng.normal(size=out_dim).astype(np.float32)
    wb, bb = pack(w, b)
    ob, ib = wb.shape[:2]
    data = std140(wb, bb)
    assert len(data) == ob * ib * 64 + ob * 16
    f = np.frombuffer(data, "<f4")
    for o in range(ob):
        for i in range(ib):
            base = (o * ib + i) * 16   # W[o * IB + i], as the generated code indexes it
            for col in range(4):
                np.testing.assert_array_equal(f[base + 4 * col: base + 4 * col + 4], wb[o, i][:, col])
    np.testing.assert_array_equal(f[ob * ib * 16:].reshape(ob, 4), bb)


def test_weight_texture_rows():
    """Texture rows: texel 0 = bias, texels 1 + 4 i + k = column k of block (o, i)."""
    rng = np.random.default_rng(0)
    w1, b1 = rng.normal(size=(6, 9)).astype(np.float32), rng.normal(size=6).astype(np.float32)
    w2, b2 = rng.normal(size=(3, 6)).astype(np.float32), rng.normal(size=3).astype(np.float32)

    class Ctx:
        def option(self, component, name):
            assert (component, name) == ("dense", "texture_format")
            return "f4"

        def name(self, *p):
            return "_".join(("net",) + p)

    tex = WeightTexture(Ctx())
    r1 = tex.add(*pack(w1, b1))
    r2 = tex.add(*pack(w2, b2))
    assert (r1, r2) == (0, 2)
    data = tex.resource().data
    assert data.shape == (3, 1 + 4 * 3, 4)
    for row0, (w, b) in ((r1, (w1, b1)), (r2, (w2, b2))):
        wb, bb = pack(w, b)
        for o in range(wb.shape[0]):
            np.testing.assert_array_equal(data[row0 + o, 0], bb[o])
            for i in range(wb.shape[1]):
                for k in range(4):
                    np.testing.assert_array_equal(data[row0 + o, 1 + 4 * i + k], wb[o, i][:, k])


def test_choose_storage_auto_rules():
    torch.manual_seed(0)
    small = mlp_graph(3, [8, 8], 3).export("s")
    assert {m for m, _ in choose_storage(small, "auto", {}).values()} == {"inline"}
    big = mlp_graph(3, [64, 64], 3).export("b")
    got = choose_storage(big, "auto", {"GL_MAX_UNIFORM_BLOCK_SIZE": 4096, "GL_MAX_FRAGMENT_UNIFORM_BLOCKS": 3})
    # l1 (64x64 = 16 KiB) exceeds 4 KiB; one block is free after the 2 reserved
    assert got["l1"][0] == "texture" and "exceeds" in got["l1"][1]
    assert [m for m, _ in got.values()].count("ubo") == 1


def test_parity_rule_message():
    ref = np.array([[0.5, 100.0]], np.float32)
    assert assert_parity(ref + np.float32([[5e-6, 5e-4]]), ref) <= TOL
    with pytest.raises(AssertionError, match=r"max \|glsl - torch\|.*max abs error"):
        assert_parity(ref + np.float32([[2e-5, 0]]), ref)
    with pytest.raises(AssertionError, match="not finite"):
        assert_parity(np.float32([[np.nan, 100.0]]), ref)


def test_random_spec_param_count_and_activations():
    spec = MLPSpec([2, 1], [5, 6], [("sin", {"omega0": 30.0}), ("exp", {})], 9, None, 0, [True, False, True], 1)
    g = build_mlp(spec)
    assert sum(p.numel() for p in g.parameters()) == spec.param_count()
    bundle = g.export("m")
    assert GraphModule.from_bundle(bundle)(torch.zeros(4, 3)).shape == (4, 9 + 5)


def test_a_looped_layer_keeps_its_loop_over_outputs():
    """Mesa's NIR unrolls any loop that runs exactly the length of an array it indexes, whatever the
    body's size (a 128-wide texture layer became 1024 unrolled mat4 blocks: 20 s of JIT instead of
    under one): a big layer looping one output block per pass writes an array one block longer. On a
    software renderer its inputs are written out (an array read at a loop index is a per-lane gather
    on llvmpipe); for a GPU they stay a loop, left to its compiler."""
    torch.manual_seed(0)
    bundle = mlp_graph(3, [128, 128], 1, "relu").export("looped")
    for limits, input_loop in (({"renderer": "llvmpipe (LLVM 15.0.6, 256 bits)"}, False), ({"software": False}, True)):
        chunk = generate(bundle, storage="texture", limits=limits).chunk
        assert re.search(r"vec4 v_\w+\[33\];", chunk) and "for (int o = 0; o < 32; o += 1)" in chunk
        assert ("for (int i" in chunk) == input_loop, limits
