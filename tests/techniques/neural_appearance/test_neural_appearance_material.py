"""The neural appearance reference material: GLSL (lib/na_reference through
passes/na_reference_test.frag) vs torch (reference.py), the procedural parameter textures, GL-style
sampling, LEAN prefiltering of the encoder inputs, and energy conservation.

Parity tolerance: the rule of tests/parity.py, |glsl - torch| <= 1e-5 max(1, |torch|).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.techniques.neural_appearance import material as M
from inshade.techniques.neural_appearance import reference as R
from parity import assert_parity, parity_settings, run_sample_pass

CHUNK = Path(M.__file__).resolve().parent / "shaders" / "lib" / "na_reference.glsl"
MATERIALS = ("ceramic", "brushed_metal")


@pytest.fixture(autouse=True)
def _one_torch_thread():
    """Elementwise work on ~1e5 samples: one thread is fastest, and on a busy 2-core machine torch's
    thread pool can be ~100x slower than one thread. Restored after each test."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _glsl_reflectance(gl, material, params, light, view):
    rows = np.zeros((params.shape[0], 20), np.float32)
    rows[:, 0:12], rows[:, 12:15], rows[:, 16:19] = params, light, view
    # the chunk is handed over in memory so the test does not depend on the technique's registration
    return run_sample_pass(gl, "passes/na_reference_test.frag", rows, 5, uniforms=M.uniforms(material),
                           chunks={"lib/na_reference": CHUNK.read_text()})[0][:, :3]


def _directions(rng, n, min_z=0.0):
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v[:, 2] = np.maximum(v[:, 2], min_z)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return v.astype(np.float32)


def _torch(material, params, light, view):
    with torch.no_grad():
        return R.reflectance(torch.from_numpy(params), torch.from_numpy(light), torch.from_numpy(view),
                             material).numpy()


def _cosines(material, params, light, view):
    """float64 min over (l.z, v.z, l.n_s, v.n_s): n_s the normal-mapped shading normal."""
    s = (2.0 * params[:, 6:8].astype(np.float64) - 1.0) * material.constants["slope_scale"]
    n = np.concatenate([-s, np.ones((len(s), 1))], 1) / np.sqrt((s * s).sum(1, keepdims=True) + 1.0)
    l, v = light.astype(np.float64), view.astype(np.float64)
    return np.minimum.reduce([l[:, 2], v[:, 2], (l * n).sum(1), (v * n).sum(1)])


def _inputs(rng, material, n, min_cos):
    """n random texels (texture values) and light/view pairs, a quarter of them mirror pairs (where
    the sharpest lobes peak), every cosine of both frames >= min_cos (rejection)."""
    params = np.zeros((0, 12), np.float32)
    light = view = np.zeros((0, 3), np.float32)
    while len(params) < n:
        p = rng.uniform(0.0, 1.0, (4 * n, 12)).astype(np.float32)
        l, v = _directions(rng, 4 * n), _directions(rng, 4 * n)
        v[: n] = l[: n] * np.array([-1.0, -1.0, 1.0], np.float32)
        keep = _cosines(material, p, l, v) >= min_cos
        params, light, view = (np.concatenate([a, b[keep]]) for a, b in ((params, p), (light, l), (view, v)))
    return params[:n], light[:n], view[:n]


@parity_settings(max_examples=4)
@given(name=st.sampled_from(MATERIALS), seed=st.integers(0, 2**31 - 1), quantized=st.booleans())
def test_reflectance_parity(gl, name, seed, quantized):
    """Both executors under the parity rule where float32 is well conditioned: every cosine of the
    geometric and the shading frame >= 0.1 (below: test_reflectance_grazing_parity's bound)."""
    material = M.load_material(name)
    rng = np.random.default_rng(seed)
    params, light, view = _inputs(rng, material, 1024, 0.1)
    if quantized:   # what the textures hold
        params = M.quantize(params)
    light[-8:, 2] *= -1.0            # a few below the horizon: exactly 0 on both sides
    ref = _torch(material, params, light, view)
    out = _glsl_reflectance(gl, material, params, light, view)
    assert_parity(out, ref, what=f"na_reflectance {name}")
    assert np.all(out[-8:] == 0.0) and np.all(ref[-8:] == 0.0)
    assert np.all(ref >= 0.0) and np.all(np.isfinite(ref))


def test_reflectance_grazing_parity(gl):
    """Grazing directions (a cosine of either frame near 0, down to exactly 0) stay finite on both
    sides and agree up to the float32 conditioning there: a cosine c is computed to a few ulps
    absolute (~2^-24), i.e. 2^-24 / c relative, and D G2 / (4 c) passes that on about 1:1. Bound:
    1e-5 + 16 * 2^-24 / c (relative, in the parity rule's max(1, |torch|) scale)."""
    rng = np.random.default_rng(7)
    for name in MATERIALS:
        material = M.load_material(name)
        params = rng.uniform(0.0, 1.0, (4096, 12)).astype(np.float32)
        light, view = _directions(rng, 4096, 0.0), _directions(rng, 4096, 0.0)
        view[:1024] = light[:1024] * np.array([-1.0, -1.0, 1.0], np.float32)
        light[:64, 2] = 0.0                               # exactly on the horizon
        light[:64] /= np.linalg.norm(light[:64], axis=1, keepdims=True)
        light[64:128, 2], view[128:192, 2] = 1e-4, 1e-4
        ref = _torch(material, params, light, view)
        out = _glsl_reflectance(gl, material, params, light, view)
        assert np.all(np.isfinite(out)) and np.all(np.isfinite(ref)) and np.all(ref >= 0.0)
        assert np.all(out[:64] == 0.0) and np.all(ref[:64] == 0.0)
        cos = np.maximum(np.abs(_cosines(material, params, light, view)), 1e-6)
        err = np.abs(out.astype(np.float64) - ref) / np.maximum(1.0, np.abs(ref))
        bound = 1e-5 + 16.0 * 2.0 ** -24 / cos[:, None]
        worst = np.unravel_index(np.argmax(err / bound), err.shape)
        assert np.all(err <= bound), (f"{name}: scaled error {err[worst]:.3g} > bound {bound[worst]:.3g} "
                                      f"at cosine {cos[worst[0]]:.3g}")


def test_reflectance_of_baked_texels_parity(gl):
    """The textures' own texels (k / 255, both materials) through both executors."""
    rng = np.random.default_rng(3)
    for name in MATERIALS:
        material = M.load_material(name)
        raw = M.bake_parameters(material, 32).reshape(-1, 12)
        light, view = _directions(rng, raw.shape[0], 0.05), _directions(rng, raw.shape[0], 0.05)
        ref = _torch(material, raw, light, view)
        assert_parity(_glsl_reflectance(gl, material, raw, light, view), ref, what=f"baked {name}")


def test_reflectance_hand_values():
    """A pure Lambert texel (no coat, no metal, no dust, flat) gives albedo / pi * cos; a pure
    conductor at normal incidence/reflection gives F0 D G / (4 cos) with D = 1 / (pi alpha^2)."""
    material = M.load_material("ceramic")
    p = np.zeros((1, 12), np.float32)
    p[0, 0:3] = (0.2, 0.4, 0.6)
    p[0, 6:8] = 0.5                                   # flat
    l = np.array([[0.6, 0.0, 0.8]], np.float32)
    v = np.array([[0.0, 0.0, 1.0]], np.float32)
    got = _torch(material, p, l, v)
    np.testing.assert_allclose(got[0], np.array([0.2, 0.4, 0.6]) / math.pi * 0.8, rtol=1e-5)
    p[0, 8] = 1.0                                     # metallic; roughness channel 0 -> r = lo
    lo = material.constants["roughness_range"][0]
    alpha = max(lo * lo, M.ALPHA_MIN)
    got = _torch(material, p, v, v)
    np.testing.assert_allclose(got[0], np.array([0.2, 0.4, 0.6]) / (math.pi * alpha * alpha) / 4.0, rtol=1e-4)


def _ggx_pdf_sampler(rng, n, ax, ay):
    """n half vectors (local frame) with pdf D(h) h.z (anisotropic GGX): standard slopes scaled."""
    u1, u2 = rng.uniform(size=n), rng.uniform(size=n)
    r = np.sqrt(u1 / (1.0 - u1))
    sx, sy = ax * r * np.cos(2 * np.pi * u2), ay * r * np.sin(2 * np.pi * u2)
    h = np.stack([-sx, -sy, np.ones(n)], -1)
    return h / np.linalg.norm(h, axis=-1, keepdims=True)


def _ggx_d(h, ax, ay):
    q = (h[..., 0] / ax) ** 2 + (h[..., 1] / ay) ** 2 + h[..., 2] ** 2
    return 1.0 / (np.pi * ax * ay * q * q)


def _albedo(material, params, view, n, rng):
    """Directional albedo (integral of reflectance over light directions) of one texel: balance-heuristic
    MIS over three proposals with n samples each: uniform hemisphere, the base's GGX lobe around the
    shading normal, the coat's GGX lobe around z. Any exact proposal pdf keeps it unbiased; these
    keep the sharp lobes' variance small."""
    c = material.constants
    p = params.astype(np.float64)
    r = c["roughness_range"][0] + (c["roughness_range"][1] - c["roughness_range"][0]) * p[3]
    a = max(r * r, M.ALPHA_MIN)
    asp = math.sqrt(1 - c["anisotropy_max"] * p[4])
    ax, ay = max(a / asp, M.ALPHA_MIN), max(a * asp, M.ALPHA_MIN)
    rc = min(c["coat_roughness_range"][0] + (c["coat_roughness_range"][1] - c["coat_roughness_range"][0]) * p[10]
             + c["smudge_coat_roughness"] * p[11], 1.0)
    ac = max(rc * rc, M.ALPHA_MIN)
    s = (2 * p[6:8] - 1) * c["slope_scale"]
    nrm = np.array([-s[0], -s[1], 1.0]) / math.sqrt(s @ s + 1)
    phi = math.pi * p[5]
    t = np.array([math.cos(phi), math.sin(phi), 0.0])
    t = t - nrm * (nrm @ t)
    t /= np.linalg.norm(t)
    frame = np.stack([t, np.cross(nrm, t), nrm])          # rows: shading axes in the geometric frame
    v = view.astype(np.float64)
    z = rng.uniform(size=n)
    ph = 2 * np.pi * rng.uniform(size=n)
    uni = np.stack([np.sqrt(1 - z * z) * np.cos(ph), np.sqrt(1 - z * z) * np.sin(ph), z], -1)
    hb = _ggx_pdf_sampler(rng, n, ax, ay) @ frame
    hc = _ggx_pdf_sampler(rng, n, ac, ac)
    ls = [uni] + [2 * (h @ v)[:, None] * h - v for h in (hb, hc)]
    l = np.concatenate(ls)
    h = l + v
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    hs = h @ frame.T
    vh = np.abs(h @ v)
    pdf = (np.where(l[:, 2] > 0, 1 / (2 * np.pi), 0.0)
           + np.where(hs[:, 2] > 0, _ggx_d(hs, ax, ay) * hs[:, 2], 0.0) / (4 * vh)
           + np.where(h[:, 2] > 0, _ggx_d(h, ac, ac) * h[:, 2], 0.0) / (4 * vh))
    f = _torch(material, np.repeat(params[None], 3 * n, 0), l.astype(np.float32),
               np.repeat(view[None], 3 * n, 0)).astype(np.float64)
    ok = (l[:, 2] > 0) & (pdf > 0)
    return (f[ok] / pdf[ok, None]).sum(0) / n


def test_directional_albedo_at_most_one():
    """White furnace: the directional albedo (MC integral of reflectance over light directions)
    stays <= 1 + 1e-2 for random parameters with a white base, views from normal to grazing."""
    rng = np.random.default_rng(11)
    for name in MATERIALS:
        material = M.load_material(name)
        params = M.quantize(rng.uniform(0.0, 1.0, (16, 12)))
        params[:, 0:3] = 1.0                          # white: the worst case for energy
        params[:8, 8] = 1.0                           # half pure conductors
        params[:4, 3] = 0.0                           # the sharpest base lobes
        params[4:8, 10:12] = 0.0                      # the sharpest coats
        for cos_v in (1.0, 0.7, 0.3, 0.08):
            view = np.array([math.sqrt(1 - cos_v ** 2), 0.0, cos_v], np.float32)
            for p in params:
                albedo = _albedo(material, p, view, 10000, rng)
                assert albedo.max() <= 1.0 + 1e-2, (f"{name}: directional albedo {albedo.max():.4f} > 1 at "
                                                    f"view cos {cos_v}, params {p.tolist()}")
    # and the estimator is not trivially small: a white Lambert texel has albedo ~1
    p = np.zeros(12, np.float32)
    p[0:3], p[6:8] = 1.0, 0.5
    albedo = _albedo(M.load_material("ceramic"), p, np.array([0, 0, 1], np.float32), 20000, rng)
    np.testing.assert_allclose(albedo, 1.0, atol=0.02)


# --- textures ---------------------------------------------------------------------------------

@pytest.mark.parametrize("name", MATERIALS)
def test_bake_deterministic_and_quantized(name):
    material = M.load_material(name)
    a = M.bake_parameters(material, 64)
    b = M.bake_parameters(M.load_material(name), 64)
    assert a.shape == (64, 64, 12) and a.dtype == np.float32
    assert np.array_equal(a, b)
    k = np.round(a * 255.0)
    assert np.array_equal(a, k.astype(np.float32) / np.float32(255.0))
    assert k.min() >= 0 and k.max() <= 255
    # every channel a generator varies actually varies (the patterns are not silently empty)
    for c, ch in enumerate(M.CHANNELS):
        if material.generators[ch]["layers"]:
            assert a[..., c].std() > 0.0, f"{name}.{ch} is constant"
    # a different seed gives a different material
    other = M.Material(material.name, material.constants, material.generators, material.seed + 1)
    assert not np.array_equal(M.bake_parameters(other, 64), a)


def test_bake_size_independent_material():
    """Patterns live in uv: a 2x smaller bake is close to the box-filtered bigger one."""
    material = M.load_material("brushed_metal")
    big, small = M.bake_parameters(material, 128), M.bake_parameters(material, 64)
    boxed = R.mip_chain(big, 2)[1].numpy()
    smooth = [M.CHANNELS.index(c) for c in ("base_r", "base_g", "roughness", "coat_weight")]
    assert np.abs(boxed[..., smooth] - small[..., smooth]).mean() < 0.01


def test_png_round_trip(tmp_path):
    material = M.load_material("ceramic")
    paths = M.write_textures(material, 32, tmp_path)
    assert [p.name for p in paths] == ["param0.png", "param1.png", "param2.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["param0.png", "param1.png", "param2.png"]
    back = M.read_textures(tmp_path)
    raw = M.bake_parameters(material, 32)
    assert np.array_equal(back, raw)
    from PIL import Image
    with Image.open(paths[0]) as im:   # PNG row 0 is the top: v = 1, the array's last row
        assert im.mode == "RGBA"
        top = np.asarray(im)[0]
    assert np.array_equal(top, np.round(raw[-1, :, 0:4] * 255).astype(np.uint8))


def test_bad_descriptions(tmp_path):
    good = json.loads((M.MATERIALS_DIR / "ceramic.json").read_text())
    cases = [
        (lambda d: d["constants"].pop("coat_ior"), "constants.coat_ior"),
        (lambda d: d["constants"].__setitem__("anisotropy_max", 2.0), "constants.anisotropy_max"),
        (lambda d: d["constants"].__setitem__("roughness_range", [0.5]), "constants.roughness_range"),
        (lambda d: d["generators"].pop("mask"), "generators.mask"),
        (lambda d: d["generators"]["mask"]["layers"][0].__setitem__("pattern", "plaid"),
         "generators.mask.layers[0].pattern"),
        (lambda d: d["generators"]["mask"]["layers"][0].pop("radius"), "generators.mask.layers[0].radius"),
        (lambda d: d.__setitem__("seed", "x"), "seed"),
    ]
    for i, (edit, field) in enumerate(cases):
        d = json.loads(json.dumps(good))
        edit(d)
        path = tmp_path / f"bad{i}.json"
        path.write_text(json.dumps(d))
        with pytest.raises(ValueError) as err:
            M.load_material(path)
        assert str(path) in str(err.value) and field in str(err.value), str(err.value)
    with pytest.raises(ValueError, match="power of two"):
        M.bake_parameters(M.load_material("ceramic"), 100)
    with pytest.raises(ValueError, match="no description"):
        M.load_material("no_such_material")


def test_uniforms_cover_the_shader():
    names = set(M.uniforms(M.load_material("brushed_metal")))
    declared = {line.split()[2].rstrip(";") for line in CHUNK.read_text().splitlines()
                if line.startswith("uniform ") and "sampler" not in line}
    assert names == declared


# --- sampling ---------------------------------------------------------------------------------

def test_sample_parameters_texel_centres_and_levels():
    raw = M.bake_parameters(M.load_material("brushed_metal"), 16)
    chain = R.mip_chain(raw, 5)
    for level in range(5):
        n = 16 >> level
        j, i = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
        uv = np.stack([(i + 0.5) / n, (j + 0.5) / n], -1).astype(np.float32)
        got = R.sample_parameters(chain, torch.from_numpy(uv), level).numpy()
        np.testing.assert_allclose(got, chain[level].numpy(), atol=1e-6)
        # the box mip by hand (float64), independent of mip_chain
        f = 1 << level
        box = raw.astype(np.float64).reshape(n, f, n, f, 12).mean((1, 3))
        np.testing.assert_allclose(chain[level].numpy(), box, atol=1e-6)
    # repeat: uv + 1 is the same point; half way between two texels is their mean
    uv = torch.tensor([[0.5 / 16, 0.5 / 16], [1.0 + 0.5 / 16, -1.0 + 0.5 / 16], [1.0 / 16, 0.5 / 16],
                       [0.0, 0.5 / 16]])
    got = R.sample_parameters(chain, uv, 0).numpy()
    np.testing.assert_allclose(got[1], raw[0, 0], atol=1e-6)
    np.testing.assert_allclose(got[2], 0.5 * (raw[0, 0] + raw[0, 1]), atol=1e-6)
    np.testing.assert_allclose(got[3], 0.5 * (raw[0, 0] + raw[0, 15]), atol=1e-6)   # wraps across u = 0
    # fractional levels blend the two mips; a level-0 array builds its own chain
    half = R.sample_parameters(raw, uv, 0.5).numpy()
    np.testing.assert_allclose(half, 0.5 * (got + R.sample_parameters(chain, uv, 1).numpy()), atol=1e-6)


def _glsl_fetch(gl, raw, uv, lod):
    """na_fetch_parameters over [N, 2] uv at [N] lod, with the parameter textures uploaded as the
    scene binds its PNGs: RGBA8, GL-built mipmaps, trilinear, repeat."""
    import moderngl

    from inshade.runtime.programs import ProgramCache
    from inshade.runtime.render import FullscreenPass, float_target, read_rgba_raw, release_target, upload_float_texture

    size = raw.shape[0]
    k = np.round(raw * 255.0).astype(np.uint8)
    textures = {}
    for i in range(M.TEXTURES):
        tex = gl.texture((size, size), 4, np.ascontiguousarray(k[..., 4 * i:4 * i + 4]).tobytes())
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        tex.repeat_x = tex.repeat_y = True
        textures[f"u_na_param{i}"] = tex
    n = uv.shape[0]
    rows = np.zeros((1, n, 4), np.float32)
    rows[0, :, 0:2], rows[0, :, 2] = uv, lod
    cache = ProgramCache(gl)
    prog = cache.get("common/fullscreen.vert", "passes/na_fetch_test.frag",
                     chunks={"lib/na_reference": CHUNK.read_text()})
    inputs = upload_float_texture(gl, rows)
    fbo = float_target(gl, n, 1, 3)
    pass_ = FullscreenPass(gl, prog)
    gl.viewport = (0, 0, n, 1)
    try:
        pass_.render(fbo, textures={"u_inputs": inputs, **textures})
        return np.concatenate([read_rgba_raw(fbo, i).reshape(-1, 4)[:n] for i in range(3)], 1)
    finally:
        pass_.vao.release()
        inputs.release()
        for tex in textures.values():
            tex.release()
        release_target(fbo)
        cache.release()


def test_fetch_parameters_matches_sample_parameters(gl):
    """GL's fetch and the torch sampler agree on orientation, texel centres, wrap and mips. Bounds:
    level-0 texel centres exact (k / 255); GL stores each mip in 8 bits (<= 0.5 / 255 rounding per
    level built from the one above, so L / 255 at level L) and may filter with 8-bit weights
    (<= 1 / 256 of a neighbour difference per axis: 2 / 256)."""
    raw = M.bake_parameters(M.load_material("ceramic"), 16)
    chain = R.mip_chain(raw, 5)
    j, i = np.meshgrid(np.arange(16), np.arange(16), indexing="ij")
    uv = np.stack([(i.ravel() + 0.5) / 16, (j.ravel() + 0.5) / 16], -1).astype(np.float32)
    got = _glsl_fetch(gl, raw, uv, np.zeros(len(uv), np.float32))
    np.testing.assert_allclose(got, raw.reshape(-1, 12), atol=1e-6)
    rng = np.random.default_rng(2)
    uv = rng.uniform(-1.0, 2.0, (256, 2)).astype(np.float32)
    for level in (0, 1, 2, 4):
        got = _glsl_fetch(gl, raw, uv, np.full(len(uv), level, np.float32))
        ref = R.sample_parameters(chain, torch.from_numpy(uv), level).numpy()
        assert np.abs(got - ref).max() <= level / 255.0 + 2.0 / 256.0 + 1e-6, (level, np.abs(got - ref).max())


# --- LEAN prefiltering -------------------------------------------------------------------------

def _raw_with(rng, size, slopes: bool):
    raw = M.quantize(rng.uniform(0, 1, (size, size, 12)))
    raw[..., 3] = 0.2                                  # one roughness, anisotropy and direction
    raw[..., 4] = 0.5
    raw[..., 5] = 0.25
    if not slopes:
        raw[..., 6:8] = 0.6
    return raw


def test_lean_flat_normals_keep_level0():
    material = M.load_material("brushed_metal")
    raw = _raw_with(np.random.default_rng(0), 16, slopes=False)
    levels = M.parameter_pyramid(raw, 5, material)
    assert [lv.shape for lv in levels] == [(16 >> k, 16 >> k, M.ENCODER_INPUTS) for k in range(5)]
    ref = levels[0][0, 0]
    for lv in levels[1:]:
        for name in ("alpha_x", "alpha_y", "cos_2phi", "sin_2phi", "normal_x", "normal_y", "normal_z"):
            c = M.ENCODER_LAYOUT.index(name)
            np.testing.assert_allclose(lv[..., c], ref[c], rtol=1e-5, atol=1e-6, err_msg=name)
    # a constant material is the same at every level in every input
    const = np.broadcast_to(raw[:1, :1], raw.shape).copy()
    const_levels = M.parameter_pyramid(const, 5, material)
    for lv in const_levels[1:]:
        np.testing.assert_allclose(lv, np.broadcast_to(const_levels[0][:1, :1], lv.shape), rtol=1e-5, atol=1e-6)
    # level 0 decodes the texels: the normal from the slopes, unit length
    s = (2 * 0.6 - 1) * material.constants["slope_scale"]
    n = np.array([-s, -s, 1.0]) / math.sqrt(2 * s * s + 1)
    c = M.ENCODER_LAYOUT.index("normal_x")
    np.testing.assert_allclose(levels[0][0, 0, c:c + 3], n, rtol=1e-5)


def test_lean_bumpy_normals_widen_alphas():
    material = M.load_material("brushed_metal")
    raw = _raw_with(np.random.default_rng(1), 16, slopes=True)
    levels = M.parameter_pyramid(raw, 5, material)
    ax, ay = M.ENCODER_LAYOUT.index("alpha_x"), M.ENCODER_LAYOUT.index("alpha_y")
    a0x, a0y = levels[0][0, 0, ax], levels[0][0, 0, ay]
    assert np.allclose(levels[0][..., ax], a0x) and np.allclose(levels[0][..., ay], a0y)
    prev = (a0x, a0y)
    for lv in levels[1:]:
        assert np.all(lv[..., ax] > a0x) and np.all(lv[..., ay] > a0y)
        # coarser means at least as wide on average
        assert lv[..., ax].mean() >= prev[0] - 1e-6 and lv[..., ay].mean() >= prev[1] - 1e-6
        prev = (lv[..., ax].mean(), lv[..., ay].mean())
    # the coarsest level's alpha^2 is level 0's plus twice the slope variance along each axis
    phi = math.pi * 0.25
    s = (2.0 * raw[..., 6:8].astype(np.float64) - 1.0) * material.constants["slope_scale"]
    t = s[..., 0] * math.cos(phi) + s[..., 1] * math.sin(phi)
    b = -s[..., 0] * math.sin(phi) + s[..., 1] * math.cos(phi)
    np.testing.assert_allclose(levels[-1][0, 0, ax] ** 2, a0x ** 2 + 2 * t.var(), rtol=1e-4)
    np.testing.assert_allclose(levels[-1][0, 0, ay] ** 2, a0y ** 2 + 2 * b.var(), rtol=1e-4)
