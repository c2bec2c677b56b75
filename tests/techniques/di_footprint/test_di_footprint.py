"""DI footprint-aware sampler (techniques/di_footprint/train.py, passes/footprint_plane.frag,
`inshade bench di_footprint --quick`).

Parity (DI path): the pass writes the network's inputs (fract uv, log2 footprint) of every pixel to a
second target beside the colour, because the footprint comes from dFdx/dFdy and cannot be recomputed
off the GPU; torch then evaluates the same bundle on exactly those inputs, and the exact LUT path
must agree within tests/parity.py's rule (1e-5). The emulated trilinear sampler (the training
target) is checked against GL's own trilinear filtering at the same LOD (FOOTPRINT_MODE
explicit_lod) within the 8-bit filter-weight bound stated in `test_emulated_trilinear_matches_gl`.
"""
import json
import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from inshade.techniques.di_footprint import bench
from inshade.techniques.di_footprint import train as fp
from inshade.models import footprint_sampler as sampler
from inshade.models import texture_cascade as tc

from parity import assert_parity

SIZE = 32
VIEW = (64, 32)


def _texture(size=SIZE, seed=0):
    """A small high-frequency RGB texture (8-bit values), row 0 = top."""
    y, x = np.mgrid[0:size, 0:size] / size
    img = np.stack([0.5 + 0.45 * np.sin(2 * np.pi * 5 * x), 0.5 + 0.45 * np.cos(2 * np.pi * 3 * y),
                    0.5 + 0.4 * np.sin(2 * np.pi * (4 * x + 7 * y + seed))], -1)
    return (np.round(img * 255) / 255).astype(np.float32)


@pytest.fixture(scope="module")
def trained():
    return fp.train_sampler(_texture(), 1.5, n_cascaded=4, steps=150, batch=1024, progress=False)


# the emulated trilinear sampler ---------------------------------------------------------------

def test_mip_chain_box_means():
    tex = torch.from_numpy(_texture())
    chain = sampler.mip_chain(tex, round_bits=None)
    assert [c.shape[0] for c in chain] == [32, 16, 8, 4, 2, 1]
    for c in chain[1:]:
        assert torch.allclose(c.mean((0, 1)), tex.mean((0, 1)), atol=1e-6)
    assert torch.allclose(chain[1][0, 0], tex[:2, :2].reshape(-1, 3).mean(0))
    q = sampler.mip_chain(tex)    # 8-bit levels
    assert all(torch.equal(torch.round(c * 255) / 255, c) for c in q)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 5), st.integers(0, 2 ** 31 - 1))
def test_integer_lod_is_bilinear_of_that_level(level, seed):
    tex = torch.from_numpy(_texture())
    chain = sampler.mip_chain(tex)
    gen = torch.Generator().manual_seed(seed)
    uv = torch.rand(64, 2, generator=gen) * 4 - 2         # any real uv: GL_REPEAT
    lf = torch.full((64,), level - math.log2(SIZE))
    out = sampler.emulated_trilinear(chain, uv, lf)
    assert torch.allclose(out, sampler.bilinear_repeat(chain[level], uv), atol=1e-6)


def test_lod_clamps_like_gl():
    tex = torch.from_numpy(_texture())
    chain = sampler.mip_chain(tex)
    uv = torch.rand(32, 2)
    mag = sampler.emulated_trilinear(chain, uv, torch.full((32,), -20.0))
    assert torch.allclose(mag, sampler.bilinear_repeat(chain[0], uv), atol=1e-6)
    far = sampler.emulated_trilinear(chain, uv, torch.full((32,), 20.0))
    assert torch.allclose(far, chain[-1].reshape(1, 3).expand(32, 3), atol=1e-6)
    half = sampler.emulated_trilinear(chain, uv, torch.full((32,), 2.5 - math.log2(SIZE)))
    mix = 0.5 * (sampler.bilinear_repeat(chain[2], uv) + sampler.bilinear_repeat(chain[3], uv))
    assert torch.allclose(half, mix, atol=1e-6)


def test_footprint_distribution_half_in_lod0_and_stratified_uv():
    gen = torch.Generator().manual_seed(0)
    lf = sampler.sample_log2_footprint(200_000, 256, gen)
    frac0 = float((sampler.gl_lod(lf, 256) <= 0).float().mean())     # lambda <= 0: LOD 0
    assert abs(frac0 - sampler.P_LOD0) < 0.01
    assert sampler.footprint_exponent(256) == pytest.approx(8.0)
    tex = torch.from_numpy(_texture())
    x, y = next(sampler.footprint_sampler(tex, SIZE * SIZE, seed=3))
    cells = (x[:, 1] * SIZE).floor() * SIZE + (x[:, 0] * SIZE).floor()
    assert torch.equal(torch.sort(cells).values, torch.arange(SIZE * SIZE, dtype=torch.float32))
    assert y.shape == (SIZE * SIZE, 3)


# sizing and bad input -----------------------------------------------------------------------

@pytest.mark.parametrize("ratio", [3, 6, 12])
def test_plan_fits_budget(ratio):
    s = sampler.plan(256, 3, ratio)
    assert s.bytes <= 256 * 256 * 3 / ratio
    assert s.n_primary % 8 == 0 and s.n_cascaded % 4 == 0
    assert s.n_lod == 9 and s.n_footprint == 4 * s.n_lod
    assert s.bytes == 3 * s.n_primary ** 2 + s.n_footprint + 3 * s.n_cascaded ** 3 * s.n_lod


def test_bad_input_is_one_clear_error():
    with pytest.raises(sampler.FootprintError, match="cannot be met"):
        sampler.plan(32, 3, 50)
    with pytest.raises(sampler.FootprintError, match="power of two"):
        sampler.plan(48, 3, 2)
    with pytest.raises(sampler.FootprintError, match="multiple of 4"):
        sampler.plan(256, 3, 6, n_cascaded=6)
    with pytest.raises(sampler.FootprintError, match="power of two.*--size"):
        fp.load_texture("skimage:chelsea", 48)              # square after --size, but 48 is no power of two
    with pytest.raises(tc.CompressionError, match="not square"):
        fp.load_texture("skimage:chelsea", None)
    with pytest.raises(tc.CompressionError):
        fp.load_texture("skimage:nonexistent_image", 32)
    with pytest.raises(sampler.FootprintError, match="expected"):
        fp.train_sampler(np.zeros((32, 16, 3), np.float32), 1.5)
    assert issubclass(sampler.FootprintError, ValueError)


def test_cli_rejects_bad_steps(tmp_path, capsys):
    assert fp.main(["--out", str(tmp_path / "x"), "--steps", "-1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("inshade: error: --steps"), err
    assert not (tmp_path / "x").exists()


# training, export, parity ---------------------------------------------------------------------

def test_training_improves_and_exports_8bit(trained):
    m = trained.metrics
    assert m["psnr_float"] > m["psnr_step0"] + 3
    assert m["bytes"] <= SIZE * SIZE * 3 / 1.5
    b = trained.bundle
    assert b.kind == "di_footprint"
    assert [(p.name, p.dim) for p in b.inputs] == [("uv", 2), ("log2_footprint", 1)]
    assert all(b.node(n).params["bits"] == 8 for n in ("primary", "lod_primary", "cascaded"))
    assert b.node("cascaded").params["resolution"] == [4, 4, 4, 6]
    assert set(m["psnr_per_lod"]) == {str(i) for i in range(6)}


def _eroded_hit(inputs):
    hit = np.pad(inputs[..., 3] > 0.5, 1)
    h, w = inputs.shape[:2]
    out = np.ones((h, w), bool)
    for dy in range(3):
        for dx in range(3):
            out &= hit[dy:dy + h, dx:dx + w]
    return out


def _camera():
    from inshade.scene.camera import camera_from_dict

    return camera_from_dict(sampler.CAMERA)


def _plane(gl, trained, *modes):
    """The plane pass in each of ``modes``: {mode: (colour, the shader's inputs)}."""
    r = bench.PlaneRenderer(gl, trained.bundle, np.ascontiguousarray(trained.image[::-1]), "exact")
    try:
        return {m: r.render(m, _camera(), *VIEW, 1.0, sampler.EXTENT) for m in modes}
    finally:
        r.release()


def test_di_pass_matches_torch_on_the_shaders_inputs(gl, trained):
    colour, inputs = _plane(gl, trained, "di")["di"]
    hit = inputs[..., 3] > 0.5
    assert hit.mean() > 0.3 and (~hit).any()                  # plane and sky both in view
    lf = inputs[..., 2][hit]
    assert lf.max() - lf.min() > 3                             # a range of footprints (LODs)
    ref = bench.di_reference(trained.bundle, inputs)
    assert_parity(colour[..., :3][hit], ref[hit], what="DI footprint pass (exact) vs torch")
    assert np.all(colour[..., 3][~hit] == 0)


def test_emulated_trilinear_matches_gl(gl, trained):
    """GL trilinear at the same LOD (explicit_lod) vs the emulation. Bound: llvmpipe (and many
    GPUs) filter with 8 fractional weight bits, so each of the three lerps (u, v, between levels)
    may be off by 2^-8 of the largest adjacent difference (<= 1), and the driver's
    glGenerateMipmap is not our box-and-round chain bit for bit (llvmpipe blits with a linear
    filter: measured up to 2 8-bit steps off, biased up by 0.3-1.3 steps on average per level):
    3 * 2^-8 + 2/255 ~ 0.0196; the mean stays within one 8-bit step."""
    tex = np.ascontiguousarray(trained.image[::-1])
    colour, inputs = _plane(gl, trained, "explicit_lod")["explicit_lod"]
    mask = _eroded_hit(inputs)
    chain = sampler.mip_chain(torch.from_numpy(tex))
    x = torch.from_numpy(np.ascontiguousarray(inputs[..., :3][mask]))
    emulated = sampler.emulated_trilinear(chain, x[:, :2], x[:, 2]).numpy()
    gl_encoded = bench.encoded(colour[mask])
    err = np.abs(gl_encoded - emulated)
    assert err.max() <= 3 * 2 ** -8 + 2 / 255
    assert err.mean() <= 1 / 255


def test_gl_modes_render_and_differ(gl, trained):
    out = {m: colour for m, (colour, _) in _plane(gl, trained, "trilinear", "bilinear").items()}
    for img in out.values():
        assert np.isfinite(img).all()
    assert np.abs(out["trilinear"] - out["bilinear"]).max() > 0.05   # mips blur what bilinear aliases


def test_asset_folder_renders_with_the_scene_renderer(gl, trained, tmp_path):
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    out = fp.write_asset(trained, tmp_path / "di_footprint", preview_size=VIEW)
    for f in ("bundle.json", "weights.safetensors", "scene.json", "preview.png", "texture.png"):
        assert (out / f).is_file()
    scene = load_scene(out)
    r = SceneRenderer(scene, gl)
    try:
        r.render(scene.make_camera("steeper"), *VIEW)
        img = r.read()
    finally:
        r.release()
    assert np.isfinite(img).all() and img[..., 3].max() == 1.0


def test_bench_quick(gl, tmp_path):
    assert bench.main(["--quick", "--out", str(tmp_path)]) == 0
    result = json.loads((tmp_path / "di_footprint.json").read_text())
    modes = {r["mode"]: r for r in result["rows"]}
    assert set(modes) >= {"di", "di_fast", "trilinear", "anisotropic", "bilinear"}
    assert result["parity_exact_max_abs_diff"] <= 1e-5
    assert result["machine"]["gl_renderer"]
    assert modes["di"]["bytes"] < modes["trilinear"]["bytes"]
    for f in ("di_footprint.md", "di_footprint.png", "di_footprint_views.png"):
        assert (tmp_path / f).is_file()
