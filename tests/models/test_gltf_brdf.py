"""The glTF reference BRDF: shaders/lib/gltf_brdf.glsl (through passes/gltf_brdf_eval_test.frag)
against its numpy twin models/gltf_brdf.py at random points, every lobe on and off, and the twin
against values worked out by hand from the spec's formulas.

Tolerance: the parity rule (tests/parity.py), |glsl - numpy| <= 1e-5 max(1, |numpy|), except GGX
near its peak: f = n.h^2 (a^2 - 1) + 1 cancels to ~a^2 for smooth surfaces, so one rounding of
n.h^2 (a^2 - 1) (~2^-24 absolute) is 2^-24 / f relative in f and twice that in D ~ 1 / f^2; those
samples get 1e-5 + 8 * 2^-23 / f on the lobe's share (as tests/models/test_brdf.py does for Disney's GGX).
"""
from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from inshade.models import gltf_brdf as G
from parity import parity_settings, run_sample_pass

PASS = "passes/gltf_brdf_eval_test.frag"


def _unit(x):
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def _points(seed: int, n: int):
    rng = np.random.default_rng(seed)
    nrm = _unit(rng.normal(size=(n, 3)))

    def hemisphere():
        d = _unit(rng.normal(size=(n, 3)))
        return d * np.sign(np.sum(d * nrm, 1, keepdims=True))

    v, l = hemisphere(), hemisphere()
    l[::9] *= -1.0                                     # some lights below the surface
    at = _unit(np.cross(nrm, rng.normal(size=(n, 3))))
    frame = dict(n=nrm, at=at, ab=np.cross(nrm, at), nc=_unit(nrm + 0.2 * rng.normal(size=(n, 3))), v=v, l=l)
    on = lambda p: rng.uniform(size=n) < p  # noqa: E731
    s = G.Shading(base_color=rng.uniform(0, 1, (n, 3)), metallic=rng.uniform(size=n),
                  roughness=rng.uniform(0.1, 1.0, n), f0=rng.uniform(0.02, 0.1, n),
                  clearcoat=rng.uniform(size=n) * on(0.5), clearcoat_roughness=rng.uniform(0.1, 1.0, n),
                  sheen_color=rng.uniform(0, 1, (n, 3)) * on(0.5)[:, None], sheen_roughness=rng.uniform(size=n),
                  anisotropy=rng.uniform(size=n) * on(0.5))
    light = dict(irradiance=rng.uniform(0, 3, (n, 3)), radiance=rng.uniform(0, 3, (n, 3)))
    return s, frame, light


def _glsl(gl, s, frame, light):
    n = len(s.metallic)
    rows = np.zeros((n, 40), np.float32)
    for k, name in enumerate(("n", "at", "ab", "nc", "v", "l")):
        rows[:, 3 * k: 3 * k + 3] = frame[name]
    rows[:, 18:21] = s.base_color
    rows[:, 21], rows[:, 22], rows[:, 23], rows[:, 24], rows[:, 25] = (s.metallic, s.roughness, s.f0, s.clearcoat,
                                                                       s.clearcoat_roughness)
    rows[:, 26:29], rows[:, 29], rows[:, 30] = s.sheen_color, s.sheen_roughness, s.anisotropy
    rows[:, 32:35], rows[:, 36:39] = light["irradiance"], light["radiance"]
    out = run_sample_pass(gl, PASS, rows, 10, attachments=2)
    return out[0][:, :3], out[1][:, :3]


def _peak_f(s, frame):
    """min over the isotropic GGX lobes of f = n.h^2 (a^2 - 1) + 1 (float64): the cancellation."""
    h = _unit(frame["l"] + frame["v"])
    f = np.ones(len(s.metallic))
    for normal, rough, on in ((frame["n"], s.roughness, s.anisotropy == 0), (frame["nc"], s.clearcoat_roughness,
                                                                              s.clearcoat > 0)):
        nh = np.clip(np.sum(normal * h, 1), 0, 1)
        a2 = rough.astype(np.float64) ** 4
        f = np.where(on, np.minimum(f, nh * nh * (a2 - 1) + 1), f)
    return f


@parity_settings(max_examples=3)
@given(seed=st.integers(0, 2 ** 31 - 1))
def test_brdf_and_environment_match_the_numpy_twin(gl, seed):
    s, frame, light = _points(seed, 2048)
    brdf, env = _glsl(gl, s, frame, light)
    ref = G.brdf(s, frame["n"], frame["at"], frame["ab"], frame["nc"], frame["v"], frame["l"])
    assert np.isfinite(ref).all() and np.isfinite(brdf).all()
    rel = np.abs(brdf.astype(np.float64) - ref) / np.maximum(1.0, np.abs(ref))
    bound = 1e-5 + 8.0 * 2.0 ** -23 / _peak_f(s, frame)[:, None]
    worst = np.unravel_index(np.argmax(rel / bound), rel.shape)
    assert np.all(rel <= bound), f"gltf_brdf: scaled error {rel[worst]:.3g} > {bound[worst]:.3g} at sample {worst[0]}"
    ref_env = G.environment(s, frame["n"], frame["v"], light["irradiance"], light["radiance"])
    rel = np.abs(env.astype(np.float64) - ref_env) / np.maximum(1.0, np.abs(ref_env))
    assert rel.max() <= 1e-5, f"gltf_environment: scaled error {rel.max():.3g}"


def _one(**kw) -> G.Shading:
    base = dict(base_color=[[0.5, 0.25, 0.125]], metallic=[0.0], roughness=[1.0], f0=[0.04], clearcoat=[0.0],
                clearcoat_roughness=[0.0], sheen_color=[[0.0, 0.0, 0.0]], sheen_roughness=[0.0], anisotropy=[0.0])
    base.update(kw)
    return G.Shading(**base)


Z, X, Y = np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]])


def test_twin_at_normal_incidence_is_the_spec_by_hand():
    """l = v = n: D = 1 / (pi a^2) for a = roughness^2, V = G / (4 n.l n.v) = 1 / 4 (no masking),
    Fresnel = F0: dielectric = mix(c / pi, V D, F0); metal = c V D."""
    c = np.array([0.5, 0.25, 0.125])
    for rough in (1.0, 0.5):
        a = rough * rough
        vd = 0.25 / (math.pi * a * a)
        got = G.brdf(_one(roughness=[rough]), Z, X, Y, Z, Z, Z)[0]
        np.testing.assert_allclose(got, c / math.pi * 0.96 + 0.04 * vd, rtol=2e-6)
        got = G.brdf(_one(roughness=[rough], metallic=[1.0]), Z, X, Y, Z, Z, Z)[0]
        np.testing.assert_allclose(got, c * vd, rtol=2e-6)


def test_clearcoat_at_normal_incidence_mixes_by_its_fresnel():
    a = 0.3 ** 2
    coat = 0.25 / (math.pi * a * a)
    base = G.brdf(_one(), Z, X, Y, Z, Z, Z)[0]
    got = G.brdf(_one(clearcoat=[1.0], clearcoat_roughness=[0.3]), Z, X, Y, Z, Z, Z)[0]
    np.testing.assert_allclose(got, base * 0.96 + 0.04 * coat, rtol=1e-5)   # float32 mix


def test_anisotropy_zero_is_isotropic_and_stretches_along_its_direction():
    rng = np.random.default_rng(1)
    # within 35 degrees of n: the anisotropic visibility's clamp to 1 (grazing angles) stays out of it
    v = _unit(np.concatenate([rng.uniform(-1, 1, (64, 2)), np.full((64, 1), 2.0)], 1))
    l = _unit(np.concatenate([rng.uniform(-1, 1, (64, 2)), np.full((64, 1), 2.0)], 1))
    rep = lambda a: np.repeat(a, 64, 0)  # noqa: E731
    iso = G.brdf(_one(roughness=[0.4] * 64, base_color=[[0.5, 0.25, 0.125]] * 64, **{
        k: [v0[0]] * 64 for k, v0 in dict(metallic=[0.0], f0=[0.04], clearcoat=[0.0], clearcoat_roughness=[0.0],
                                           sheen_roughness=[0.0], anisotropy=[0.0]).items()},
        sheen_color=[[0, 0, 0]] * 64), rep(Z), rep(X), rep(Y), rep(Z), v, l)
    # the anisotropic lobe at strength -> 0 is the isotropic one (its own formula)
    s = _one(roughness=[0.4] * 64, base_color=[[0.5, 0.25, 0.125]] * 64, metallic=[0.0] * 64, f0=[0.04] * 64,
             clearcoat=[0.0] * 64, clearcoat_roughness=[0.0] * 64, sheen_color=[[0, 0, 0]] * 64,
             sheen_roughness=[0.0] * 64, anisotropy=[1e-4] * 64)
    np.testing.assert_allclose(G.brdf(s, rep(Z), rep(X), rep(Y), rep(Z), v, l), iso, rtol=1e-4)
    # the distribution is wider along at (roughness mix(a, 1, strength^2)) than along ab (a)
    h = math.radians(25.0)
    along_t = G.d_ggx_anisotropic(np.float32(math.cos(h)), np.float32(math.sin(h)), np.float32(0.0),
                                  np.float32(0.6), np.float32(0.16))
    along_b = G.d_ggx_anisotropic(np.float32(math.cos(h)), np.float32(0.0), np.float32(math.sin(h)),
                                  np.float32(0.6), np.float32(0.16))
    assert along_t > 10.0 * along_b
