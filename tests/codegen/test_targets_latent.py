"""The neural-appearance components -- latent pyramid, shading frames, proxy_params -- on every shading
language beside OpenGL's GLSL (WGSL, Vulkan GLSL, HLSL, Slang: SPIR-V on wgpu over this machine's Vulkan
device), held to the rules of their GL tests (tests/components/test_latent_pyramid.py,
test_shading_frames.py, test_proxy_lobe.py), and the shipped neural-appearance bundles on every target."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.bundle import load
from inshade.codegen import generate
from inshade.components.elementwise.torch_twin import Expm1
from inshade.components.proxy_params.torch_twin import ProxyParams
from inshade.components.shading_frames.torch_twin import ShadingFrames
from inshade.models import GraphModule
from inshade.runtime.compute import TARGETS, run_target
from parity import assert_parity, parity_settings, torch_reference, unit_directions
from test_latent_pyramid import fast_bound, pyramid_graph, pyramid_inputs
from test_shading_frames import frame_inputs, make_frames

REPO = Path(__file__).resolve().parents[2]
SHIPPED = sorted((REPO / "trained").glob("neural_appearance_*/*/bundle.json"))
LATENT_FILTERS = ("exact", "fast")

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def evaluate(gen, x, target):
    return run_target(gen, x, target)[0]


# --- latent pyramid ---------------------------------------------------------------------------------

def _pyramid_case_and_inputs(case, seed):
    bundle = pyramid_graph(case).export("latent")
    return bundle, pyramid_inputs(seed, 200, case["res"], case["levels"])


def assert_latent(out, ref, bundle, x, latent_filter, what):
    if latent_filter == "exact":
        assert_parity(out, ref, what=what)
        return
    ratio = float((np.abs(out.astype(np.float64) - ref) / fast_bound(bundle, x, ref)).max())
    assert ratio <= 1.0, f"{what}: the fast path exceeds test_latent_pyramid.fast_bound: err / bound = {ratio:.3f}"


@st.composite
def pyramid_cases(draw):
    res = draw(st.sampled_from([1, 2, 4, 8, 16]))
    return dict(res=res, levels=draw(st.integers(1, res.bit_length())), channels=draw(st.sampled_from([4, 8])),
                precision=draw(st.sampled_from(["f16", "f32", "u8"])), seed=draw(st.integers(0, 2**31 - 1)))


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("latent_filter", LATENT_FILTERS)
@parity_settings(max_examples=3)
@given(case=pyramid_cases())
def test_latent_pyramid_parity(target, latent_filter, case):
    """uv past [0, 1] (repeat), levels past both ends (floor + clamp), texel centres and edges."""
    bundle, x = _pyramid_case_and_inputs(case, case["seed"] + 1)
    out = evaluate(generate(bundle, target=target, options={"latent_pyramid": {"filter": latent_filter}}), x, target)
    if out is not None:
        assert_latent(out, torch_reference(bundle, x), bundle, x, latent_filter, f"{target} {latent_filter} {case}")


# --- shading frames -----------------------------------------------------------------------------------

def _frames_bundle(m):
    g = GraphModule([("z", m.latent), ("light", 3), ("view", 3)])
    g.add("sf", m, ["z", "light", "view"])
    g.output("y", "sf")
    return g.export("frames")


@pytest.mark.parametrize("target", TARGETS)
@parity_settings(max_examples=3)
@given(latent=st.integers(1, 12), frames=st.integers(1, 3), seed=st.integers(0, 2**31 - 1))
def test_shading_frames_parity(target, latent, frames, seed):
    """Random layers, unit lights, views of other lengths; rows with near-parallel n and t left out, as in
    the GL test (b = normalize(n x t) is ill-conditioned there on any executor)."""
    m = make_frames(latent, frames, seed)
    bundle, x = _frames_bundle(m), frame_inputs(m, seed, 200)
    out = evaluate(generate(bundle, target=target), x, target)
    assert_parity(out, torch_reference(bundle, x), what=f"{target} shading_frames latent={latent} frames={frames}")


@pytest.mark.parametrize("target", TARGETS)
def test_shading_frames_guard_zero_vectors(target):
    """n = 0 and n parallel to t: the guarded normalise gives 0, never NaN, on every target."""
    m = ShadingFrames(4, 2)
    with torch.no_grad():
        m.linear.weight.zero_()
        m.linear.bias.copy_(torch.tensor([0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 2.0]))
    bundle = _frames_bundle(m)
    x = np.concatenate([np.zeros((4, 4)), unit_directions(0, 4), unit_directions(1, 4)], 1).astype(np.float32)
    out = evaluate(generate(bundle, target=target), x, target)
    assert np.array_equal(out[:, [1, 2, 4, 5, 7, 10]], np.zeros((4, 6), np.float32))
    assert_parity(out, torch_reference(bundle, x), what=f"{target} guarded frames")


# --- proxy_params -------------------------------------------------------------------------------------

@pytest.mark.parametrize("target", TARGETS)
@parity_settings(max_examples=3)
@given(iso=st.booleans(), alpha_min=st.sampled_from([0.01, 0.05, 0.3]), seed=st.integers(0, 2**31 - 1))
def test_proxy_params_parity(target, iso, alpha_min, seed):
    """proxy_params (and expm1 behind it): raw lanes across both branches of the quadratic tanh (|x| < 2
    and beyond, and at 2 itself) and logit gaps that saturate the softmax to 0 / 1."""
    width = 3 if iso else 9
    g = GraphModule([("raw", width)])
    g.add("pp", ProxyParams(iso, alpha_min), "raw")
    g.add("e", Expm1(), "pp")
    g.output("params", "pp")
    g.output("e", "e")
    bundle = g.export("proxy")
    x = np.random.default_rng(seed).uniform(-5.0, 5.0, (160, width)).astype(np.float32)
    x[:8, :2] = [[40, -40], [-40, 40], [0, 0], [2, 2], [1e-3, 0], [3, -1], [-2, 2], [2, -2]]
    x[:8, 2] = [2.0, -2.0, 1.999, -1.999, 0.0, 4.0, -4.0, 0.5]
    out = evaluate(generate(bundle, target=target), x, target)
    assert_parity(out, torch_reference(bundle, x), what=f"{target} proxy_params isotropic={iso}")


# --- the shipped neural-appearance bundles --------------------------------------------------------------

def _latents(material: Path, uvl: np.ndarray) -> np.ndarray:
    return torch_reference(load(material / "latents" / "bundle.json"), uvl)


def shipped_inputs(path: Path, n: int) -> np.ndarray:
    """What the technique feeds each bundle: (u, v, level) past both ends for the latents; the material's
    own latents at random texels with unit light and view directions for the decoders and samplers (rows
    whose shading frame is near-degenerate left out, as in the GL test)."""
    rng = np.random.default_rng(7)
    uvl = np.stack([rng.uniform(-0.5, 1.5, n), rng.uniform(-0.5, 1.5, n), rng.uniform(-1.0, 11.0, n)], 1)
    uvl = uvl.astype(np.float32)
    if path.parent.name == "latents":
        return uvl
    bundle = load(path)
    z = _latents(path.parent.parent, uvl)
    dirs = [unit_directions(8 + i, n) for i in range(len(bundle.inputs) - 1)]
    x = np.concatenate([z, *dirs], 1).astype(np.float32)
    frames = [m for m in GraphModule.from_bundle(bundle).nodes.values() if isinstance(m, ShadingFrames)]
    for m in frames:
        with torch.no_grad():
            nrm, t, _ = m.frames_of(torch.from_numpy(z))
        x = x[torch.linalg.cross(nrm, t).norm(dim=-1).min(-1).values.numpy() >= 0.05]
    return x


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: f"{p.parent.parent.name}/{p.parent.name}")
def test_the_shipped_neural_appearance_bundles_on_every_target(target, path):
    bundle = load(path)
    x = shipped_inputs(path, 128)
    ref = torch_reference(bundle, x)
    for latent_filter in LATENT_FILTERS if path.parent.name == "latents" else ("exact",):
        gen = generate(bundle, target=target, options={"latent_pyramid": {"filter": latent_filter}})
        out = evaluate(gen, x, target)
        if out is not None:
            assert_latent(out, ref, bundle, x, latent_filter, f"{target} {latent_filter} {path.parent}")
