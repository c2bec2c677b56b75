"""3D textures with mip chains and 2D texture arrays (codegen/glsl.py TextureResource ``mips`` in
3D, ``array``; runtime/network.py ``texture_levels`` / ``_make_texture`` / ``_check_fits``) through
the real driver: every level of every slice / layer reads back exactly with texelFetch (uint32 and
float16 / float32), hardware bilinear sampling of an array layer matches numpy, and malformed
chains or oversized textures are refused naming the resource (and level)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from inshade.codegen.glsl import TextureResource
from inshade.codegen.limits import LimitError
from inshade.runtime.network import NetworkResources, _check_fits, _make_texture, texture_levels
from inshade.runtime.programs import ProgramCache
from inshade.runtime.render import FullscreenPass, float_target, read_rgba_raw, release_target, upload_float_texture

from parity import parity_settings
from test_texture_mips import HW_FILTER_TOL, TEXEL_RANGE, bilinear

FEW = parity_settings(5)


class _Generated:
    def __init__(self, resources):
        self.resources = resources


@pytest.fixture
def cache(gl):
    c = ProgramCache(gl)
    yield gl, c
    c.release()


def _pass(gl, cache, *, array: bool, uint: bool, sample: bool = False) -> FullscreenPass:
    defines = {k: 1 for k, on in (("TEX_ARRAY", array), ("TEX_UINT", uint), ("TEX_SAMPLE", sample)) if on}
    return FullscreenPass(gl, cache.get("common/fullscreen.vert", "passes/texture_layers_test.frag", defines=defines))


def fetch_level(gl, p: FullscreenPass, tex, level: int, shape: tuple, uint: bool) -> np.ndarray:
    """texelFetch of every texel of ``level`` (shape [D or L, H, W, C]) -> [D, H, W, 4]."""
    d, h, w = shape[:3]
    fbo = float_target(gl, w, d * h, formats=("rgba32ui" if uint else "rgba32f",))
    try:
        gl.viewport = (0, 0, w, d * h)
        p.render(fbo, uniforms={"u_level": level, "u_rows": h}, textures={"u_tex": tex})
        raw = np.frombuffer(fbo.read(components=4, dtype="u4" if uint else "f4"), np.uint32 if uint else np.float32)
        return raw.reshape(d, h, w, 4)
    finally:
        release_target(fbo)


def chain(rng, shape: tuple, levels: int, *, lead: int, uint: bool) -> list[np.ndarray]:
    """A random chain: each level halves the axes after the first ``lead`` (layers stay)."""
    out = []
    for k in range(levels):
        s = (*shape[:lead], *(max(n >> k, 1) for n in shape[lead:-1]), shape[-1])
        out.append(rng.integers(0, 2 ** 32, s, dtype=np.uint32) if uint
                   else rng.uniform(-TEXEL_RANGE, TEXEL_RANGE, s).astype(np.float16))
    return out


def full_levels(*sides: int) -> int:
    return max(sides).bit_length()


def check_every_level(gl, cache, res: TextureResource, levels: list[np.ndarray], uint: bool) -> None:
    p = _pass(gl, cache, array=res.array, uint=uint)
    tex = _make_texture(gl, res)
    try:
        assert gl.error == "GL_NO_ERROR"
        for k, want in enumerate(levels):
            got = fetch_level(gl, p, tex, k, want.shape, uint)[..., : want.shape[-1]]
            np.testing.assert_array_equal(got, want.astype(got.dtype), err_msg=f"{res.name} level {k}")
    finally:
        tex.release()
        p.vao.release()


# --- 3D mip chains ---------------------------------------------------------------------------------

@FEW
@given(d=st.integers(1, 6), h=st.integers(1, 6), w=st.integers(1, 6), seed=st.integers(0, 2 ** 31 - 1),
       uint=st.booleans(), data=st.data())
def test_3d_chain_reads_back_exactly_per_level(cache, d, h, w, seed, uint, data):
    """uint32 R (usampler3D, as a voxel slot grid is) and float16 RGBA 3D chains, possibly stopping
    before 1x1x1: texelFetch(t, ivec3, k) at every texel of level k equals the numpy level."""
    gl, c = cache
    levels = data.draw(st.integers(1, full_levels(d, h, w)), label="levels")
    lv = chain(np.random.default_rng(seed), (d, h, w, 1 if uint else 4), levels, lead=0, uint=uint)
    res = TextureResource("t_vol", lv[0], "u4" if uint else "f2", mips=tuple(lv[1:]))
    check_every_level(gl, c, res, lv, uint)


def test_3d_chain_of_float32_is_stored_as_given_dtype(cache):
    """float32 data with dtype 'f2' is rounded to float16 like the 2D path (texture_levels casts)."""
    gl, c = cache
    lv = [a.astype(np.float32) for a in chain(np.random.default_rng(3), (4, 2, 8, 3), 3, lead=0, uint=False)]
    res = TextureResource("t_vol32", lv[0], "f2", mips=tuple(lv[1:]))
    assert [a.dtype for a in texture_levels(res)] == [np.float16] * 3
    check_every_level(gl, c, res, [a.astype(np.float16) for a in lv], uint=False)


@pytest.mark.parametrize("mips, message", [
    ((np.zeros((2, 2, 2, 1), np.uint32),), r"texture t_bad3: mip level 1 must be \[D, H, W, C\] = \[2, 2, 1, 1\]"),
    ((np.zeros((2, 2, 1, 1), np.uint32), np.zeros((1, 1, 1, 1), np.uint32), np.zeros((1, 1, 1, 1), np.uint32)),
     r"texture t_bad3: mip level 3: the chain already ends at 1x1x1 \(level 2\)"),
])
def test_bad_3d_chains_are_refused_naming_resource_and_level(gl, mips, message):
    res = TextureResource("t_bad3", np.zeros((4, 4, 3, 1), np.uint32), "u4", mips=mips)
    with pytest.raises(ValueError, match=message):
        NetworkResources(gl, _Generated([res]))


# --- 2D texture arrays -------------------------------------------------------------------------------

@FEW
@given(layers=st.integers(1, 5), h=st.integers(1, 6), w=st.integers(1, 6), seed=st.integers(0, 2 ** 31 - 1),
       dtype=st.sampled_from(["f4", "f2", "u4"]), channels=st.integers(1, 4), data=st.data())
def test_array_layers_read_back_exactly(cache, layers, h, w, seed, dtype, channels, data):
    """Every layer (and every level of a per-layer mip chain) of an f4 / f2 / u4 array fetched
    with texelFetch(t, ivec3(x, y, layer), k) equals numpy."""
    gl, c = cache
    levels = data.draw(st.integers(1, full_levels(h, w)), label="levels")
    rng = np.random.default_rng(seed)
    uint = dtype == "u4"
    lv = chain(rng, (layers, h, w, channels), levels, lead=1, uint=uint)
    if dtype == "f4":
        lv = [rng.standard_normal(a.shape).astype(np.float32) for a in lv]
    res = TextureResource("t_arr", lv[0], dtype, mips=tuple(lv[1:]), array=True)
    assert (res.dims, res.layers) == (2, layers)
    check_every_level(gl, c, res, lv, uint)


@FEW
@given(seed=st.integers(0, 2 ** 31 - 1), wrap=st.sampled_from(["repeat", "clamp"]))
def test_array_linear_sampling_is_bilinear_within_the_layer(cache, seed, wrap):
    """texture(sampler2DArray, vec3(uv, layer)): bilinear within that layer (layers hold unrelated
    values: a blend across layers would show), wrap as asked, within the hardware-filter bound."""
    gl, c = cache
    rng = np.random.default_rng(seed)
    data = rng.uniform(-TEXEL_RANGE, TEXEL_RANGE, (3, 6, 5, 4)).astype(np.float16)
    tex = _make_texture(gl, TextureResource("t_lin", data, "f2", "linear", wrap=wrap, array=True))
    p = _pass(gl, c, array=True, uint=False, sample=True)
    uv = rng.uniform(-1.0, 2.0, (4, 6, 2))
    layer = rng.integers(0, 3, (4, 6))
    coords = upload_float_texture(gl, np.concatenate([uv, layer[..., None], np.zeros((4, 6, 1))], -1))
    fbo = float_target(gl, 6, 4)
    try:
        gl.viewport = (0, 0, 6, 4)
        p.render(fbo, uniforms={"u_level": 0}, textures={"u_tex": tex, "u_coords": coords})
        got = read_rgba_raw(fbo)
        want = np.stack([bilinear(data[layer[y, x]], uv[y, x], wrap) for y in range(4) for x in range(6)]).reshape(got.shape)
        np.testing.assert_allclose(got, want, atol=HW_FILTER_TOL, rtol=0)
    finally:
        release_target(fbo)
        coords.release()
        tex.release()
        p.vao.release()


def test_array_limits_name_the_resource(gl):
    """Layers are checked against GL_MAX_ARRAY_TEXTURE_LAYERS, sides against GL_MAX_TEXTURE_SIZE
    (a layer count above the side limit is fine: layers are not a side)."""
    cap_layers = int(gl.info["GL_MAX_ARRAY_TEXTURE_LAYERS"])
    cap_side = int(gl.info["GL_MAX_TEXTURE_SIZE"])
    many = TextureResource("t_many", np.lib.stride_tricks.as_strided(np.zeros(1, np.float32), (cap_layers + 1, 1, 1, 1),
                                                                     (0, 0, 0, 0)), "f4", array=True)
    with pytest.raises(LimitError, match=rf"texture t_many .*: {cap_layers + 1} layers; .*GL_MAX_ARRAY_TEXTURE_LAYERS"):
        _check_fits(gl, many)
    wide = TextureResource("t_wide", np.lib.stride_tricks.as_strided(np.zeros(1, np.float32), (1, 1, cap_side + 1, 1),
                                                                     (0, 0, 0, 0)), "f4", array=True)
    with pytest.raises(LimitError, match=rf"texture t_wide .*: a side of {cap_side + 1} texels; .*GL_MAX_TEXTURE_SIZE"):
        _check_fits(gl, wide)


def test_array_shape_and_chain_errors_name_the_field():
    with pytest.raises(ValueError, match=r"texture t_a: a texture array's data is \[L, H, W, C\], got \[4, 4, 1\]"):
        TextureResource("t_a", np.zeros((4, 4, 1), np.float32), "f4", array=True)
    res = TextureResource("t_a", np.zeros((3, 4, 4, 1), np.float32), "f4", mips=(np.zeros((1, 2, 2, 1), np.float32),),
                          array=True)
    with pytest.raises(ValueError, match=r"texture t_a: mip level 1 must be \[L, H, W, C\] = \[3, 2, 2, 1\]"):
        texture_levels(res)



@FEW
@given(h=st.integers(1, 6), w=st.integers(1, 6), seed=st.integers(0, 2 ** 31 - 1), data=st.data())
def test_2d_uint_chain_reads_back_exactly(cache, h, w, seed, data):
    """A 2D u4 chain (build_mipmaps' glGenerateMipmap refuses integer formats, so it takes the
    direct path too): usampler2D texelFetch per level equals numpy."""
    gl, c = cache
    levels = data.draw(st.integers(1, full_levels(h, w)), label="levels")
    lv = chain(np.random.default_rng(seed), (h, w, 2), levels, lead=0, uint=True)
    p = FullscreenPass(gl, c.get("common/fullscreen.vert", "passes/texture_layers_test.frag",
                                 defines={"TEX_2D": 1, "TEX_UINT": 1}))
    tex = _make_texture(gl, TextureResource("t_u2d", lv[0], "u4", mips=tuple(lv[1:])))
    try:
        for k, want in enumerate(lv):
            got = fetch_level(gl, p, tex, k, (1, *want.shape), uint=True)[0, ..., :2]
            np.testing.assert_array_equal(got, want, err_msg=f"level {k}")
    finally:
        tex.release()
        p.vao.release()
