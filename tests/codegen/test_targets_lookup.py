"""Differentiable Indirection arrays on every shading language beside OpenGL's GLSL, through the real
driver (runtime.compute on this machine's Vulkan device): the exact path under tests/parity.py's rule,
the fast (hardware-filtered) path under the bound tests/components/test_lookup_array.py states and
measures for GL, every layout the limits can ask for (4D folded, wrapped into rows), and every
shipped network that reads lookup arrays."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given

from inshade.bundle import load
from inshade.codegen import generate
from inshade.codegen.registry import LOWERED
from inshade.runtime.compute import TARGETS, run_target
from parity import assert_parity, parity_settings, torch_reference, uniform_inputs
from test_lookup_array import fast_path_bound, lut_cases, lut_graph, lut_inputs

REPO = Path(__file__).resolve().parents[2]
DRIVEN = TARGETS

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _check(bundle, x, target, lut_filter, what, **gen):
    out = run_target(generate(bundle, target=target, lut_filter=lut_filter, **gen), x, target)[0]
    exact = torch_reference(bundle, x)
    if lut_filter == "exact":
        return assert_parity(out, exact, what=what)
    bound = fast_path_bound(bundle, "lut", exact)
    excess = np.abs(out - exact) - bound
    assert excess.max() <= 0, f"{what}: |fast - exact| past the bound by {excess.max():.3g}"
    return float(np.abs(out - exact).max())


@pytest.mark.parametrize("target", DRIVEN)
@pytest.mark.parametrize("lut_filter", ["exact", "fast"])
@parity_settings(max_examples=8)
@given(case=lut_cases())
def test_lookup_arrays_on_every_target(target, lut_filter, case):
    bundle = lut_graph(case).export("lut")
    d = len(case["res"])
    _check(bundle, lut_inputs(case["seed"], 256, d, case["res"]), target, lut_filter, f"{target} {lut_filter} {case}")


@pytest.mark.parametrize("target", DRIVEN)
@pytest.mark.parametrize("res, lut_filter, limits, layout", [
    ([3, 2, 3, 4], "exact", {"GL_MAX_3D_TEXTURE_SIZE": 8}, "fold"),
    ([3, 2, 3, 4], "fast", {"GL_MAX_3D_TEXTURE_SIZE": 8}, "fold"),
    ([6, 5, 6], "exact", {"GL_MAX_3D_TEXTURE_SIZE": 4, "GL_MAX_TEXTURE_SIZE": 64}, "wrap"),
    ([9, 7], "exact", {"GL_MAX_TEXTURE_SIZE": 8}, "wrap"),
    ([3, 3, 2, 3], "exact", {"GL_MAX_3D_TEXTURE_SIZE": 2, "GL_MAX_TEXTURE_SIZE": 32}, "wrap"),
])
def test_layouts_the_limits_ask_for(target, res, lut_filter, limits, layout):
    """A caller's limits (a small device's) fold a 4D array's blocks along another axis or wrap the cells
    into rows of a 2D texture: the same values on every target."""
    case = dict(res=res, channels=5, bits=16, nonlinearity="none", seed=11)
    bundle = lut_graph(case).export("lut")
    gen = generate(bundle, target=target, lut_filter=lut_filter, limits=limits)
    assert f"({layout})" in gen.plan.rows[0].storage
    _check(bundle, lut_inputs(3, 300, len(res), res), target, lut_filter, f"{target} {layout} {res}", limits=limits)


def _shipped_with_lookups():
    found = []
    for path in sorted((REPO / "trained").rglob("bundle.json")):
        bundle = load(path)
        types = {n.type for n in bundle.nodes}
        if "lookup_array" in types and types <= LOWERED:
            found.append(path.parent)
    return found


SHIPPED = _shipped_with_lookups()


def test_the_shipped_lookup_networks_are_found():
    assert len(SHIPPED) >= 15, [str(p.relative_to(REPO)) for p in SHIPPED]


@pytest.mark.parametrize("folder", SHIPPED, ids=lambda p: str(p.relative_to(REPO / "trained")))
def test_shipped_lookup_networks_on_every_target(folder):
    """Each shipped network reading lookup arrays, 128 points in [0, 1] (the arrays' domain; beyond it they
    clamp) on every driven target, exact path."""
    bundle = load(folder)
    x = uniform_inputs(5, 128, bundle.in_dim, 0.0, 1.0)
    ref = torch_reference(bundle, x)
    for target in DRIVEN:
        out = run_target(generate(bundle, target=target), x, target)[0]
        assert_parity(out, ref, what=f"{target} {folder.name}")


def test_more_textures_than_a_stage_binds_are_refused_naming_the_limit():
    """Six 9-channel arrays read 18 textures: past WebGPU's 16 sampled textures per stage, within D3D11's 128."""
    from inshade.codegen.limits import LimitError
    from inshade.models import GraphModule
    from test_lookup_array import make_lut

    g = GraphModule([("uv", 2)])
    for i in range(6):
        g.add(f"lut{i}", make_lut([4, 4], 9, 8, seed=i), "uv")
    for i in range(6):
        g.output(f"y{i}", f"lut{i}")
    bundle = g.export("luts")
    with pytest.raises(LimitError, match="needs samplers 18; GL_MAX_TEXTURE_IMAGE_UNITS is 16 "
                                         r"\(WebGPU default maxSampledTexturesPerShaderStage\)"):
        generate(bundle, target="wgsl")
    x = lut_inputs(2, 64, 2, [4, 4])
    assert_parity(run_target(generate(bundle, target="hlsl"), x, "hlsl")[0], torch_reference(bundle, x), what="hlsl")


def test_a_texture_past_the_targets_side_is_wrapped_or_refused():
    """A 9000-cell 1D array: past WebGPU's 8192-texel side, wrapped into rows on the exact path; the fast path
    filters in hardware and is refused in one line naming the limit."""
    from inshade.codegen.limits import LimitError

    bundle = lut_graph(dict(res=[9000], channels=2, bits=32, nonlinearity="none", seed=4)).export("long")
    with pytest.raises(LimitError, match="GL_MAX_TEXTURE_SIZE is 8192 \\(WebGPU default maxTextureDimension2D\\)"):
        generate(bundle, target="wgsl", lut_filter="fast")
    gen = generate(bundle, target="wgsl")
    assert "(wrap)" in gen.plan.rows[0].storage
    x = lut_inputs(6, 256, 1, [9000])
    assert_parity(run_target(gen, x, "wgsl")[0], torch_reference(bundle, x), what="wgsl wrapped")
