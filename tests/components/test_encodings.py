"""Input encodings through GLSL (tolerance rule of tests/parity.py), and the SH basis against
an independent formula (associated Legendre recursion) and for orthonormality."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.components import ComponentError, check_node, resolve_params
from inshade.components.dense.torch_twin import Dense
from inshade.components.elementwise.torch_twin import Tanh
from inshade.components.encodings.torch_twin import Frequency, SphericalHarmonics, TriangleWave
from inshade.components.one_blob.torch_twin import OneBlob
from inshade.models import GraphModule
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


# --- one_blob (tiny-cuda-nn's OneBlob) ------------------------------------------------------------

def blob_inputs(seed: int, n: int, d: int, bins: int) -> np.ndarray:
    """Uniform in [-0.5, 1.5] (the wrap-around on both sides), plus bin boundaries k / B (where the
    blob's edges and centre land on a boundary: |u| = 0 and 1), their float32 neighbours, 0 and 1."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-0.5, 1.5, (n, d)).astype(np.float32)
    edges = (rng.integers(-bins, 2 * bins + 1, (n // 4, d)) / bins).astype(np.float32)
    x[:n // 4] = edges
    x[n // 4:n // 2] = np.nextafter(edges, np.where(rng.random(edges.shape) < 0.5, -np.inf, np.inf).astype(np.float32))
    x[n // 2, :] = 0.0
    x[n // 2 + 1, :] = 1.0
    return x


@st.composite
def one_blob_cases(draw):
    bins = draw(st.sampled_from([1, 2, 4, 8, 16, 32]))
    d = draw(st.integers(1, min(4, 32 // bins)))      # <= 32 outputs (8 draw buffers)
    return bins, d, draw(st.integers(0, 2**31 - 1))


@parity_settings(max_examples=8)
@given(case=one_blob_cases())
def test_one_blob_parity(gl, case):
    """Measured bit-identical on llvmpipe (the Horner form with exact coefficients and one-rounding
    arguments leave the compiler nothing to refold); held to the 1e-5 rule."""
    bins, d, seed = case
    bundle = _encoding_graph(OneBlob(bins), d).export("one_blob")
    check_parity(gl, bundle, blob_inputs(seed, N, d, bins), what=f"one_blob n_bins={bins} d={d}")


def test_one_blob_into_dense(gl):
    """192 lanes (3 inputs x 64 bins) feeding a layer."""
    bundle = _encoding_graph(OneBlob(64), 3, dense_out=7).export("one_blob_mlp")
    check_parity(gl, bundle, blob_inputs(5, N, 3, 64), storage="texture")


def blob_masses(x: np.ndarray, bins: int) -> np.ndarray:
    """The mass of the blob 15/16 B (1 - (B v)^2)^2 (|B v| <= 1) at x, wrapped once each way with
    period 1, in each bin [k, k + 1) / B: the kernel integrated by 3-point Gauss-Legendre (exact for
    its degree 4) on each piece between the breakpoints. float64; x [M] -> [M, B]."""
    nodes, weights = np.polynomial.legendre.leggauss(3)
    out = np.zeros((len(x), bins))
    for m, xv in enumerate(np.asarray(x, np.float64)):
        centres = xv + np.array([-1.0, 0.0, 1.0])
        for k in range(bins):
            lo, hi = k / bins, (k + 1) / bins
            cuts = np.concatenate([[lo, hi], centres, centres - 1 / bins, centres + 1 / bins])
            cuts = np.unique(np.clip(cuts, lo, hi))
            for a, b in zip(cuts, cuts[1:]):
                y = (a + b) / 2 + (b - a) / 2 * nodes
                v = (y[:, None] - centres[None]) * bins
                kern = np.where(np.abs(v) <= 1, 15 / 16 * bins * (1 - v * v) ** 2, 0.0).sum(1)
                out[m, k] += (b - a) / 2 * (weights * kern).sum()
    return out


@pytest.mark.parametrize("bins", [1, 2, 16, 128])
def test_one_blob_is_the_blob_mass_per_bin(bins):
    """Against the kernel integrated directly (not its closed-form cdf): within 4e-7 (measured
    3.6e-7, at every n_bins up to 1024: each argument is exact where the kernel is not flat).
    Inputs in [0, 1] put their whole mass in the bins."""
    x = blob_inputs(7, 64, 1, bins)[:, 0]
    with torch.no_grad():
        got = OneBlob(bins)(torch.from_numpy(x[:, None])).numpy().astype(np.float64)
    want = blob_masses(x, bins)
    np.testing.assert_allclose(got, want, rtol=0, atol=4e-7)
    inside = (x >= 0) & (x <= 1)
    np.testing.assert_allclose(want[inside].sum(1), 1.0, atol=1e-12)


def tcnn_one_blob(x: np.ndarray, bins: int) -> np.ndarray:
    """tiny-cuda-nn's kernel_one_blob_soa / quartic_cdf as written, float32 step by step in C's order
    (no fused multiply-adds). x [M] -> [M, B]."""
    f = np.float32

    def quartic_cdf(t):
        u = t * f(bins)
        u2 = u * u
        u4 = u2 * u2
        return np.clip(f(15 / 16) * u * (f(1) - f(2 / 3) * u2 + f(1 / 5) * u4) + f(0.5), f(0), f(1))

    x = np.asarray(x, np.float32)
    left = quartic_cdf(-x) + quartic_cdf(-x - f(1)) + quartic_cdf(-x + f(1))
    out = []
    for k in range(bins):
        b = f((k + 1) / bins)
        right = quartic_cdf(b - x) + quartic_cdf(b - x - f(1)) + quartic_cdf(b - x + f(1))
        out.append(right - left)
        left = right
    return np.stack(out, -1)


@pytest.mark.parametrize("bins", [1, 4, 16, 64, 1024])
def test_one_blob_against_tiny_cuda_nn_float32(bins):
    """Our evaluation order against tiny-cuda-nn's own: within 2.8e-8 * B + 5e-7 (its (b - x) - 1
    rounds b - x first, one ulp of ~1 times the slope 15/16 B; measured 1.9e-6 at B = 64,
    2.77e-5 at 1024). Inputs in [0, 1]."""
    x = np.random.default_rng(bins).uniform(0, 1, 20000).astype(np.float32)
    with torch.no_grad():
        got = OneBlob(bins)(torch.from_numpy(x[:, None])).numpy()
    assert np.abs(got - tcnn_one_blob(x, bins)).max() <= 2.8e-8 * bins + 5e-7


def test_one_blob_gradient_is_tiny_cuda_nns():
    """d out / dx as kernel_one_blob_backward computes it: per bin the kernel (quartic * B, summed
    over the three wraps) at the left boundary minus at the right one."""
    bins = 8
    x = torch.from_numpy(blob_inputs(3, 64, 1, bins)[32:, 0].astype(np.float64) * 0.9 + 0.05).float()
    x.requires_grad_(True)
    weights = torch.linspace(-1, 1, bins)
    (OneBlob(bins)(x[:, None]) * weights).sum().backward()

    def kernel(t):
        u = np.clip(t * bins, -1, 1)
        return 15 / 16 * bins * (1 - u * u) ** 2

    xv = x.detach().numpy().astype(np.float64)[:, None]
    b = np.arange(bins + 1) / bins
    k = sum(kernel(b - xv + s) for s in (-1.0, 0.0, 1.0))          # [M, B + 1]
    want = ((k[:, :-1] - k[:, 1:]) * weights.numpy()).sum(1)
    np.testing.assert_allclose(x.grad.numpy(), want, rtol=1e-5, atol=1e-5)


def test_one_blob_component():
    p = resolve_params("one_blob", {})
    assert p == {"n_bins": 16}                         # tiny-cuda-nn's default
    assert check_node("one_blob", p, 3) == 48
    for bad in (0, 3, 12, 2048, 16.0, True):
        with pytest.raises(ComponentError, match="'n_bins'"):
            resolve_params("one_blob", {"n_bins": bad})
    with pytest.raises(ComponentError, match=r"^n_bins: 5 inputs x 1024 bins = 5120 lanes, more than 4096$"):
        check_node("one_blob", {"n_bins": 1024}, 5)
    assert OneBlob(32).params() == {"n_bins": 32}


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
