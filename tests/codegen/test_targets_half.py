"""fp16 arithmetic (codegen option ``arithmetic``) on a real driver: Vulkan GLSL
(GL_EXT_shader_explicit_arithmetic_types_float16), WGSL (``enable f16``) and Slang (``half``) on this
machine's Vulkan device (lavapipe), every weight storage, held to the float16 envelope
(inshade/convert/half_envelope.py: a bound per example and output, walked beside the float32 twin) plus the
float32 rule. Only dense
layers compute in float16; the other components keep float32 and their own parity tests."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from inshade.codegen import generate
from inshade.codegen.targets import TargetError
from inshade.convert.half_envelope import half_envelope
from inshade.quantize import quantized
from inshade.runtime.compute import run_target
from parity import TOL, MLPSpec, build_mlp, mlp_specs, parity_settings, spec_inputs

pytestmark = pytest.mark.usefixtures("one_torch_thread")
HALF_TARGETS = ("vulkan", "wgsl", "slang")
ARITHMETIC = ("f16", "f16_acc32")
STORAGES = ("inline", "ubo", "texture")
FIXED = MLPSpec([3, 2], [21, 13], [("relu", {}), ("tanh", {})], 6, None, 0, [True, False, True], seed=11)


def within(out: np.ndarray, twin: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """Where the shader is within the envelope: |shader - twin| <= bound + the float32 rule (an infinite
    bound, where float16 may overflow or leave a function's domain, holds nothing)."""
    return (np.abs(out.astype(np.float64) - twin) <= bound + TOL) | ~np.isfinite(bound)


@pytest.mark.parametrize("target", HALF_TARGETS)
@pytest.mark.parametrize("arithmetic", ARITHMETIC)
def test_a_network_in_half_precision_stays_in_its_envelope(target, arithmetic):
    bundle = quantized(build_mlp(FIXED).export("mlp"), "f16")
    x = spec_inputs(FIXED, 300)
    twin, bound = half_envelope(bundle, x, arithmetic)
    assert np.isfinite(bound).all()
    for storage in STORAGES:
        gen = generate(bundle, target=target, storage=storage, arithmetic=arithmetic)
        out = run_target(gen, x, target)[0]
        err = np.abs(out - twin)
        assert within(out, twin, bound).all(), f"{target} {storage} {arithmetic}: max {err.max():.3g}"
        # the shader does compute in float16: a float32 one would sit within 1e-6 of the twin
        assert err.max() > 1e-4, f"{target} {storage} {arithmetic}: {err.max():.3g}: no float16 rounding seen"
        # and the bound is no blanket: within 100x of the worst error seen
        assert bound.max() < 100 * err.max()


@pytest.mark.parametrize("target", HALF_TARGETS)
@parity_settings(max_examples=6)
@given(data=st.data())
def test_random_networks_in_half_precision(target, data):
    spec = data.draw(mlp_specs(max_width=48, block_budget=160), label="spec")
    arithmetic = data.draw(st.sampled_from(ARITHMETIC), label="arithmetic")
    storage = data.draw(st.sampled_from(STORAGES), label="storage")
    bundle = quantized(build_mlp(spec).export("mlp"), "f16")
    x = spec_inputs(spec, 200)
    twin, bound = half_envelope(bundle, x, arithmetic)
    out = run_target(generate(bundle, target=target, storage=storage, arithmetic=arithmetic), x, target)[0]
    bad = ~within(out, twin, bound)
    assert not bad.any(), (f"{target} {storage} {arithmetic} {spec}: {int(bad.sum())} outside, e.g. shader "
                           f"{out[bad][0]!r}, twin {twin[bad][0]!r}, bound {bound[bad][0]!r}")


@pytest.mark.parametrize("asset", ["di_texture_chelsea", "di_footprint"])
def test_lookup_arrays_after_a_half_layer_carry_its_error_by_their_slope(asset):
    """Differentiable Indirection's networks: float16 dense layers feeding lookup arrays."""
    from inshade.bundle import load
    from inshade.scene.description import load_scene, resolve_asset

    bundle = quantized(load(load_scene(resolve_asset(asset)).networks[0].bundle), "f16")
    x = np.random.default_rng(5).uniform(0.0, 1.0, (512, bundle.in_dim)).astype(np.float32)
    twin, bound = half_envelope(bundle, x, "f16")
    out = run_target(generate(bundle, target="wgsl", storage="texture", arithmetic="f16"), x, "wgsl")[0]
    assert np.isfinite(bound).all() and within(out, twin, bound).all()
    assert np.abs(out - twin).max() > 1e-5


def test_the_code_says_what_it_needs():
    bundle = quantized(build_mlp(FIXED).export("mlp"), "f16")
    vulkan = generate(bundle, target="vulkan", storage="inline", arithmetic="f16")
    assert vulkan.chunk.startswith("#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require\n")
    assert "f16vec4" in vulkan.chunk
    wgsl = generate(bundle, target="wgsl", storage="texture", arithmetic="f16_acc32")
    assert wgsl.chunk.startswith("enable f16;\n") and "mat4x4<f16>" in wgsl.chunk
    assert all("arithmetic f16_acc32: float16 block products, float32 sums" in r.why
               for r in wgsl.plan.rows if r.type == "dense")
    assert "f16" not in generate(bundle, target="wgsl", storage="inline").chunk.split("\n")[0]
    slang = generate(bundle, target="slang", storage="ubo", arithmetic="f16")
    assert slang.chunk.startswith("// float16 arithmetic (half)") and "half4(" in slang.chunk


@pytest.mark.parametrize("target", ["330", "es300", "hlsl"])
def test_a_target_without_half_arithmetic_is_refused_naming_those_with_it(target):
    bundle = quantized(build_mlp(FIXED).export("mlp"), "f16")
    with pytest.raises(TargetError, match=f"target {target} has no float16 arithmetic here; targets with it: "
                                          "vulkan, wgsl, slang"):
        generate(bundle, target=target, arithmetic="f16")


def test_weights_not_stored_as_float16_are_refused():
    with pytest.raises(TargetError, match=r"node l0: arithmetic f16 computes with float16 weights: store the layer "
                                          r"at precision f16 \(inshade.quantize, --precision f16\), not f32"):
        generate(build_mlp(FIXED).export("mlp"), target="wgsl", arithmetic="f16")


def test_a_component_without_a_float16_rule_after_a_half_layer_is_refused():
    from inshade.models import GraphModule
    from inshade.models.registry import TORCH_COMPONENTS

    g = GraphModule([("x", 3)])
    g.dense("l0", "x", 8)
    g.add("r", TORCH_COMPONENTS["reduce"](groups=2, op="sum"), "l0")
    g.output("y", "r")
    bundle = quantized(g.export("mlp"), "f16")
    with pytest.raises(ValueError, match="node r: component 'reduce' has no float16 error rule"):
        half_envelope(bundle, np.zeros((4, 3), np.float32), "f16")
