"""Mip-chained and half-float texture resources (codegen/glsl.py TextureResource ``mips``,
``wrap``, dtype 'f2'; runtime/network.py ``_make_texture``) through the real driver: every level
uploaded exactly as given, ``textureLod`` at an integer level bilinear within that level only,
repeat vs clamp at the border, and malformed chains refused with the resource and level named."""
from __future__ import annotations

import moderngl
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from inshade.codegen.glsl import TextureResource
from inshade.runtime.network import NetworkResources, _make_texture
from inshade.runtime.render import float_target, read_rgba_raw, release_target, upload_float_texture

# Program compiles dominate on llvmpipe: few, small examples.
FEW = settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

# Hardware bilinear filtering uses low-precision weights (8 fractional bits on many GPUs): a weight
# may be off by up to 1/256 per axis (truncated), an error up to 2 * |largest texel difference| / 256.
# Texels lie in [-0.06, 0.06] (differences <= 0.12), so the bound is ~9.4e-4 < 1e-3; a read of the
# wrong level or texel is off by ~0.05, far beyond it.
HW_FILTER_TOL = 1e-3
TEXEL_RANGE = 0.06


class _Generated:
    def __init__(self, resources):
        self.resources = resources


def make_chain(rng, h: int, w: int, levels: int, c: int = 4) -> list[np.ndarray]:
    return [rng.uniform(-TEXEL_RANGE, TEXEL_RANGE, (max(h >> k, 1), max(w >> k, 1), c)).astype(np.float16)
            for k in range(levels)]


def full_levels(h: int, w: int) -> int:
    return max(h, w).bit_length()


def bilinear(level: np.ndarray, uv: np.ndarray, wrap: str) -> np.ndarray:
    """GL's bilinear lookup of ``level`` [H, W, C] (data orientation: texel (x, y) = level[y, x]) at
    ``uv`` [..., 2], float64 weights; ``wrap`` 'repeat' or 'clamp' (to edge)."""
    h, w = level.shape[:2]
    x = uv[..., 0] * w - 0.5
    y = uv[..., 1] * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]

    def idx(i, n):
        i = i.astype(np.int64)
        return np.mod(i, n) if wrap == "repeat" else np.clip(i, 0, n - 1)

    t = level.astype(np.float64)
    xa, xb, ya, yb = idx(x0, w), idx(x0 + 1, w), idx(y0, h), idx(y0 + 1, h)
    return ((1 - fy) * ((1 - fx) * t[ya, xa] + fx * t[ya, xb]) + fy * ((1 - fx) * t[yb, xa] + fx * t[yb, xb]))


@pytest.fixture
def mip_pass(gl, fullscreen_test_pass):
    return gl, fullscreen_test_pass("passes/texture_mips_test.frag")


def draw(gl, p, tex, level: int, uvs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(texelFetch at ``level``, textureLod at ``uvs`` and ``level``) over a target uvs.shape[:2]."""
    h, w = uvs.shape[:2]
    uv_tex = upload_float_texture(gl, np.concatenate([uvs, np.zeros((h, w, 2))], -1))
    fbo = float_target(gl, w, h, 2)
    try:
        gl.viewport = (0, 0, w, h)
        p.render(fbo, uniforms={"u_level": level}, textures={"u_tex": tex, "u_inputs": uv_tex})
        return read_rgba_raw(fbo, 0), read_rgba_raw(fbo, 1)
    finally:
        release_target(fbo)
        uv_tex.release()


@FEW
@given(h=st.integers(1, 12), w=st.integers(1, 12), seed=st.integers(0, 2 ** 31 - 1), data=st.data())
def test_every_level_reads_back_exactly(mip_pass, h, w, seed, data):
    """A float16 RGBA chain (possibly stopping before 1x1) reads back per level bit for bit."""
    gl, p = mip_pass
    levels = data.draw(st.integers(1, full_levels(h, w)), label="levels")
    chain = make_chain(np.random.default_rng(seed), h, w, levels)
    res = TextureResource("t_mips", chain[0], "f2", "linear", mips=tuple(chain[1:]))
    tex = _make_texture(gl, res)
    try:
        assert tex.dtype == "f2" and tex.size == (w, h)
        for k, want in enumerate(chain):
            hk, wk = want.shape[:2]
            fetched, _ = draw(gl, p, tex, k, np.zeros((hk, wk, 2)))
            np.testing.assert_array_equal(fetched, want.astype(np.float32), err_msg=f"level {k}")
    finally:
        tex.release()


@FEW
@given(seed=st.integers(0, 2 ** 31 - 1), wrap=st.sampled_from(["repeat", "clamp"]),
       levels=st.integers(1, 4), from_f32=st.booleans())
def test_texture_lod_is_bilinear_within_the_level(mip_pass, seed, wrap, levels, from_f32):
    """textureLod at integer level k: bilinear within level k only (levels hold unrelated values,
    so any blend with a neighbouring level would show), with the resource's wrap mode. float32
    data with dtype 'f2' is stored as float16 (the reference rounds it the same way)."""
    gl, p = mip_pass
    rng = np.random.default_rng(seed)
    chain = make_chain(rng, 16, 8, levels)
    given_chain = [c.astype(np.float32) for c in chain] if from_f32 else chain
    res = TextureResource("t_lod", given_chain[0], "f2", "linear", mips=tuple(given_chain[1:]), wrap=wrap)
    tex = _make_texture(gl, res)
    try:
        assert tex.filter == (moderngl.LINEAR_MIPMAP_NEAREST if levels > 1 else moderngl.LINEAR, moderngl.LINEAR)
        uvs = rng.uniform(-1.0, 2.0, (5, 7, 2))   # outside [0, 1] too: the wrap mode matters
        for k in range(levels):
            _, got = draw(gl, p, tex, k, uvs)
            want = bilinear(chain[k], uvs, wrap)
            np.testing.assert_allclose(got, want, atol=HW_FILTER_TOL, rtol=0, err_msg=f"level {k}, {wrap}")
    finally:
        tex.release()


def test_repeat_and_clamp_differ_at_the_border(mip_pass):
    """At u = 0 (the left edge, between texel 0 and its left neighbour), repeat blends texel 0 half
    and half with the last texel of the row; clamp-to-edge gives texel 0 alone."""
    gl, p = mip_pass
    level = np.zeros((2, 4, 4), np.float16)
    level[:, 0] = 0.5
    level[:, 3] = 0.25   # the texel repeat wraps to
    uvs = np.array([[[0.0, 0.25]]])   # row 0's centre in v, the edge in u
    got = {}
    for wrap in ("repeat", "clamp"):
        tex = _make_texture(gl, TextureResource(f"t_{wrap}", level, "f2", "linear", mips=(level[:1, :2],),
                                                wrap=wrap))
        try:
            got[wrap] = draw(gl, p, tex, 0, uvs)[1][0, 0]
            assert (tex.repeat_x, tex.repeat_y) == ((True, True) if wrap == "repeat" else (False, False))
        finally:
            tex.release()
    np.testing.assert_allclose(got["repeat"], 0.375, atol=HW_FILTER_TOL)
    np.testing.assert_allclose(got["clamp"], 0.5, atol=HW_FILTER_TOL)


def test_nearest_filter_reads_the_nearest_texel_of_the_level(mip_pass):
    """filter 'nearest' with mips: NEAREST_MIPMAP_NEAREST; textureLod at level 1 is a texel of level 1."""
    gl, p = mip_pass
    chain = make_chain(np.random.default_rng(7), 8, 8, 3)
    tex = _make_texture(gl, TextureResource("t_nearest", chain[0], "f2", "nearest", mips=tuple(chain[1:])))
    try:
        assert tex.filter == (moderngl.NEAREST_MIPMAP_NEAREST, moderngl.NEAREST)
        uvs = (np.stack(np.meshgrid(np.arange(4), np.arange(4)), -1) + 0.5) / 4   # uvs[y, x] = texel (x, y) centre
        _, got = draw(gl, p, tex, 1, uvs)
        np.testing.assert_array_equal(got, chain[1].astype(np.float32))
    finally:
        tex.release()


@pytest.mark.parametrize("mips, message", [
    ((np.zeros((4, 4, 4), np.float16),), r"texture t_bad: mip level 1 must be \[H, W, C\] = \[4, 3, 4\]"),
    ((np.zeros((4, 3, 4), np.float16), np.zeros((2, 1, 3), np.float16)),
     r"texture t_bad: mip level 2 must be \[H, W, C\] = \[2, 1, 4\]"),
    ((np.zeros((4, 3, 4), np.float16), np.zeros((2, 1, 4), np.float16), np.zeros((1, 1, 4), np.float16),
      np.zeros((1, 1, 4), np.float16)), r"texture t_bad: mip level 4: the chain already ends at 1x1 \(level 3\)"),
])
def test_bad_chains_are_refused_naming_resource_and_level(gl, mips, message):
    res = TextureResource("t_bad", np.zeros((8, 6, 4), np.float16), "f2", "linear", mips=mips)
    with pytest.raises(ValueError, match=message):
        NetworkResources(gl, _Generated([res]))


def test_bad_wrap_dtype_and_3d_chain_shape_are_refused(gl):
    base = np.zeros((4, 4, 4), np.uint8)
    with pytest.raises(ValueError, match=r"texture t_u8: mip level 1 is uint16; level 0 is uint8"):
        NetworkResources(gl, _Generated([TextureResource("t_u8", base, "f1", mips=(np.zeros((2, 2, 4), np.uint16),))]))
    with pytest.raises(ValueError, match=r"texture t_wrap: wrap must be 'clamp' or 'repeat', got 'mirror'"):
        NetworkResources(gl, _Generated([TextureResource("t_wrap", base, "f1", wrap="mirror")]))
    # 3D chains: tests/runtime/test_texture_arrays.py
    with pytest.raises(ValueError, match=r"texture t_3d: mip level 1 must be \[D, H, W, C\] = \[1, 1, 1, 4\]"):
        NetworkResources(gl, _Generated([TextureResource("t_3d", np.zeros((2, 2, 2, 4), np.float16), "f2",
                                                         mips=(np.zeros((1, 1, 4), np.float16),))]))


def test_nbytes_counts_every_level():
    chain = make_chain(np.random.default_rng(0), 8, 4, 3)
    res = TextureResource("t", chain[0], "f2", mips=tuple(chain[1:]))
    assert res.nbytes == 2 * 4 * (8 * 4 + 4 * 2 + 2 * 1)
