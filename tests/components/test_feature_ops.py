"""The feature-axis components an imported network needs (components/feature_axis/spec.py: affine, select,
sub / mul / div, reduce, layer_norm, where; sqrt, reciprocal): torch twin (components/feature_axis/torch_twin.py,
components/elementwise/torch_twin.py) against the GLSL (components/feature_axis/emit.py)
through the driver, under the parity rule (tests/parity.py), on random graphs that mix them with
dense layers; their envelope rules (inshade/envelope.py) bound what the twin computes."""
from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.components import REDUCE_OPS, ComponentError, check_node, resolve_params
from inshade.components.dense.torch_twin import Dense
from inshade.components.elementwise.torch_twin import Reciprocal, Sqrt
from inshade.components.feature_axis.torch_twin import Affine, Div, LayerNorm, Mul, Reduce, Select, Sub, Where
from inshade.envelope import analyse
from inshade.models import GraphModule

from parity import check_parity, node_values, parity_settings, torch_reference, uniform_inputs

N = 512


@st.composite
def feature_graphs(draw):
    """x [d] -> dense -> one of the feature ops (several in a chain) -> dense: a printable recipe."""
    d = draw(st.integers(1, 9))
    steps = draw(st.lists(st.sampled_from(["affine", "select", "sub", "mul", "div", "reduce", "layer_norm",
                                           "where", "sqrt", "reciprocal"]), min_size=1, max_size=4))
    widths = [draw(st.integers(1, 13)) for _ in steps]
    return {"d": d, "steps": steps, "widths": widths, "seed": draw(st.integers(0, 2 ** 31 - 1)),
            "reduce": draw(st.sampled_from(REDUCE_OPS)), "where": draw(st.sampled_from(["gt", "ge", "lt", "le"])),
            "affine_ln": draw(st.booleans())}


def build(recipe) -> GraphModule:
    gen = torch.Generator().manual_seed(recipe["seed"])
    rng = np.random.default_rng(recipe["seed"])
    g = GraphModule([("x", recipe["d"])])
    src = "x"

    def dense(name, src, out):
        """torch.nn.Linear's scale: values stay O(1), inside the envelope (no cancellation of large sums)."""
        n = g.dim(src) if isinstance(src, str) else sum(g.dim(s) for s in src)
        layer = Dense(n, out)
        with torch.no_grad():
            layer.linear.weight.copy_((torch.rand(layer.linear.weight.shape, generator=gen) * 2 - 1) / n ** 0.5)
            layer.linear.bias.copy_((torch.rand(layer.linear.bias.shape, generator=gen) * 2 - 1) * 0.5)
        return g.add(name, layer, src)

    for i, (step, w) in enumerate(zip(recipe["steps"], recipe["widths"])):
        h = dense(f"l{i}", src, w)
        if step == "affine":
            src = g.add(f"f{i}", Affine(rng.uniform(-1.5, 1.5, w), rng.uniform(-0.5, 0.5, w)), h)
        elif step == "select":
            lanes = rng.integers(0, w, rng.integers(1, 2 * w + 1)).tolist()
            src = g.add(f"f{i}", Select(lanes), h)
        elif step in ("sub", "mul", "div"):
            h2 = dense(f"m{i}", src, w)
            if step == "div":   # a divisor bounded away from 0
                h2 = g.add(f"p{i}", Affine(np.full(w, 0.25), np.full(w, 2.0)), h2)
            src = g.add(f"f{i}", {"sub": Sub, "mul": Mul, "div": Div}[step](), [h, h2])
        elif step == "reduce":
            groups = int(rng.choice([k for k in range(1, w + 1) if w % k == 0]))
            src = g.add(f"f{i}", Reduce(recipe["reduce"], groups), h)
        elif step == "layer_norm":
            # offsets spread within each run keep its variance away from 0, where LayerNorm amplifies an
            # ulp of its input by up to 1 / sqrt(eps) (the envelope's note): a conditioning limit of fp32
            groups = int(rng.choice([k for k in range(1, w + 1) if w % k == 0]))
            size = w // groups
            h = g.add(f"s{i}", Affine(np.ones(w), np.tile(np.linspace(-4, 4, size) if size > 1 else [0.0], groups)), h)
            weight, bias = ((rng.uniform(-2, 2, size), rng.uniform(-1, 1, size)) if recipe["affine_ln"]
                            else (None, None))
            src = g.add(f"f{i}", LayerNorm(size, 1e-5, groups, weight, bias), h)
        elif step == "where":
            parts = [h] + [dense(f"m{i}_{k}", src, w) for k in range(3)]
            src = g.add(f"f{i}", Where(recipe["where"]), parts)
        elif step == "sqrt":   # of a positive value: 0.5 + h^2 through mul
            sq = g.add(f"q{i}", Mul(), [h, h])
            src = g.add(f"f{i}", Sqrt(), g.add(f"p{i}", Affine(np.ones(w), np.full(w, 0.5)), sq))
        else:                  # reciprocal of a value in [1, 3]
            src = g.add(f"f{i}", Reciprocal(), g.add(f"p{i}", Affine(np.full(w, 0.5), np.full(w, 2.0)),
                                                     g.add(f"t{i}", torch_tanh(), h)))
    g.output("y", dense("out", src, 5))
    g.output("h", src)
    return g


def torch_tanh():
    from inshade.components.elementwise.torch_twin import Tanh
    return Tanh()


@parity_settings(max_examples=25)
@given(recipe=feature_graphs())
def test_feature_ops_parity(gl, recipe):
    bundle = build(recipe).export("ops")
    x = uniform_inputs(recipe["seed"] + 1, N, recipe["d"])
    check_parity(gl, bundle, x, storage="inline", what=str(recipe))


@pytest.mark.parametrize("storage", ["ubo", "texture"])
def test_feature_ops_with_other_weight_storage(gl, storage):
    recipe = {"d": 5, "steps": ["layer_norm", "where", "select", "div", "reduce", "affine"],
              "widths": [12, 7, 9, 6, 8, 3], "seed": 11, "reduce": "norm", "where": "ge", "affine_ln": True}
    bundle = build(recipe).export("ops")
    check_parity(gl, bundle, uniform_inputs(3, N, 5), storage=storage)


def test_envelope_bounds_hold_on_samples():
    """Every value the twin computes lies inside the interval the envelope gives it."""
    for seed in range(6):
        recipe = {"d": 4, "steps": ["affine", "select", "sub", "mul", "div", "reduce", "layer_norm", "where",
                                    "sqrt", "reciprocal"], "widths": [6, 5, 8, 4, 6, 6, 8, 3, 4, 5], "seed": seed,
                  "reduce": REDUCE_OPS[seed % len(REDUCE_OPS)], "where": "lt", "affine_ln": bool(seed % 2)}
        g = build(recipe)
        bundle = g.export("ops")
        env = analyse(bundle)
        x = torch.from_numpy(uniform_inputs(seed, 4096, 4))
        values = node_values(g, x)
        for node_id, (lo, hi) in env.intervals.items():
            v = values[node_id].numpy()
            assert (v >= lo - 1e-5 * np.maximum(1, abs(lo))).all() and (v <= hi + 1e-5 * np.maximum(1, abs(hi))).all(), \
                (seed, node_id, float(v.min()), float(v.max()), lo.min(), hi.max())


def test_select_of_a_contiguous_run_is_a_view_not_a_copy():
    from inshade.codegen import generate

    g = GraphModule([("x", 8)])
    g.add("s", Select([2, 3, 4]), "x")
    g.output("y", "s")
    chunk = generate(g.export("v")).chunk
    assert "v_s" not in chunk        # the output reads x's lanes directly


def test_bad_params_are_one_error():
    with pytest.raises(ComponentError, match="select: lane 8 is not in 0..7"):
        check_node("select", resolve_params("select", {"lanes": [1, 8]}), 8)
    with pytest.raises(ComponentError, match="groups: 3 does not divide the input width 8"):
        check_node("reduce", resolve_params("reduce", {"op": "sum", "groups": 3}), 8)
    with pytest.raises(ComponentError, match="invalid value 'median'"):
        resolve_params("reduce", {"op": "median"})
    with pytest.raises(ComponentError, match="clamp: needs min, max or both"):
        check_node("clamp", resolve_params("clamp", {}), 4)
    with pytest.raises(ComponentError, match="where cannot take a 6-wide input"):
        check_node("where", resolve_params("where", {"op": "gt"}), 6)


def test_softplus_without_parameters_keeps_the_stable_form():
    """Bundles written before beta/threshold existed: the same function as before."""
    from inshade.components.elementwise.torch_twin import Softplus

    x = torch.linspace(-30, 30, 301)
    assert torch.equal(Softplus()(x), torch.clamp_min(x, 0) + torch.log1p(torch.exp(-x.abs())))
    ref = torch.nn.functional.softplus(x, 2.0, 20.0)
    assert torch.equal(Softplus(2.0, 20.0)(x), ref)


def test_twins_match_torch_functions():
    x = torch.randn(64, 12)
    assert torch.equal(Reduce("norm", 3)(x), torch.linalg.vector_norm(x.reshape(64, 3, 4), dim=-1))
    assert torch.equal(Reduce("mean", 2)(x), x.reshape(64, 2, 6).mean(-1))
    ln = torch.nn.LayerNorm(6)
    with torch.no_grad():
        ln.weight.uniform_(-1, 1)
        ln.bias.uniform_(-1, 1)
    ours = LayerNorm(6, ln.eps, 2, ln.weight.detach().numpy(), ln.bias.detach().numpy())
    assert torch.allclose(ours(x), ln(x.reshape(64, 2, 6)).reshape(64, 12), atol=1e-6)
    assert torch_reference is not None
