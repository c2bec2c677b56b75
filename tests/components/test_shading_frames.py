"""Learned shading frames (components/shading_frames/torch_twin.py, components/shading_frames/emit.py): GLSL parity, an
independent numpy reference, the guard at zero vectors, and a whole neural-appearance graph
(latent pyramid -> frames -> decoder -> expm1, and the sampler -> proxy_params) through codegen.

Tolerance: the parity rule of tests/parity.py. Rows whose frame has |n x t| < 0.05 are left out
of the random inputs: b = normalize(n x t) divides the fp32 rounding of n x t (~1e-7) by |n x t|,
so near-parallel n and t are ill-conditioned on any executor (the zero-vector guard itself is
tested separately, where the result is exactly defined).
"""
from __future__ import annotations

import numpy as np
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.components import check_node, resolve_params
from inshade.components.elementwise.torch_twin import Expm1, ReLU
from inshade.components.latent_pyramid.torch_twin import LatentPyramid
from inshade.components.proxy_params.torch_twin import ProxyParams
from inshade.components.shading_frames.torch_twin import ShadingFrames
from inshade.models import GraphModule

from parity import assert_parity, check_parity, parity_settings, torch_reference, unit_directions


def make_frames(latent, frames, seed) -> ShadingFrames:
    m = ShadingFrames(latent, frames)
    gen = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        m.linear.weight.copy_(torch.randn(m.linear.weight.shape, generator=gen))
        m.linear.bias.copy_(torch.randn(m.linear.bias.shape, generator=gen))
    return m


def numpy_frames(w, b, x, latent, frames):
    """Independent reference: Eq. 7 written out with numpy, float64."""
    x = x.astype(np.float64)
    z, l, v = x[:, :latent], x[:, latent:latent + 3], x[:, latent + 3:latent + 6]
    lin = z @ w.T.astype(np.float64) + b
    out = []
    norm = lambda a: a / np.sqrt(np.maximum((a * a).sum(1, keepdims=True), 1e-12))  # noqa: E731
    for k in range(frames):
        n, t = norm(lin[:, 6 * k:6 * k + 3]), norm(lin[:, 6 * k + 3:6 * k + 6])
        bt = norm(np.cross(n, t))
        out += [(t * l).sum(1), (bt * l).sum(1), (n * l).sum(1), (t * v).sum(1), (bt * v).sum(1), (n * v).sum(1)]
    return np.stack(out, 1)


def frame_inputs(m: ShadingFrames, seed: int, n: int) -> np.ndarray:
    """[z in [-1, 1], unit light, view (half of them scaled: the layer does not normalise them)],
    without rows whose frames are near-degenerate (module docstring)."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(-1, 1, (n, m.latent))
    l, v = unit_directions(seed + 1, n), unit_directions(seed + 2, n)
    v[: n // 2] *= rng.uniform(0.1, 3.0, (n // 2, 1))
    x = np.concatenate([z, l, v], 1).astype(np.float32)
    with torch.no_grad():
        nrm, t, _ = m.frames_of(torch.from_numpy(x[:, :m.latent]))
    keep = torch.linalg.cross(nrm, t).norm(dim=-1).min(-1).values.numpy() >= 0.05
    return x[keep]


@given(latent=st.integers(1, 12), frames=st.integers(1, 3), seed=st.integers(0, 2**31 - 1))
@parity_settings(8)
def test_parity(gl, latent, frames, seed):
    m = make_frames(latent, frames, seed)
    g = GraphModule([("z", latent), ("light", 3), ("view", 3)])
    g.add("sf", m, ["z", "light", "view"])
    g.output("y", "sf")
    bundle = g.export("frames")
    x = frame_inputs(m, seed, 300)
    assert x.shape[0] > 100
    ref = torch_reference(bundle, x)
    assert_parity(ref, numpy_frames(bundle.tensors["sf.weight"], bundle.tensors["sf.bias"], x, latent, frames),
                  what="torch twin vs numpy reference")
    check_parity(gl, bundle, x, reference=ref, what=f"shading_frames latent={latent} frames={frames}")


def test_zero_vectors_are_guarded(gl):
    """n = 0 (zero weights and bias) and n parallel to t: the guard gives 0, never NaN."""
    m = ShadingFrames(4, 2)
    with torch.no_grad():
        m.linear.weight.zero_()
        m.linear.bias.copy_(torch.tensor([0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 2.0]))
    g = GraphModule([("x", 10)])
    g.add("sf", m, "x")
    g.output("y", "sf")
    x = np.concatenate([np.zeros((4, 4)), unit_directions(0, 4), unit_directions(1, 4)], 1).astype(np.float32)
    ref = torch_reference(g.export("f"), x)
    assert np.isfinite(ref).all()
    # frame 0: n = 0 -> n.l = n.v = 0 and b = 0; frame 1: n = t = z -> b = 0
    assert np.array_equal(ref[:, [1, 2, 4, 5, 7, 10]], np.zeros((4, 6), np.float32))
    np.testing.assert_allclose(ref[:, 0], x[:, 4], atol=1e-7)   # t = +x: t.l = l.x
    check_parity(gl, g.export("f"), x, reference=ref, what="guarded frames")


def test_spec_and_gradients():
    p = resolve_params("shading_frames", {})
    assert p == {"frames": 2, "latent": 8} and check_node("shading_frames", p, 14) == 12
    m = make_frames(8, 2, 0)
    x = torch.from_numpy(frame_inputs(m, 0, 64))
    m(x).square().sum().backward()
    assert torch.isfinite(m.linear.weight.grad).all() and m.linear.weight.grad.abs().sum() > 0


def test_neural_appearance_graph(gl):
    """The paper's model as one bundle: latent pyramid -> shading frames -> decoder -> expm1 (the
    BRDF from log(1 + f)), and [z, light] -> sampler -> proxy_params."""
    torch.manual_seed(0)
    g = GraphModule([("uvl", 3), ("light", 3), ("view", 3)])
    g.add("lat", LatentPyramid(16, 5, 8, "f16", scale=0.5, seed=4), "uvl")
    g.add("frames", make_frames(8, 2, 5), ["lat", "light", "view"])
    g.dense("d0", ["lat", "frames"], 16)
    g.add("a0", ReLU(), "d0")
    g.dense("d1", "a0", 3)
    g.add("brdf", Expm1(), "d1")
    g.dense("s0", ["lat", "light"], 12)
    g.add("sa0", ReLU(), "s0")
    g.dense("s1", "sa0", 9)
    g.add("proxy", ProxyParams(), "s1")
    g.output("brdf", "brdf")
    g.output("proxy", "proxy")
    bundle = g.export("neural_appearance_test")
    rng = np.random.default_rng(1)
    n = 400
    x = np.concatenate([rng.uniform(-0.5, 1.5, (n, 2)), rng.uniform(0, 5, (n, 1)),
                        unit_directions(2, n), unit_directions(3, n)], 1).astype(np.float32)
    module = GraphModule.from_bundle(bundle)
    with torch.no_grad():
        z = module.nodes["lat"](torch.from_numpy(x[:, :3]))
        nrm, t, _ = module.nodes["frames"].frames_of(z)
    x = x[torch.linalg.cross(nrm, t).norm(dim=-1).min(-1).values.numpy() >= 0.05]
    assert bundle.out_dim == 12
    check_parity(gl, bundle, x, what="neural appearance graph")
