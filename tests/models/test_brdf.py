"""Analytic BRDFs: GLSL (shaders/lib/brdf.glsl through passes/brdf_eval_test.frag) vs torch
(models/brdf.py) at random inputs, the paper's albedo factorisation, reference values.

Tolerance: the parity rule of tests/parity.py, |glsl - torch| <= 1e-5 max(1, |torch|) (both
float32, same operation order; the driver's sqrt/inversesqrt/log and division differ by ulps), except
GGX's D near its peak, whose condition number is stated next to its check.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.models import brdf
from parity import parity_settings, run_sample_pass


def _glsl_eval(gl, l, v, base, params, nh, alpha):
    rows = np.zeros((l.shape[0], 24), np.float32)
    rows[:, 0:3], rows[:, 3:6], rows[:, 6:9], rows[:, 9:19] = l, v, base, params
    rows[:, 20], rows[:, 21] = nh, alpha
    return run_sample_pass(gl, "passes/brdf_eval_test.frag", rows, 6)[0]


def _random_inputs(seed: int, n: int):
    gen = torch.Generator().manual_seed(seed)
    l = brdf.uniform_hemisphere(n, gen, min_cos=0.05)
    v = brdf.uniform_hemisphere(n, gen, min_cos=0.05)
    base = torch.rand(n, 3, generator=gen) * 0.95 + 0.05
    params = torch.rand(n, len(brdf.PARAMS), generator=gen)
    params[:, 0] = params[:, 0] * 0.9 + 0.1   # roughness >= 0.1 keeps D within float32's comfort
    nh = torch.rand(n, generator=gen)
    alpha = torch.rand(n, generator=gen) * 0.95 + 0.05
    return l, v, base, params, nh, alpha


@parity_settings(max_examples=3)
@given(seed=st.integers(0, 2 ** 31 - 1))
def test_disney_and_ggx_parity(gl, seed):
    l, v, base, params, nh, alpha = _random_inputs(seed, 512)
    out = _glsl_eval(gl, l.numpy(), v.numpy(), base.numpy(), params.numpy(), nh.numpy(), alpha.numpy())
    with torch.no_grad():
        ref = brdf.disney(l, v, base, params).numpy()
        d = brdf.ggx_d(nh, alpha).numpy()
    # The clearcoat lobe has the same peak cancellation as GGX (t_c = 1 + (a_g^2 - 1) n.h^2 ~ a_g^2,
    # a_g <= 0.1): its share of the value gets the same few-ulps-over-t_c allowance.
    with torch.no_grad():
        lobes = brdf.disney_lobes(l, v, params)
        clear = (0.25 * params[:, brdf.PARAMS.index("clearcoat")] * lobes["clear"]).double().numpy()
    g = params[:, brdf.PARAMS.index("clearcoat_gloss")].double().numpy()
    ag2 = ((1.0 - g) * 0.1 + g * 0.001) ** 2
    h = brdf.half_vector(l.double(), v.double())[:, 2].numpy()
    tc = 1.0 + (ag2 - 1.0) * h ** 2
    rel = np.abs(out[:, :3].astype(np.float64) - ref) / np.maximum(1.0, np.abs(ref))
    bound = 1e-5 + 8.0 * 2.0 ** -23 * np.abs(clear)[:, None] / (tc[:, None] * np.maximum(1.0, np.abs(ref)))
    worst = np.unravel_index(np.argmax(rel / bound), rel.shape)
    assert np.all(rel <= bound), f"disney_brdf: scaled error {rel[worst]:.3g} > bound {bound[worst]:.3g} at {worst}"
    # GGX near its peak is ill-conditioned: t = 1 + (a^4 - 1) n.h^2 cancels to ~a^4, so the one
    # rounding (or FMA contraction) of (a^4 - 1) n.h^2 (~2^-24 absolute) becomes 2^-24 / t relative
    # in t and twice that in D ~ 1 / t^2. Bound: 1e-5 + 8 * 2^-23 / t (a few ulps, relative).
    a4 = alpha.double().numpy() ** 4
    t = 1.0 + (a4 - 1.0) * nh.double().numpy() ** 2
    rel = np.abs(out[:, 3].astype(np.float64) - d) / np.maximum(1.0, np.abs(d))
    bound = 1e-5 + 8.0 * 2.0 ** -23 / t
    worst = int(np.argmax(rel / bound))
    assert np.all(rel <= bound), (f"ggx: scaled error {rel[worst]:.3g} > bound {bound[worst]:.3g} at "
                                  f"n.h={float(nh[worst])}, alpha={float(alpha[worst])}")


def test_below_horizon_is_zero(gl):
    l = np.array([[0.0, 0.6, -0.8], [0.0, 0.6, 0.8]], np.float32)
    v = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, -0.8]], np.float32)
    base = np.full((2, 3), 0.5, np.float32)
    params = np.full((2, 10), 0.5, np.float32)
    out = _glsl_eval(gl, l, v, base, params, np.zeros(2, np.float32), np.ones(2, np.float32))
    assert np.all(out[:, :3] == 0.0)
    ref = brdf.disney(torch.from_numpy(l), torch.from_numpy(v), torch.from_numpy(base), torch.from_numpy(params))
    assert torch.all(ref == 0.0)


@pytest.mark.parametrize("seed", [0, 1])
def test_albedo_factorisation_is_exact(seed):
    """Paper Eq. 3: disney(x, A) = (A / lum(A)) p(x) + q(x)."""
    l, v, base, params, _, _ = _random_inputs(seed, 4096)
    with torch.no_grad():
        ref = brdf.disney(l, v, base, params).double()
        lum = brdf.luminance(base)
        p, q = brdf.disney_pq(l, v, params, lum)
        got = base.double() / lum.double()[:, None] * p.double()[:, None] + q.double()[:, None]
    np.testing.assert_allclose(got.numpy(), ref.numpy(), rtol=2e-5, atol=1e-6)


def test_ggx_closed_forms():
    """D integrates to 1 against n.h over the hemisphere, and D(1, a) = 1 / (pi a^4)."""
    a = torch.tensor([0.3, 0.6, 0.9], dtype=torch.float64)
    assert torch.allclose(brdf.ggx_d(torch.ones(3, dtype=torch.float64), a), 1.0 / (math.pi * a ** 4))
    z = torch.linspace(0, 1, 200001, dtype=torch.float64)
    for ai in a:
        integrand = brdf.ggx_d(z, ai) * z * 2 * math.pi   # d omega = 2 pi d(cos)
        assert abs(float(torch.trapezoid(integrand, z)) - 1.0) < 1e-3


def test_lambert_limit():
    """Roughness 0.5 at normal incidence both ways: the diffuse lobe is A / pi (Burley's F_D = 1)."""
    base, params = brdf.material({"roughness": 0.5, "specular": 0.0}, base_color=(0.5, 0.5, 0.5))
    n = torch.tensor([0.0, 0.0, 1.0])
    f = brdf.disney(n, n, base, params)
    assert torch.allclose(f, torch.full((3,), 0.5 / math.pi), rtol=1e-5)


def test_unknown_parameter_is_an_error():
    with pytest.raises(ValueError, match="unknown Disney parameter 'glossy'"):
        brdf.material({"glossy": 1.0})
