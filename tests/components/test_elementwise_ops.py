"""Elementwise ops with special values (components/elementwise/spec.py: log, log2, floor, ceil, trunc, round, frac,
fmod, remainder, power; the two-branch atan2): torch twin (components/elementwise/torch_twin.py, components/feature_axis/torch_twin.py)
against the GLSL (components/elementwise/emit.py, components/feature_axis/emit.py, shaders/lib/activations.glsl) through the
driver, at the points where each is discontinuous or special (probed explicitly, many per program) and
at random ones, and inside random graphs; their envelope rules (inshade/envelope.py).

The rule is tests/parity.py's, |glsl - torch| <= 1e-5 max(1, |torch|), with non-finite values matched
exactly (the same inf, NaN where torch gives NaN). The stepped ops are exact on both sides, so they are
held to equality; the one allowance is below 2^-126, where drivers flush subnormals to zero."""
from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.codegen import GL_TARGETS, generate
from inshade.components import ComponentError, check_node, resolve_params
from inshade.components.dense.torch_twin import Dense
from inshade.components.elementwise.torch_twin import (Ceil, Floor, Fmod, Frac, Log, Log2, Power, Remainder, Round,
                                                       Tanh, Trunc)
from inshade.components.feature_axis.torch_twin import Affine, Atan2
from inshade.envelope import POW_ARG, POW_EXPONENT, analyse
from inshade.models import GraphModule

from parity import (TOL, check_parity, glsl_eval, node_values, parity_settings, scaled_error, torch_reference,
                    uniform_inputs)

F32 = np.finfo(np.float32)
TINY = float(F32.tiny)            # 2^-126: below it drivers flush, torch does not
SUBNORMALS = [1e-40, 5e-39, 1.4e-45]   # 5e-39: 1 / x is still finite (2e38)
SPECIAL = ([0.0, -0.0, math.inf, -math.inf, math.nan, TINY, -TINY, float(F32.max), -float(F32.max), 1.0, -1.0]
           + SUBNORMALS + [-v for v in SUBNORMALS])


def f32(values) -> np.ndarray:
    return np.asarray(values, np.float64).astype(np.float32)


def around(values) -> np.ndarray:
    """Each value and its float32 neighbours one ulp either side."""
    v = f32(values)
    return np.concatenate([v, np.nextafter(v, np.float32(-np.inf)), np.nextafter(v, np.float32(np.inf))])


def as_rows(values, width: int) -> np.ndarray:
    """A flat probe list as [N, width] rows (padded with its first value), every lane used."""
    v = f32(values)
    v = np.concatenate([v, np.full(-len(v) % width, v[0], np.float32)])
    return v.reshape(-1, width)


def assert_matches(glsl, ref, x=None, *, exact=False, what=""):
    """torch's non-finite values exactly; finite ones under the parity rule, or equal when `exact`
    (then within 2^-126 where either side is below it: a driver flushes subnormals)."""
    glsl, ref = np.asarray(glsl, np.float64), np.asarray(ref, np.float64)
    assert glsl.shape == ref.shape, (glsl.shape, ref.shape)
    finite = np.isfinite(ref)
    same_special = (np.isnan(ref) & np.isnan(glsl)) | (np.isinf(ref) & (glsl == ref))
    with np.errstate(invalid="ignore"):   # inf - inf where both are infinite: judged by same_special
        err = scaled_error(glsl, ref)
        close = (glsl == ref) | (np.abs(glsl - ref) <= TINY) if exact else np.isfinite(glsl) & (err <= TOL)
    bad = np.flatnonzero(~np.where(finite, close, same_special))
    if bad.size:
        xs = np.asarray(x).reshape(-1) if x is not None else None
        rows = [f"x={xs[i]!r} " if xs is not None and xs.size == ref.size else "" for i in bad[:8]]
        detail = "; ".join(f"{r}glsl {glsl.flat[i]!r} torch {ref.flat[i]!r}" for r, i in zip(rows, bad[:8]))
        raise AssertionError(f"{what}: {bad.size} of {ref.size} differ: {detail}")
    return float(np.nanmax(np.where(finite, err, 0.0))) if ref.size else 0.0


def per_op(ops: dict, width: int):
    """One program for many ops: input port `x_<name>` (width lanes) -> op -> output `<name>`."""
    g = GraphModule([(f"x_{k}", width) for k in ops])
    for k, comp in ops.items():
        g.output(k, g.add(k, comp, f"x_{k}"))
    return g.export("ops")


def evaluate(gl, bundle, inputs: dict, width: int):
    """Both executors over per-port probe lists (each padded to the longest): outputs by op name,
    with the probe values in the same layout."""
    rows = max(math.ceil(len(v) / width) for v in inputs.values())
    xs = {k: as_rows(np.resize(f32(v), rows * width), width) for k, v in inputs.items()}
    x = np.concatenate(list(xs.values()), 1)
    out, ref = glsl_eval(gl, bundle, x), torch_reference(bundle, x)
    return {k: (out[:, i * width:(i + 1) * width], ref[:, i * width:(i + 1) * width], xs[k])
            for i, k in enumerate(inputs)}


# --- probe points -----------------------------------------------------------------------------

def rounding_probes(seed=0) -> np.ndarray:
    """Integers, half-integers and their ulp neighbours (around 2^22 .. 2^24 too, where halves stop
    existing), the special values, random points."""
    k = np.arange(-12, 13, dtype=np.float64)
    big = [2.0 ** 22 + 0.5, 2.0 ** 23 - 0.5, 2.0 ** 23, 2.0 ** 23 + 1, 2.0 ** 24, 2.0 ** 24 + 2, 1e30, 0.49999997]
    rng = np.random.default_rng(seed)
    return np.concatenate([around(np.concatenate([k, k + 0.5, big, [-b for b in big]])), f32(SPECIAL),
                           f32(rng.uniform(-100, 100, 256)), f32(rng.uniform(-1, 1, 64))])


def log_probes(seed=0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.concatenate([f32(SPECIAL), around([1.0, 2.0, 0.5, math.e, 10.0]), f32(-rng.uniform(0, 10, 16)),
                           f32(np.exp(rng.uniform(-87, 88.7, 512))), f32(1 + rng.uniform(-1e-3, 1e-3, 128))])


def divisor_probes(c: float, seed=0) -> np.ndarray:
    """Multiples k c (|k| up to a few thousand, and to 2^100) with their ulp neighbours, values just
    inside +-c, the special values, random points with |x / c| up to 3000."""
    c = float(np.float32(c))
    rng = np.random.default_rng(seed)
    k = np.concatenate([np.arange(-16, 17), rng.integers(-3000, 3001, 64), [2.0 ** 40, -(2.0 ** 70), 2.0 ** 100]])
    inside = [c * 0.999, -c * 0.999, c / 3, 1e-10, -1e-10]
    with np.errstate(over="ignore"):
        points = np.concatenate([around(k * c), around(inside), f32(SPECIAL), f32(rng.uniform(-3000, 3000, 256) * c)])
    return points[np.abs(points.astype(np.float64) / c) < 2.0 ** 127]   # torch's own kernel is NaN at 2^128


def power_probes(p: float, seed=0) -> np.ndarray:
    """The special values, small integers and halves of both signs, random magnitudes with
    |p log2|x|| <= POW_ARG (the envelope's accuracy limit; for |p| far past POW_EXPONENT, where the
    envelope warns, results that saturate to 0 or inf instead); points whose result lies within a
    factor 4 of float32's overflow (where the last ulp decides inf) left out."""
    rng = np.random.default_rng(seed)
    if abs(p) <= 2 * POW_EXPONENT:
        mags = np.exp2(rng.uniform(-POW_ARG, POW_ARG, 256) / max(abs(p), 1.0))
    else:
        mags = np.exp2(rng.choice([-1.0, 1.0], 256) * rng.uniform(150, 300, 256) / abs(p))
    x = np.concatenate([f32(SPECIAL), f32([2, -2, 0.5, -0.5, 3, -3, 1.5, -1.5, 10, -10]), f32(mags),
                        f32(-mags[:64])])
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        q = float(np.float32(p)) * np.log2(np.abs(x.astype(np.float64)))
    return x[~((q > 126) & (q < 130))]


def atan2_probes(seed=0) -> tuple[np.ndarray, np.ndarray]:
    """(a, b) pairs: every pair of special values (signed zeros, infinities, NaN, subnormals, values
    near 2^-100 where the shader rescales), the axes, random points of random magnitudes."""
    special = f32([0.0, -0.0, 1.0, -1.0, 2.5, -0.3, math.inf, -math.inf, math.nan, 1e-40, -1e-40, TINY, -TINY,
                   2.0 ** -100, -(2.0 ** -101), 3e38, -3e38])
    a, b = np.meshgrid(special, special, indexing="ij")
    rng = np.random.default_rng(seed)
    n = 512
    ra = rng.normal(size=n) * 10.0 ** rng.uniform(-30, 30, n)
    rb = rng.normal(size=n) * 10.0 ** rng.uniform(-30, 30, n)
    axis = rng.uniform(-5, 5, 32)
    aa = np.concatenate([a.ravel(), f32(ra), f32(rng.normal(size=n)), f32(axis), np.zeros(32, np.float32)])
    bb = np.concatenate([b.ravel(), f32(rb), f32(rng.normal(size=n)), np.zeros(32, np.float32), f32(axis)])
    return aa, bb


# --- the ops at their special points ------------------------------------------------------------

def test_rounding_and_log_at_special_points(gl):
    """floor, ceil, trunc, round (halves to even), frac exactly; log, log2 under the rule with -inf at
    0, NaN below, +inf at +inf; vec4 blocks and single lanes (width 4 and 3), one program."""
    stepped = {"floor": Floor(), "ceil": Ceil(), "trunc": Trunc(), "round": Round(), "frac": Frac()}
    for width in (4, 3):
        ops = {**stepped, "log": Log(), "log2": Log2()}
        probes = {k: rounding_probes() for k in stepped} | {"log": log_probes(), "log2": log_probes(1)}
        res = evaluate(gl, per_op(ops, width), probes, width)
        for k, (out, ref, x) in res.items():
            assert_matches(out, ref, x, exact=k in stepped, what=f"{k} (width {width})")
    # round is torch's half-to-even: the probes do hold halves that an away-from-zero round would break
    halves = f32([0.5, 1.5, 2.5, -0.5, -2.5])
    assert torch.equal(Round()(torch.from_numpy(halves)), torch.tensor([0.0, 2.0, 2.0, -0.0, -2.0]))


@parity_settings(max_examples=6)
@given(divisors=st.lists(st.one_of(
    st.sampled_from([1.0, -1.0, 0.1, -0.7, 3.0, 0.75, -2.5, 2.0 ** -20, 1e30, 1 / 3]),
    # short mantissas: k c is exact for |k| < 2^13, so the multiples are exact
    st.builds(lambda j, e, s: s * (1 + j / 1024) * 2.0 ** e, st.integers(0, 1023), st.integers(-30, 30),
              st.sampled_from([1.0, -1.0])),
    st.builds(lambda m, e: m * 2.0 ** e, st.floats(-2, 2, width=32).filter(lambda m: abs(m) >= 1), st.integers(-30, 30))),
    min_size=4, max_size=4), width=st.sampled_from([4, 3]))
def test_fmod_and_remainder_exact_at_multiples(gl, divisors, width):
    """Bit-exact (the same value) at exact multiples of the divisor, one ulp either side of them
    (where a quotient rounding across an integer would push a naive result out of its half-open
    range), at +-0 (torch.remainder(-0.0, c) = -0.0), inf and NaN, and at random points. Eight nodes
    in one program (their loops once made llvmpipe's compile time explode); width 3: lanes gathered."""
    ops, probes = {}, {}
    for i, c in enumerate(divisors):
        ops[f"fmod{i}"], ops[f"remainder{i}"] = Fmod(c), Remainder(c)
        probes[f"fmod{i}"] = probes[f"remainder{i}"] = divisor_probes(c, i)
    res = evaluate(gl, per_op(ops, width), probes, width)
    for k, (out, ref, x) in res.items():
        c = ops[k].divisor
        assert_matches(out, ref, x, exact=True, what=f"{k} divisor {c!r}")
        if k.startswith("fmod"):   # the probes did hit exact multiples (k c, k a power of two, at least)
            finite = np.unique(x[np.isfinite(x)]).astype(np.float64)
            assert (np.fmod(finite, c) == 0).sum() >= 8


def test_atan2_at_zeros_axes_and_infinities(gl):
    """torch.atan2 including atan2(+-0, +-0) (0, pi, -pi, -0), the axes, the infinities and NaN; the
    vec4 path (two 4-lane branches) and the lane path (one 6-lane [a | b] input), one program."""
    a, b = atan2_probes()
    n = math.ceil(len(a) / 4) * 4
    a, b = np.resize(a, n), np.resize(b, n)
    g = GraphModule([("a", 4), ("b", 4), ("ab", 6)])
    g.output("y4", g.add("t4", Atan2(), ["a", "b"]))
    g.output("y3", g.add("t3", Atan2(), "ab"))
    rows = n // 4
    x4a, x4b = a.reshape(rows, 4), b.reshape(rows, 4)
    x3 = np.concatenate([a[:rows * 3].reshape(rows, 3), b[:rows * 3].reshape(rows, 3)], 1)
    bundle = g.export("atan2")
    x = np.concatenate([x4a, x4b, x3], 1)
    out, ref = glsl_eval(gl, bundle, x), torch_reference(bundle, x)
    err = assert_matches(out, ref, what="atan2")
    assert err < 5e-7, err     # the helper's accuracy (llvmpipe's own atan(y, x): 3.4e-6)
    exact_pi = np.abs(ref) == np.float32(np.pi)
    assert exact_pi.sum() >= 4 and np.array_equal(out[exact_pi], ref[exact_pi])   # +-pi to the bit


POW_SPECIAL = [0.0, 1.0, 2.0, 3.0, -2.0, 0.5, -0.5, -1.0, 7.0, -3.0, 4.0, -32.0, 32.0, 33.0, -33.0, 40.0, 1e10,
               -1e10, 2.5, -2.5, 1.5, 0.1, 2.0 ** 24 + 2, 1 / 3]


@pytest.mark.parametrize("chunk", range(3))
def test_power_at_special_points(gl, chunk):
    """torch's own paths (p = 0, 1, 2, 3, -2, 0.5, -0.5, -1), integers by repeated squaring, odd and even
    ones past it, huge integers, non-integers: at +-0, subnormals, +-1, +-inf, NaN, negative bases."""
    exps = POW_SPECIAL[chunk * 8:(chunk + 1) * 8]
    ops = {f"p{i}": Power(p) for i, p in enumerate(exps)}
    res = evaluate(gl, per_op(ops, 4), {k: power_probes(ops[k].exponent, i) for i, k in enumerate(ops)}, 4)
    for k, (out, ref, x) in res.items():
        assert_matches(out, ref, x, what=f"power {ops[k].exponent!r}")


@parity_settings(max_examples=5)
@given(exps=st.lists(st.one_of(st.integers(-32, 32).map(float), st.integers(-64, 64).map(lambda k: k / 2),
                               st.floats(-8, 8, width=32)), min_size=8, max_size=8))
def test_power_random_exponents(gl, exps):
    """Exponents inside the envelope (|p| <= POW_EXPONENT), probed as test_power_at_special_points."""
    ops = {f"p{i}": Power(p) for i, p in enumerate(exps)}
    res = evaluate(gl, per_op(ops, 4), {k: power_probes(ops[k].exponent, i) for i, k in enumerate(ops)}, 4)
    for k, (out, ref, x) in res.items():
        assert_matches(out, ref, x, what=f"power {ops[k].exponent!r}")


def test_padding_lanes_stay_finite_before_a_looping_dense(gl):
    """log / log2 / power(p < 0) of a partial vec4 block: padding lanes (0) must not become inf, or a
    dense that multiplies whole blocks (texture and ubo storage loop) turns them into NaN."""
    gen = torch.Generator().manual_seed(0)
    g = GraphModule([("x", 3)])
    for k, comp in (("l", Log()), ("l2", Log2()), ("p", Power(-1.5))):
        d = Dense(3, 6)
        with torch.no_grad():
            d.linear.weight.copy_(torch.rand(6, 3, generator=gen) - 0.5)
        g.output(f"y_{k}", g.add(f"d_{k}", d, g.add(k, comp, "x")))
    bundle = g.export("pad")
    x = uniform_inputs(0, 256, 3, 0.25, 4.0)
    for storage in ("texture", "ubo"):
        check_parity(gl, bundle, x, storage=storage)


# --- inside random graphs -------------------------------------------------------------------------

STEPPED_OPS = {"floor": Floor, "ceil": Ceil, "trunc": Trunc, "round": Round, "frac": Frac}


@st.composite
def op_graphs(draw):
    """x [d] (in [-4, 4]) -> a stepped op of the input -> dense -> a continuous op on a value kept in
    its domain (and small: a dense of large values cancels, the envelope's note) -> dense: a printable recipe. Stepped ops take inputs only: on a computed value one ulp
    across a step moves the output by the step (the envelope's note), on an input both sides agree."""
    return {"d": draw(st.integers(1, 7)), "width": draw(st.integers(1, 9)), "seed": draw(st.integers(0, 2 ** 31 - 1)),
            "stepped": draw(st.sampled_from([*STEPPED_OPS, "fmod", "remainder"])),
            "divisor": draw(st.sampled_from([1.0, -0.75, 0.3, 2.5])),
            "op": draw(st.sampled_from(["log", "log2", "power", "atan2"])),
            "exponent": draw(st.sampled_from([2.2, 1 / 2.4, -1.5, 3.0, -2.0, 0.5, 4.0])),
            "positive_x": draw(st.booleans())}


def build_op_graph(recipe) -> GraphModule:
    gen = torch.Generator().manual_seed(recipe["seed"])
    g = GraphModule([("x", recipe["d"])])
    w = recipe["width"]

    def dense(name, src, out):
        n = g.dim(src)
        layer = Dense(n, out)
        with torch.no_grad():
            layer.linear.weight.copy_((torch.rand(layer.linear.weight.shape, generator=gen) * 2 - 1) / n ** 0.5)
            layer.linear.bias.copy_((torch.rand(layer.linear.bias.shape, generator=gen) * 2 - 1) * 0.5)
        return g.add(name, layer, src)

    s = recipe["stepped"]
    comp = STEPPED_OPS[s]() if s in STEPPED_OPS else (Fmod if s == "fmod" else Remainder)(recipe["divisor"])
    h = dense("l0", g.add("s", comp, "x"), w)
    if recipe["op"] == "atan2":   # kept off the negative x axis (the angle's jump): b > 0 or a > 0
        t = g.add("t", Tanh(), dense("l1", "s", w))
        lifted = g.add("lift", Affine(np.full(w, 0.5), np.full(w, 1.0)), t)    # in [0.5, 1.5]
        pair = [h, lifted] if recipe["positive_x"] else [lifted, h]
        y = g.add("op", Atan2(), pair)
    else:                          # base 1.25 + 0.75 tanh(h) in [0.5, 2]: in the domain, outputs <= 16
        base = g.add("base", Affine(np.full(w, 0.75), np.full(w, 1.25)), g.add("th", Tanh(), h))
        op = {"log": Log(), "log2": Log2(), "power": Power(recipe["exponent"])}[recipe["op"]]
        y = g.add("op", op, base)
    g.output("y", dense("out", y, 5))
    g.output("h", y)
    g.output("s", "s")
    return g


@parity_settings(max_examples=8)
@given(recipe=op_graphs())
def test_ops_in_random_graphs(gl, recipe):
    bundle = build_op_graph(recipe).export("ops")
    x = uniform_inputs(recipe["seed"] + 1, 512, recipe["d"], -4.0, 4.0)
    check_parity(gl, bundle, x, storage="inline", what=str(recipe))
    env = analyse(bundle, {"x": (-4.0, 4.0)})
    assert env.ok, [f.line() for f in env.warnings]


def test_envelope_bounds_hold_on_samples():
    """Every value the twin computes lies inside the interval the envelope gives it."""
    for seed in range(12):
        recipe = {"d": 4, "width": 6, "seed": seed, "stepped": [*STEPPED_OPS, "fmod", "remainder"][seed % 7],
                  "divisor": [1.0, -0.75, 0.3, 2.5][seed % 4], "op": ["log", "log2", "power", "atan2"][seed % 4],
                  "exponent": [2.2, -1.5, 3.0, 0.5, 4.0, -2.0][seed % 6], "positive_x": bool(seed % 3)}
        g = build_op_graph(recipe)
        env = analyse(g.export("ops"), {"x": (-4.0, 4.0)})
        x = torch.from_numpy(uniform_inputs(seed, 4096, 4, -4.0, 4.0))
        values = node_values(g, x)
        for node_id, (lo, hi) in env.intervals.items():
            v = values[node_id].numpy()
            slack = 1e-5 * np.maximum(1, np.maximum(abs(lo), abs(hi)))
            assert (v >= lo - slack).all() and (v <= hi + slack).all(), (recipe, node_id, v.min(), v.max(), lo, hi)


# --- the envelope's findings, the specs -------------------------------------------------------------

def _findings(comp, lo, hi, computed=False):
    g = GraphModule([("x", 2)])
    src = "x"
    if computed:
        d = Dense(2, 2)
        with torch.no_grad():
            d.linear.weight.copy_(torch.eye(2))
            d.linear.bias.zero_()
        src = g.add("d", d, "x")
    g.output("y", g.add("f", comp, src))
    env = analyse(g.export("e"), {"x": (lo, hi)})
    return env, [f.line() for f in env.warnings], [f.line() for f in env.notes]


def test_envelope_domains_and_limits():
    assert _findings(Log(), 0.5, 2.0)[0].ok
    assert any("log2 argument (lowest)" in w for w in _findings(Log2(), 0.0, 2.0)[1])
    assert any("power base (lowest)" in w for w in _findings(Power(2.5), -1.0, 2.0)[1])
    assert _findings(Power(3.0), -2.0, 2.0)[0].ok                        # an integer exponent: any sign
    assert any("includes 0" in w for w in _findings(Power(-2.0), -1.0, 1.0)[1])
    assert _findings(Power(2.5), 0.0, 2.0 ** (POW_ARG / 2.5 - 1))[0].ok
    assert any("p log2|x|" in w for w in _findings(Power(2.5), 0.0, 2.0 ** 30)[1])
    assert any("|p|" in w for w in _findings(Power(40.5), 0.5, 2.0)[1])
    assert _findings(Power(40.0), 0.5, 2.0)[0].ok is False      # 40 > 32: exp2 path, |p| limit
    assert _findings(Power(31.0), 0.5, 2.0)[0].ok               # repeated squaring
    assert any("quotient" in w for w in _findings(Fmod(1e-30), -1e9, 1e9)[1])
    # stepped: exact from an input, a note from a computed argument whose range holds a step
    env, warnings, notes = _findings(Floor(), -2.0, 2.0)
    assert env.ok and not notes
    env, warnings, notes = _findings(Floor(), -2.0, 2.0, computed=True)
    assert env.ok and any("holds an integer" in n for n in notes)
    assert not _findings(Remainder(1.0), 0.25, 0.75, computed=True)[2]   # one piece: no step
    env, _, notes = _findings(Atan2(), -1.0, 1.0, computed=True)
    assert env.ok and any("negative x axis" in n for n in notes)
    # ranges: within one piece the op is x - k c; atan2 off the cut from the corners
    env = _findings(Remainder(-0.75), 1.0, 1.25)[0]
    assert np.allclose(env.intervals["f"][0], 1.0 - 2 * 0.75) and np.allclose(env.intervals["f"][1], 1.25 - 2 * 0.75)
    lo, hi = _findings(Atan2(), 0.5, 1.0)[0].intervals["f"]
    assert np.allclose([lo[0], hi[0]], [math.atan2(0.5, 1.0), math.atan2(1.0, 0.5)])


def test_params_and_twins():
    with pytest.raises(ComponentError, match="param 'divisor' of fmod has an invalid value 0.0"):
        resolve_params("fmod", {"divisor": 0.0})
    for bad in (1e-40, math.inf, 1e39):
        with pytest.raises(ComponentError, match="divisor"):
            resolve_params("remainder", {"divisor": bad})
    with pytest.raises(ComponentError, match="missing param 'exponent'"):
        resolve_params("power", {})
    with pytest.raises(ComponentError, match="exponent"):
        resolve_params("power", {"exponent": math.nan})
    with pytest.raises(ComponentError, match="atan2 cannot take a 5-wide input"):
        check_node("atan2", resolve_params("atan2", {}), 5)
    assert check_node("atan2", {}, 6) == 3
    # parameters travel as the float32 both sides compute with, and survive the bundle
    g = GraphModule([("x", 2)])
    g.output("y", g.add("f", Fmod(0.1), "x"))
    g.output("z", g.add("p", Power(1 / 3), "x"))
    back = GraphModule.from_bundle(g.export("b"))
    assert back.nodes["f"].divisor == float(np.float32(0.1)) and back.nodes["p"].exponent == float(np.float32(1 / 3))
    x = torch.linspace(-7, 7, 101)
    assert torch.equal(Frac()(x), x - torch.trunc(x))
    assert torch.equal(Remainder(-0.75)(x), torch.remainder(x, -0.75))


@pytest.mark.parametrize("target", GL_TARGETS)
def test_helpers_pass_glslang(tmp_path, target):
    """Every new op, both code paths, through the reference compiler for every target."""
    from inshade.shaders import assemble

    validator = shutil.which("glslangValidator")
    assert validator, "glslangValidator not found on PATH: install glslang-tools"
    ops = {"log": Log(), "log2": Log2(), "floor": Floor(), "ceil": Ceil(), "trunc": Trunc(), "round": Round(),
           "frac": Frac(), "fmod": Fmod(0.3), "rem": Remainder(-2.0), "pow": Power(2.5)}
    g = GraphModule([("x", 5), ("a", 4), ("b", 4)])
    for k, comp in ops.items():
        g.add(k, comp, "x")
    g.add("at", Atan2(), ["a", "b"])
    g.output("y", g.add("cat", Affine(np.ones(5 * len(ops) + 4), np.zeros(5 * len(ops) + 4)), [*ops, "at"]))
    gen = generate(g.export("all"), target=target)
    frag = assemble("passes/evaluate.frag", version=target, chunks={"network": gen.chunk})
    path = tmp_path / f"ops-{target}.frag"
    path.write_text(frag.source)
    proc = subprocess.run([validator, str(path)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
