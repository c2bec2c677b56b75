"""Input encodings through GLSL (tolerance rule of tests/parity.py), and the SH basis against
an independent formula (associated Legendre recursion) and for orthonormality."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.models import GraphModule
from inshade.models.activations import Tanh
from inshade.models.encodings import Frequency, SphericalHarmonics, TriangleWave
from inshade.models.mlp import Dense
from inshade.sh import SH_TERMS, sh_basis

from parity import check_parity, parity_settings, uniform_inputs, unit_directions

N = 200


def _encoding_graph(enc, in_dim: int, dense_out: int | None = None) -> GraphModule:
    g = GraphModule([("x", in_dim)])
    src = g.add("enc", enc, "x")
    if dense_out is not None:
        torch.manual_seed(0)
        src = g.add("l0", Dense(g.dim("enc"), dense_out), "enc")
        src = g.add("a0", Tanh(), src)
    g.output("y", src)
    return g


# n_freqs <= 8 with inputs in [-1, 1]: sin/cos arguments up to 2^7 pi ~ 402, where llvmpipe's
# argument reduction still agrees with torch within the 1e-5 rule (see tests/parity.py).
@st.composite
def frequency_cases(draw):
    n = draw(st.integers(1, 8))
    include = draw(st.booleans())
    per_dim = 2 * n + include
    d = draw(st.integers(1, max(1, min(4, 32 // per_dim))))   # <= 32 outputs (8 draw buffers)
    return n, include, d, draw(st.integers(0, 2**31 - 1))


@parity_settings(max_examples=10)
@given(case=frequency_cases())
def test_frequency_parity(gl, case):
    n, include, d, seed = case
    bundle = _encoding_graph(Frequency(n, include), d).export("freq")
    x = uniform_inputs(seed, N, d)
    check_parity(gl, bundle, x, what=f"frequency n={n} include_input={include} d={d}")


@pytest.mark.parametrize("include", [True, False])
def test_frequency_into_dense(gl, include):
    """A wide encoding (3 x 17 = 51 lanes, unaligned start without raw input) feeding a layer."""
    bundle = _encoding_graph(Frequency(8, include), 3, dense_out=7).export("freq_mlp")
    check_parity(gl, bundle, uniform_inputs(1, N, 3), storage="inline")


@parity_settings(max_examples=10)
@given(n=st.integers(1, 8), d=st.integers(1, 4), seed=st.integers(0, 2**31 - 1))
def test_triangle_wave_parity(gl, n, d, seed):
    """tri(2^k x), n_freqs <= 8 and inputs in [-1, 1], i.e. arguments |t| <= 128.

    Why bounded: 2^k x, mod(t, 2) and 1 - |. - 1| are all exact in fp32, and torch is exact,
    but llvmpipe's compiled generated code rounds once at the argument's magnitude (measured:
    error = ulp(|t|)/2, e.g. 1.5e-5 at t = -255.70335 = 128 * -1.9976825; the same expression
    in a one-line shader is exact, so it is a compiler rewrite). ulp(128)/2 = 7.6e-6 keeps the
    1e-5 rule; n_freqs up to 16 with |x| ~ 1 would need a 2^-9 bound."""
    if n * d > 32:
        d = 32 // n
    bundle = _encoding_graph(TriangleWave(n), d).export("tri")
    x = uniform_inputs(seed, N, d)
    x[:16] = np.round(x[:16] * 4) / 4  # kinks and plateaus of the wave
    check_parity(gl, bundle, x, what=f"triangle_wave n={n} d={d}")


# Degree 1 is a constant: the linker drops u_inputs, which the pass must then not bind.
@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
def test_spherical_harmonics_parity(gl, degree):
    bundle = _encoding_graph(SphericalHarmonics(degree), 3).export("sh")
    x = unit_directions(degree, N)
    x[:6] = np.float32(np.concatenate([np.eye(3), -np.eye(3)]))  # the poles and axes
    check_parity(gl, bundle, x, what=f"spherical_harmonics degree={degree}")


def test_spherical_harmonics_into_dense(gl):
    bundle = _encoding_graph(SphericalHarmonics(5), 3, dense_out=9).export("sh_mlp")
    check_parity(gl, bundle, unit_directions(9, N), storage="texture")


# --- the SH basis against a direct formula ----------------------------------------------------

def legendre(lmax: int, x: np.ndarray) -> dict[tuple[int, int], np.ndarray]:
    """Associated Legendre P_l^m(x), 0 <= m <= l < lmax, Condon-Shortley phase included, by
    the standard recursion (P_m^m, P_{m+1}^m, then upward in l)."""
    p = {}
    s = np.sqrt(np.maximum(0.0, 1.0 - x * x))
    for m in range(lmax):
        pmm = np.ones_like(x)
        for k in range(1, m + 1):
            pmm = pmm * (-(2 * k - 1)) * s      # (-1)^m (2m-1)!! (1-x^2)^(m/2)
        p[m, m] = pmm
        if m + 1 < lmax:
            p[m + 1, m] = x * (2 * m + 1) * pmm
        for l in range(m + 2, lmax):
            p[l, m] = ((2 * l - 1) * x * p[l - 1, m] - (l + m - 1) * p[l - 2, m]) / (l - m)
    return p


def sh_direct(dirs: np.ndarray, degree: int) -> np.ndarray:
    """Real orthonormal SH, index l*l + l + m:
    Y_l^0 = K_l^0 P_l^0(z); Y_l^m = sqrt2 K_l^m cos(m phi) P_l^m(z) (m > 0);
    Y_l^-m = sqrt2 K_l^m sin(m phi) P_l^m(z), K_l^m = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!)."""
    x, y, z = dirs[:, 0].astype(np.float64), dirs[:, 1].astype(np.float64), dirs[:, 2].astype(np.float64)
    phi = np.arctan2(y, x)
    p = legendre(degree, z)
    out = np.zeros((len(dirs), degree * degree))
    for l in range(degree):
        for m in range(-l, l + 1):
            am = abs(m)
            k = math.sqrt((2 * l + 1) / (4 * math.pi) * math.factorial(l - am) / math.factorial(l + am))
            if m == 0:
                v = k * p[l, 0]
            elif m > 0:
                v = math.sqrt(2) * k * np.cos(m * phi) * p[l, m]
            else:
                v = math.sqrt(2) * k * np.sin(am * phi) * p[l, am]
            out[:, l * l + l + m] = v
    return out


@given(seed=st.integers(0, 2**31 - 1))
def test_sh_table_matches_direct_formula(seed):
    dirs = np.random.default_rng(seed).normal(size=(64, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    for degree in range(1, 6):
        np.testing.assert_allclose(sh_basis(dirs, degree), sh_direct(dirs, degree), rtol=0, atol=1e-12)
    # torch evaluates the same table
    got = sh_basis(torch.from_numpy(dirs), 5, xp=torch).numpy()
    np.testing.assert_allclose(got, sh_direct(dirs, 5), atol=1e-12)


def test_sh_orthonormal_by_quadrature():
    """Gauss-Legendre in z (16 nodes) x uniform phi (32 nodes) integrates products of bands
    l < 5 (polynomials of degree <= 8) exactly: the Gram matrix is the identity."""
    zs, wz = np.polynomial.legendre.leggauss(16)
    phis = (np.arange(32) + 0.5) * 2 * np.pi / 32
    z, phi = np.meshgrid(zs, phis, indexing="ij")
    s = np.sqrt(1 - z * z)
    dirs = np.stack([s * np.cos(phi), s * np.sin(phi), z], -1).reshape(-1, 3)
    w = (wz[:, None] * np.full(32, 2 * np.pi / 32)[None]).reshape(-1)
    y = sh_basis(dirs, 5)
    gram = (y * w[:, None]).T @ y
    np.testing.assert_allclose(gram, np.eye(25), atol=1e-12)


def test_sh_orthonormal_monte_carlo():
    """Independent check of the quadrature: uniform directions, E[Y_i Y_j] * 4 pi ~ delta_ij
    (4e5 samples: standard error ~ 0.01)."""
    dirs = unit_directions(123, 400_000).astype(np.float64)
    y = sh_basis(dirs, 5)
    gram = y.T @ y * (4 * np.pi / len(dirs))
    assert np.abs(gram - np.eye(25)).max() < 0.06


def test_sh_table_has_every_index():
    assert len(SH_TERMS) == 25
    assert all(terms for terms in SH_TERMS)
