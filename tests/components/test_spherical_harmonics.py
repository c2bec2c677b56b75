"""The SH toolkit (inshade/sh.py): projection, environments, rotation, triple product, zonal
convolution, and the GLSL lighting chunk (lib/spherical_harmonics) against numpy through the
real driver under the tolerance rule of tests/parity.py."""
from __future__ import annotations

import math

import numpy as np
import pytest
from PIL import Image

from inshade import sh
from inshade.codegen.spherical_harmonics import sh_chunk, sh_chunks
from inshade.scene.image_io import load_environment, write_exr

from parity import assert_parity, unit_directions

DEG = 4  # 16 coefficients, the PRT default
K = DEG * DEG


def unit64(seed: int, n: int) -> np.ndarray:
    """Unit directions to float64 precision (the SH polynomials assume |d| = 1)."""
    d = unit_directions(seed, n).astype(np.float64)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def random_rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


# --- projection -------------------------------------------------------------------------------

def test_quadrature_integrates_basis_orthonormally():
    dirs, w = sh.sphere_quadrature(6)
    assert abs(w.sum() - 4 * math.pi) < 1e-12
    y = sh.sh_basis(dirs, 5)
    np.testing.assert_allclose((y * w[:, None]).T @ y, np.eye(25), atol=1e-12)


def test_project_constant_and_single_basis_function():
    c = sh.project_function(lambda d: np.full(len(d), 2.5), DEG, n=8)
    expect = np.zeros(K)
    expect[0] = 2.5 * math.sqrt(4 * math.pi)
    np.testing.assert_allclose(c, expect, atol=1e-12)
    for i in (1, 6, 11, 15):
        c = sh.project_function(lambda d: sh.sh_basis(d, DEG)[:, i], DEG, n=8)
        np.testing.assert_allclose(c, np.eye(K)[i], atol=1e-12)


def test_project_clamped_cosine_matches_zonal_closed_form():
    """f(d) = max(d.a, 0) is the clamped-cosine kernel centred on a; by Funk-Hecke and the
    addition theorem its coefficients are c_lm = A_l Y_lm(a), A_l = lambert_bands (closed form).
    The kink at the equator makes quadrature converge slowly, hence n = 200 and atol 2e-5."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=3)
    a /= np.linalg.norm(a)
    c = sh.project_function(lambda d: np.maximum(d @ a, 0.0), DEG, n=200)
    expect = sh.convolve_zonal(sh.sh_basis(a, DEG), sh.lambert_bands(DEG))
    np.testing.assert_allclose(c, expect, atol=2e-5)


# --- environments -----------------------------------------------------------------------------

def test_equirect_convention_and_solid_angles():
    d = sh.equirect_directions(8, 4)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-12)
    assert d[0, 0, 1] > 0.9 and d[-1, 0, 1] < -0.9              # row 0 looks up
    centre = sh.equirect_directions(2048, 1024)[512, 1024]       # u ~ 0.5, v ~ 0.5 -> -z
    np.testing.assert_allclose(centre, [0, 0, -1], atol=4e-3)
    uv = sh.direction_to_equirect(np.array([[1.0, 0, 0], [0, 0, -1.0]]))
    np.testing.assert_allclose(uv, [[0.75, 0.5], [0.5, 0.5]], atol=1e-12)
    dd = sh.equirect_directions(64, 32)
    u = (np.arange(64) + 0.5) / 64
    v = (np.arange(32) + 0.5) / 32
    np.testing.assert_allclose(sh.direction_to_equirect(dd), np.stack(np.meshgrid(u, v), -1), atol=1e-12)
    assert abs(sh.equirect_solid_angles(64, 32).sum() - 4 * math.pi) < 1e-12


@pytest.mark.parametrize("name", list(sh.SKY_PRESETS))
def test_procedural_sky_projection_matches_quadrature(name):
    """Texel weights: the equirect projection converges to the quadrature projection of the
    analytic sky (a wrong weight, e.g. without sin(theta), is off by O(1))."""
    env = sh.procedural_sky(name, 1024)
    assert env.shape == (512, 1024, 3) and env.dtype == np.float32 and (env >= 0).all()
    c_img = sh.project_environment(env, DEG)
    c_ref = sh.project_function(lambda d: sh.sky_radiance(name, d), DEG, n=256)
    scale = np.abs(c_ref).max()
    assert np.abs(c_img - c_ref).max() < 2e-3 * scale, (name, np.abs(c_img - c_ref).max(), scale)


def test_smooth_sky_reconstruction_error_is_low():
    env = sh.procedural_sky("overcast", 256)
    c = sh.project_environment(env, 5)
    rec = sh.sh_to_equirect(c, 256, 128)
    w = sh.equirect_solid_angles(256, 128)[..., None]
    rel = math.sqrt((w * (rec - env) ** 2).sum() / (w * env.astype(np.float64) ** 2).sum())
    assert rel < 0.03, rel


def test_unknown_sky_preset():
    with pytest.raises(ValueError, match="unknown sky preset 'mars'.*overcast"):
        sh.procedural_sky("mars", 64)


def test_load_environment_roundtrip(tmp_path):
    env = sh.procedural_sky("studio", 64)
    p = write_exr(tmp_path / "studio.exr", env)
    np.testing.assert_array_equal(load_environment(p), env)
    png = tmp_path / "grey.png"
    Image.fromarray(np.full((16, 32, 3), 255, np.uint8)).save(png)
    np.testing.assert_allclose(load_environment(png), 1.0)


@pytest.mark.parametrize("case", ["shape", "nan", "missing", "format", "negative"])
def test_load_environment_bad_inputs(tmp_path, case):
    path = tmp_path / f"{case}.exr"
    image = np.ones((16, 32, 3), np.float32)
    expect = {"shape": "twice as wide", "nan": "non-finite", "missing": "no such file",
              "format": "unsupported format", "negative": "negative radiance"}[case]
    if case == "shape":
        image = np.ones((16, 16, 3), np.float32)
    elif case == "nan":
        image[3, 5, 1] = np.nan
    elif case == "negative":
        image[0, 0, 0] = -1.0
    elif case == "format":
        path = tmp_path / "env.hdr"
        path.write_bytes(b"#?RADIANCE\n")
    if case not in ("missing", "format"):
        write_exr(path, image)
    with pytest.raises(ValueError) as info:
        load_environment(path)
    msg = str(info.value)
    assert msg.startswith(f"environment map {path}:") and expect in msg and msg.count("\n") == 0, msg


def test_project_environment_rejects_bad_arrays():
    with pytest.raises(ValueError, match=r"\[H, W, 3\]"):
        sh.project_environment(np.ones((8, 16)))
    bad = np.ones((8, 16, 3))
    bad[2, 2, 2] = np.inf
    with pytest.raises(ValueError, match="non-finite"):
        sh.project_environment(bad)


# --- rotation ---------------------------------------------------------------------------------

def test_rotation_is_a_representation_and_orthogonal_per_band():
    rng = np.random.default_rng(0)
    for _ in range(5):
        a, b = random_rotation(rng), random_rotation(rng)
        da, db, dab = (sh.sh_rotation(r, 5) for r in (a, b, a @ b))
        np.testing.assert_allclose(da @ db, dab, atol=1e-12)
        for l in range(5):
            s = slice(l * l, (l + 1) * (l + 1))
            blk = da[s, s]
            np.testing.assert_allclose(blk @ blk.T, np.eye(2 * l + 1), atol=1e-12)
        off = da.copy()
        for l in range(5):
            off[l * l:(l + 1) ** 2, l * l:(l + 1) ** 2] = 0
        assert not off.any()
    np.testing.assert_allclose(sh.sh_rotation(np.eye(3), 5), np.eye(25), atol=1e-13)


def test_rotating_coefficients_equals_projecting_rotated_function():
    rng = np.random.default_rng(1)
    c = rng.normal(size=(25, 3))
    f = lambda d: sh.sh_evaluate(c, d)
    for _ in range(3):
        r = random_rotation(rng)
        rotated = sh.project_function(lambda d: f(d @ r), 5, n=8)    # g(w) = f(R^T w)
        np.testing.assert_allclose(sh.rotate_sh(c, r), rotated, atol=1e-10)
    # and point-wise: the rotated function at R d equals the original at d
    d = unit64(2, 50)
    r = sh.rotation_matrix([0, 1, 0], 0.9)
    np.testing.assert_allclose(sh.sh_evaluate(sh.rotate_sh(c, r), d @ r.T), f(d), atol=1e-10)


def test_rotation_rejects_non_rotations():
    with pytest.raises(ValueError, match="rotation"):
        sh.sh_rotation(np.diag([1.0, 1.0, -1.0]))


# --- triple product ---------------------------------------------------------------------------

def test_triple_product_symmetry_and_normalisation():
    t = sh.triple_product_tensor(DEG)
    assert t.shape == (K, K, K)
    for perm in [(1, 0, 2), (0, 2, 1), (2, 1, 0), (1, 2, 0)]:
        np.testing.assert_array_equal(t, t.transpose(perm))
    np.testing.assert_allclose(t[0], np.eye(K) / math.sqrt(4 * math.pi), atol=1e-14)
    assert sh.triple_product_tensor(DEG) is t                       # cached
    assert (t != 0).mean() < 0.15                                   # sparse (selection rules)
    # l=4 bands too, and the sub-tensor of a lower degree is the same numbers
    np.testing.assert_allclose(sh.triple_product_tensor(5)[:K, :K, :K], t, atol=1e-14)


def test_product_projection_matches_quadrature():
    rng = np.random.default_rng(4)
    a, b = rng.normal(size=(K, 3)), rng.normal(size=(K, 3))
    ref = sh.project_function(lambda d: sh.sh_evaluate(a, d) * sh.sh_evaluate(b, d), DEG, n=12)
    np.testing.assert_allclose(sh.sh_product(a, b), ref, atol=1e-12)
    m = sh.sh_product_matrix(a[:, 0])                               # the light matrix
    np.testing.assert_allclose(m @ b[:, 0], ref[:, 0], atol=1e-12)
    np.testing.assert_allclose(sh.sh_product_matrix(a)[1] @ b[:, 1], ref[:, 1], atol=1e-12)


# --- zonal convolution ------------------------------------------------------------------------

def test_lambert_closed_form_values():
    np.testing.assert_allclose(sh.lambert_bands(5), [math.pi, 2 * math.pi / 3, math.pi / 4, 0, -math.pi / 24],
                               atol=1e-15)
    np.testing.assert_allclose(sh.phong_bands(1, 5), sh.lambert_bands(5) / math.pi, atol=1e-15)


@pytest.mark.parametrize("s", [0.0, 1.0, 7.0, 32.0, 150.5])
def test_phong_bands_match_numeric(s):
    h = lambda t: np.where(t > 0, (s + 1) / (2 * math.pi) * np.abs(t) ** s, 0.0)
    # split-free check with the kink at 0: integrate on [0, 1] only, exact for integer s
    t, w = np.polynomial.legendre.leggauss(200)
    t, w = 0.5 * (t + 1), 0.5 * w
    num = [2 * math.pi * np.sum(w * h(t) * np.polynomial.legendre.Legendre.basis(l)(t)) for l in range(5)]
    np.testing.assert_allclose(sh.phong_bands(s, 5), num, atol=1e-10)
    assert abs(sh.phong_bands(s, 5)[0] - 1.0) < 1e-12
    smooth = sh.zonal_bands(lambda x: np.exp(3 * (x - 1)), 5)      # generic path, smooth kernel
    analytic0 = 2 * math.pi * (1 - math.exp(-6)) / 3
    assert abs(smooth[0] - analytic0) < 1e-12


def test_irradiance_of_directional_light_vs_brute_force():
    """A (band-limited) light: its irradiance via A_l equals brute-force integration of
    L(w) max(n.w, 0) over the sphere (done at high order, since the cosine is clamped)."""
    rng = np.random.default_rng(5)
    light = rng.normal(size=3)
    light /= np.linalg.norm(light)
    # a soft directional light: a sharp-ish spherical Gaussian, projected to SH
    lobe = lambda d: np.exp(20 * (d @ light - 1))[:, None] * np.array([1.0, 0.7, 0.4])
    c = sh.project_function(lobe, DEG, n=64)
    normals = unit64(6, 20)
    dirs, w = sh.sphere_quadrature(400)
    radiance = sh.sh_evaluate(c, dirs)                               # the band-limited light
    brute = np.stack([(w * np.maximum(dirs @ n, 0))[None] @ radiance for n in normals])[:, 0]
    np.testing.assert_allclose(sh.sh_irradiance(c, normals), brute, atol=2e-5 * np.abs(brute).max())
    # a delta light of unit intensity: E(n) ~ max(n.l, 0) up to the band-limit (l <= 3 and 4)
    delta = sh.sh_basis(light, 5)[:, None]
    e = sh.sh_irradiance(delta, normals)[:, 0]
    assert np.abs(e - np.maximum(normals @ light, 0)).max() < 0.1


def test_sh_irradiance_torch_matches_numpy():
    import torch
    rng = np.random.default_rng(7)
    c = rng.normal(size=(K, 3))
    n = unit64(8, 30)
    out = sh.sh_irradiance(torch.from_numpy(c), torch.from_numpy(n), xp=torch).numpy()
    np.testing.assert_allclose(out, sh.sh_irradiance(c, n), atol=1e-12)


# --- GLSL -------------------------------------------------------------------------------------

def test_chunk_is_generated_from_the_table():
    src = sh_chunk(4)
    assert "#define SH_COEFFS 16" in src and "void sh_basis(vec3 d, out float y[SH_COEFFS])" in src
    assert "3.14159274" in src                                       # A_0 = pi, %.9g
    with pytest.raises(ValueError, match="degree"):
        sh_chunk(6)


@pytest.mark.parametrize("degree", [4, 5])
def test_glsl_lighting_parity(gl, degree):
    from inshade.runtime.programs import ProgramCache
    from inshade.runtime.render import FullscreenPass, float_target, read_rgba_raw, release_target, upload_float_texture

    k = degree * degree
    rng = np.random.default_rng(degree)
    coeffs = sh.project_environment(sh.procedural_sky("sunset", 128), degree).astype(np.float32)
    coeffs[1:] += rng.normal(scale=0.2, size=(k - 1, 3)).astype(np.float32)
    bands = sh.phong_bands(12.0, degree).astype(np.float32)
    w, h = 16, 8
    dirs = unit_directions(degree + 10, w * h)
    dirs[:6] = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]]
    cache = ProgramCache(gl)
    program = cache.get("common/fullscreen.vert", "passes/sh_irradiance_test.frag", chunks=sh_chunks(degree))
    tex = upload_float_texture(gl, np.concatenate([dirs, np.zeros((w * h, 1), np.float32)], 1).reshape(h, w, 4))
    fbo = float_target(gl, w, h, 4)
    pass_ = FullscreenPass(gl, program)
    try:
        gl.viewport = (0, 0, w, h)
        pass_.render(fbo, uniforms={"u_sh": coeffs.tobytes(), "u_bands": bands.tobytes()},
                     textures={"u_dirs": tex})
        out = [read_rgba_raw(fbo, a).reshape(-1, 4)[:, :3] for a in range(4)]
    finally:
        tex.release()
        release_target(fbo)
        pass_.vao.release()
        cache.release()
    # the reference: numpy in float64 from the same float32 inputs
    d64, c64 = dirs.astype(np.float64), coeffs.astype(np.float64)
    assert_parity(out[0], sh.sh_irradiance(c64, d64), what=f"sh_irradiance degree {degree}")
    assert_parity(out[1], sh.sh_evaluate(c64, d64), what=f"sh_radiance degree {degree}")
    assert_parity(out[2], sh.sh_evaluate(sh.convolve_zonal(c64, bands.astype(np.float64)), d64),
                  what=f"sh_convolved degree {degree}")
    background = np.maximum(sh.sh_evaluate(sh.convolve_zonal(c64, sh.background_bands(degree)), d64), 0.0)
    assert_parity(out[3], background, what=f"sh_background degree {degree}")


@pytest.mark.parametrize("name", sorted(sh.SKY_PRESETS))
def test_background_does_not_ring_into_black(name):
    """An environment shown behind the scene is its degree-4 series: truncated as it is, the sunset
    and studio skies dip to -0.8 and -2.0 times their mean (black once clamped; studio over 30% of
    the sphere, the dark band in sdf_mechanical's corner). The Hann-windowed bands keep every
    preset's dip within 15% of its mean (studio's deepest: 9%)."""
    coeffs = sh.project_environment(sh.procedural_sky(name, 256), DEG)
    dirs = unit64(3, 20000)
    shown = sh.sh_evaluate(sh.convolve_zonal(coeffs, sh.background_bands(DEG)), dirs)
    assert shown.min() >= -0.15 * shown.mean(), (name, shown.min(), shown.mean())
