"""The elementwise ops with special values (log, log2, floor, ceil, fmod, remainder, power), atan2 and
int_gather on every shading language beside OpenGL's GLSL (WGSL, Vulkan GLSL, HLSL, Slang), through the
real driver (runtime.compute), held to the rules their GL tests state (tests/components/
test_elementwise_ops.py, test_int_lanes.py) on the same probes: torch's non-finite values exactly (the
same inf, NaN where torch gives NaN), floor / ceil / fmod / remainder equal to torch's (within 2^-126
where either side is subnormal: a driver flushes), log / log2 / power under tests/parity.py's rule,
atan2 within 5e-7 with +-pi to the bit, int_gather's rows equal.

Measured on this machine (lavapipe, every target): every target meets the GL rule on every probe,
subnormals and signed zeros included (the helpers read a float's bits, so a flushing driver does not
change them); no derived rule was needed. The worst errors (scaled, as tests/parity.py's rule): log
1.2e-7, log2 1.1e-7, power 3.7e-6 (the exp2 path at |p log2|x|| near the envelope's POW_ARG), atan2
1.2e-7; floor, ceil, fmod, remainder and int_gather exact."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

import inshade
from inshade.codegen import generate
from inshade.grid_layout import grid_levels
from inshade.components.dense.torch_twin import Dense
from inshade.components.elementwise.torch_twin import Ceil, Floor, Fmod, Log, Log2, Power, Remainder
from inshade.components.feature_axis.torch_twin import Atan2, IntGather
from inshade.models import GraphModule
from inshade.runtime.compute import TARGETS, run_target
from parity import assert_parity, parity_settings, torch_reference, uniform_inputs
from test_elementwise_ops import (POW_SPECIAL, as_rows, assert_matches, atan2_probes, build_op_graph, divisor_probes,
                                  f32, log_probes, op_graphs, per_op, power_probes, rounding_probes)
from test_int_lanes import Lookup, PlainHashEncoding, programs
from test_outside_networks import PeriodicOps

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def run_ops(bundle, inputs: dict, width: int, target: str) -> dict:
    """The target and torch over per-port probe lists (each padded to the longest): outputs by op
    name, with the probe values in the same layout (test_elementwise_ops.evaluate's, on a target)."""
    rows = max(math.ceil(len(v) / width) for v in inputs.values())
    xs = {k: as_rows(np.resize(f32(v), rows * width), width) for k, v in inputs.items()}
    x = np.concatenate(list(xs.values()), 1)
    out, ref = run_target(generate(bundle, target=target), x, target)[0], torch_reference(bundle, x)
    return {k: (out[:, i * width:(i + 1) * width], ref[:, i * width:(i + 1) * width], xs[k])
            for i, k in enumerate(inputs)}


def assert_ops(results: dict, exact, what: str) -> None:
    for k, (out, ref, x) in results.items():
        assert_matches(out, ref, x, exact=exact(k), what=f"{what} {k}")


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("width", [4, 3])
def test_rounding_and_log_at_special_points(target, width):
    """floor and ceil exactly, log and log2 under the rule (-inf at +-0, NaN below, subnormals from
    their bits); whole vec4 blocks (width 4) and single lanes (width 3), one program."""
    ops = {"floor": Floor(), "ceil": Ceil(), "log": Log(), "log2": Log2()}
    probes = {"floor": rounding_probes(), "ceil": rounding_probes(1), "log": log_probes(), "log2": log_probes(1)}
    res = run_ops(per_op(ops, width), probes, width, target)
    assert_ops(res, lambda k: k in ("floor", "ceil"), f"{target} width {width}")


DIVISORS = st.one_of(
    st.sampled_from([1.0, -1.0, 0.1, -0.7, 3.0, 0.75, -2.5, 2.0 ** -20, 1e30, 1 / 3]),
    st.builds(lambda m, e: m * 2.0 ** e, st.floats(-2, 2, width=32).filter(lambda m: abs(m) >= 1), st.integers(-30, 30)))


@pytest.mark.parametrize("target", TARGETS)
@parity_settings(max_examples=2)
@given(divisors=st.lists(DIVISORS, min_size=2, max_size=2), width=st.sampled_from([4, 3]))
def test_fmod_and_remainder_exact_at_multiples(target, divisors, width):
    """Equal to torch at exact multiples of the divisor and one ulp either side, at +-0, inf, NaN,
    subnormals and random points; four nodes (their lane loops) in one program."""
    ops, probes = {}, {}
    for i, c in enumerate(divisors):
        ops[f"fmod{i}"], ops[f"remainder{i}"] = Fmod(c), Remainder(c)
        probes[f"fmod{i}"] = probes[f"remainder{i}"] = divisor_probes(c, i)
    assert_ops(run_ops(per_op(ops, width), probes, width, target), lambda k: True, f"{target} width {width}")


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("chunk", range(3))
def test_power_at_special_points(target, chunk):
    """torch's own paths (p = 0, 1, 0.5, -0.5, -1), integers by repeated squaring, huge integers,
    non-integers; at +-0, subnormals, +-1, +-inf, NaN and negative bases."""
    exps = POW_SPECIAL[chunk * 8:(chunk + 1) * 8]
    ops = {f"p{i}": Power(p) for i, p in enumerate(exps)}
    probes = {k: power_probes(ops[k].exponent, i) for i, k in enumerate(ops)}
    assert_ops(run_ops(per_op(ops, 4), probes, 4, target), lambda k: False, f"{target} power {exps}")


@pytest.mark.parametrize("target", TARGETS)
@parity_settings(max_examples=2)
@given(exps=st.lists(st.one_of(st.integers(-32, 32).map(float), st.integers(-64, 64).map(lambda k: k / 2),
                               st.floats(-8, 8, width=32)), min_size=4, max_size=4))
def test_power_random_exponents(target, exps):
    """Random exponents on lanes (all zero: a network that reads none of its inputs, x^0 = 1)."""
    ops = {f"p{i}": Power(p) for i, p in enumerate(exps)}
    probes = {k: power_probes(ops[k].exponent, i) for i, k in enumerate(ops)}
    assert_ops(run_ops(per_op(ops, 3), probes, 3, target), lambda k: False, f"{target} power {exps}")


@pytest.mark.parametrize("target", TARGETS)
def test_a_network_that_reads_no_input(target):
    ops = {f"p{i}": Power(0.0) for i in range(4)}
    probes = {k: power_probes(0.0, i) for i, k in enumerate(ops)}
    assert_ops(run_ops(per_op(ops, 3), probes, 3, target), lambda k: False, f"{target} x^0")


@pytest.mark.parametrize("target", TARGETS)
def test_atan2_at_zeros_axes_and_infinities(target):
    """torch.atan2 with C's special values (atan2(+-0, +-0), the axes, the infinities, NaN, subnormals):
    the vec4 path (two 4-lane branches) and the lane path (one 6-lane [a | b] input), one program;
    within the GL helper's 5e-7, +-pi to the bit."""
    a, b = atan2_probes()
    rows = math.ceil(len(a) / 4)
    a, b = np.resize(a, 4 * rows), np.resize(b, 4 * rows)
    g = GraphModule([("a", 4), ("b", 4), ("ab", 6)])
    g.output("y4", g.add("t4", Atan2(), ["a", "b"]))
    g.output("y3", g.add("t3", Atan2(), "ab"))
    bundle = g.export("atan2")
    x = np.concatenate([a.reshape(rows, 4), b.reshape(rows, 4), a[:rows * 3].reshape(rows, 3),
                        b[:rows * 3].reshape(rows, 3)], 1)
    out, ref = run_target(generate(bundle, target=target), x, target)[0], torch_reference(bundle, x)
    assert assert_matches(out, ref, what=f"{target} atan2") < 5e-7
    exact_pi = np.abs(ref) == np.float32(np.pi)
    assert exact_pi.sum() >= 4 and np.array_equal(out[exact_pi], ref[exact_pi])


@pytest.mark.parametrize("target, storage", [(t, s) for t in TARGETS for s in ("ubo", "texture")])
def test_padding_lanes_stay_finite_before_a_looping_dense(target, storage):
    """log / log2 / power(p < 0) of a partial block feeding a dense that multiplies whole blocks: the
    padding lanes (0) stay finite, or 0 * inf would turn the sums into NaN."""
    gen = torch.Generator().manual_seed(0)
    g = GraphModule([("x", 3)])
    for k, comp in (("l", Log()), ("l2", Log2()), ("p", Power(-1.5))):
        d = Dense(3, 6)
        with torch.no_grad():
            d.linear.weight.copy_(torch.rand(6, 3, generator=gen) - 0.5)
        g.output(f"y_{k}", g.add(f"d_{k}", d, g.add(k, comp, "x")))
    bundle = g.export("pad")
    x = uniform_inputs(0, 128, 3, 0.25, 4.0)
    out = run_target(generate(bundle, target=target, storage=storage), x, target)[0]
    assert_parity(out, torch_reference(bundle, x), what=f"{target} {storage}")


@pytest.mark.parametrize("target", TARGETS)
@parity_settings(max_examples=2)
@given(recipe=op_graphs())
def test_ops_in_random_graphs(target, recipe):
    """A stepped op of the input, a dense, a continuous op (log, log2, power, atan2) kept in its domain,
    a dense: test_elementwise_ops' random graphs, on the target."""
    bundle = build_op_graph(recipe).export("ops")
    x = uniform_inputs(recipe["seed"] + 1, 256, recipe["d"], -4.0, 4.0)
    out = run_target(generate(bundle, target=target, storage="inline"), x, target)[0]
    assert_parity(out, torch_reference(bundle, x), what=f"{target} {recipe}")


@pytest.mark.parametrize("target", TARGETS)
def test_coordinate_network_ops_on_every_target(target, tmp_path):
    """An imported coordinate network using every op here (logs, rounding, fmod and %, atan2, powers)."""
    torch.manual_seed(3)
    module, x = PeriodicOps().eval(), torch.rand(128, 2) * 2 - 1
    bundle = inshade.export(module, x, tmp_path / "b", quiet=True, check=False)
    out = run_target(generate(bundle, target=target), x.numpy(), target)[0]
    with torch.no_grad():
        assert_parity(out, module(x).numpy(), what=f"{target} coordinate ops")


def _gather_bundle(case, features: int, seed: int):
    program, indices, rows = case
    rng = np.random.default_rng(seed)
    g = GraphModule([("x", 2)])
    g.add("gather", IntGather(program, indices, rows, features,
                              table=rng.uniform(-1, 1, (rows, features)).astype(np.float32)), "x")
    g.output("y", "gather")
    x = rng.uniform(-300, 300, (64, 2)).astype(np.float32)
    x[:4] = [[0.0, -0.0], [-1.5, 2.5], [2 ** 30, -(2 ** 30)], [-7.99, 7.99]]   # signs, halves, big values
    return g, g.export("imported", "int_gather_probe"), x


@pytest.mark.parametrize("target", TARGETS)
@parity_settings(max_examples=4)
@given(case=programs(), features=st.sampled_from([1, 3, 5, 8]), seed=st.integers(0, 2 ** 16))
def test_int_gather_matches_torch_exactly(target, case, features, seed):
    """uint32 programs (wrapping products, xor, shifts, big constants) and the rows they index, equal
    to torch's: integer code and an exact texel read on both sides."""
    g, bundle, x = _gather_bundle(case, features, seed)
    with torch.no_grad():
        ref = g(torch.from_numpy(x)).numpy()
    np.testing.assert_array_equal(run_target(generate(bundle, target=target), x, target)[0], ref)



@pytest.mark.parametrize("target", TARGETS)
def test_computed_index_networks_on_every_target(target, tmp_path):
    """An Embedding indexed by a computed integer, and nerfstudio's plain-torch hash encoding, exported
    from torch: int_gather on the target within the rule of the torch module."""
    torch.manual_seed(0)
    levels = grid_levels(3, 4, 20, 1.5, 12)
    table = torch.rand(sum(lv.rows for lv in levels), 2) * 2 - 1
    for name, module, x in (("embedding", Lookup().eval(), torch.rand(128, 1)),
                            ("hash encoding", PlainHashEncoding(levels, table).eval(), torch.rand(128, 3))):
        bundle = inshade.export(module, x, tmp_path / name, quiet=True, check=False)
        assert any(n.type == "int_gather" for n in bundle.nodes), name
        with torch.no_grad():
            ref = module(x).numpy()
        assert_parity(run_target(generate(bundle, target=target), x.numpy(), target)[0], ref, what=f"{target} {name}")
