"""inshade.metrics (PSNR, SSIM, sRGB, FLIP) and inshade.bench.codecs (ASTC / BC / ETC1 round trips)."""
import math
import subprocess
import sys

import numpy as np
import pytest

from inshade import metrics

from inshade.bench import codecs


def test_imports_are_cheap_and_torch_free():
    code = ("import sys, inshade.metrics, inshade.bench.codecs; "
            "bad = [m for m in ('torch', 'skimage', 'flip_evaluator', 'astc_encoder', 'etcpak') if m in sys.modules]; "
            "sys.exit(1 if bad else 0)")
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


# PSNR ------------------------------------------------------------------------------------------------

def test_psnr_of_a_known_mse():
    a = np.zeros((4, 4, 3))
    b = np.full((4, 4, 3), 0.1)                    # mse 0.01 -> 20 dB at peak 1
    assert metrics.psnr(a, b) == pytest.approx(20.0, abs=1e-12)
    assert metrics.psnr_from_mse(0.01) == pytest.approx(20.0, abs=1e-12)
    assert metrics.psnr_from_mse(1.0, peak=255.0) == pytest.approx(20 * math.log10(255.0), abs=1e-12)
    assert metrics.psnr(a, a) == math.inf and metrics.psnr_from_mse(0) == math.inf
    assert isinstance(metrics.psnr(a, b), float)


def test_psnr_matches_the_direct_formula_bit_for_bit():
    rng = np.random.default_rng(0)
    a8 = rng.integers(0, 256, (9, 11, 3), dtype=np.uint8)
    b8 = np.clip(a8.astype(int) + rng.integers(-3, 4, a8.shape), 0, 255).astype(np.uint8)
    mse = float(np.mean((a8.astype(np.float64) - b8.astype(np.float64)) ** 2))
    assert metrics.psnr(a8, b8, 255.0) == 10.0 * math.log10(255.0 ** 2 / mse)
    a, b = rng.random((9, 11, 3)).astype(np.float32), rng.random((9, 11, 3)).astype(np.float32)
    mask = rng.random((9, 11)) > 0.5
    d = a.astype(np.float64)[mask] - b.astype(np.float64)[mask]
    assert metrics.mse(a, b, mask) == float(np.mean(d ** 2))
    assert metrics.psnr(a, b, mask=mask) == 10.0 * math.log10(1.0 / float(np.mean(d ** 2)))
    # the mask selects pixels: an error outside it does not count
    c = a.copy()
    c[~mask] += 0.5
    assert metrics.psnr(a, c, mask=mask) == math.inf


def test_psnr_of_tensors_uses_torch_in_float64():
    import torch

    rng = np.random.default_rng(1)
    a, b = (torch.from_numpy(rng.random((64, 3)).astype(np.float32)) for _ in range(2))
    expect = 10.0 * math.log10(0.49 / float(torch.mean((a.double() - b.double()) ** 2)))
    assert metrics.psnr(a, b, 0.7) == expect
    mask = torch.arange(64) % 2 == 0
    assert metrics.psnr(a, b, mask=mask) == metrics.psnr(a[mask], b[mask])


# SSIM ------------------------------------------------------------------------------------------------

def test_ssim():
    from skimage.metrics import structural_similarity

    rng = np.random.default_rng(2)
    ref = rng.random((16, 16, 3))
    img = np.clip(ref + rng.normal(0, 0.05, ref.shape), 0, 1)
    assert metrics.ssim(ref, ref) == pytest.approx(1.0)
    got = metrics.ssim(img, ref)
    assert 0.0 < got < 1.0
    assert got == float(structural_similarity(ref, img, data_range=1.0, channel_axis=-1, win_size=7))
    assert [metrics.ssim_window(n, 20) for n in (3, 4, 5, 6, 7, 30)] == [1, 3, 3, 5, 7, 7]
    assert 0.0 < metrics.ssim(img[:5, :5], ref[:5, :5]) <= 1.0      # small images get a smaller window


# sRGB ------------------------------------------------------------------------------------------------

def test_srgb_known_values_and_round_trip():
    assert metrics.srgb_oetf(0.0) == 0.0 and metrics.srgb_oetf(1.0) == pytest.approx(1.0, abs=1e-12)
    assert metrics.srgb_eotf(0.5) == pytest.approx(((0.5 + 0.055) / 1.055) ** 2.4)
    assert metrics.srgb_eotf(0.04) == pytest.approx(0.04 / 12.92)          # the linear toe
    assert metrics.srgb_oetf(0.002) == pytest.approx(0.002 * 12.92)
    assert metrics.srgb_oetf(0.18) == pytest.approx(0.4613561295004, abs=1e-9)   # mid grey
    x = np.linspace(0.0, 1.0, 1001)
    np.testing.assert_allclose(metrics.srgb_oetf(metrics.srgb_eotf(x)), x, atol=1e-12)
    np.testing.assert_allclose(metrics.srgb_eotf(metrics.srgb_oetf(x)), x, atol=1e-12)
    # clipped to [0, 1], float64 out
    assert metrics.srgb_oetf(np.float32(2.0)).dtype == np.float64
    np.testing.assert_array_equal(metrics.srgb_eotf(np.array([-1.0, 3.0])), [0.0, 1.0])
    # the two branches meet (continuity at the thresholds)
    assert metrics.srgb_eotf(0.04045) == pytest.approx(((0.04045 + 0.055) / 1.055) ** 2.4, rel=1e-4)


# FLIP ------------------------------------------------------------------------------------------------

def test_flip():
    assert metrics.flip_unavailable() is None   # flip-evaluator is a test requirement ([bench])
    rng = np.random.default_rng(3)
    ref8 = rng.integers(0, 256, (32, 32, 3), dtype=np.uint8)
    assert metrics.flip(ref8, ref8) == pytest.approx(0.0, abs=1e-6)
    noisy = np.clip(ref8.astype(int) + rng.integers(-40, 41, ref8.shape), 0, 255).astype(np.uint8)
    e = metrics.flip(ref8, noisy)
    assert 0.0 < e < 1.0
    assert metrics.flip(ref8.astype(np.float32) / 255.0, noisy.astype(np.float32) / 255.0) == e


# codecs ----------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def photo8():
    from skimage import data

    return np.ascontiguousarray(data.astronaut()[100:164, 180:244])      # 64x64 RGB8


def _run(fn, *args):
    return fn(*args)   # astc-encoder-py and etcpak are test requirements ([bench]): a CodecError fails


@pytest.mark.parametrize("block", [4, 6, 8, 12])
def test_astc_roundtrip(photo8, block):
    r = _run(codecs.astc_roundtrip, photo8, block)
    blocks = math.ceil(64 / block) ** 2
    assert r.nbytes == 16 * blocks and r.bpp == 128.0 * blocks / (64 * 64)
    assert r.image.shape == photo8.shape and r.image.dtype == np.uint8
    decoded, nbytes = r                                           # unpacks as (image, bytes)
    assert nbytes == r.nbytes
    p = metrics.psnr(r.image, photo8, 255.0)
    assert 20.0 < p < 60.0
    rgba = _run(codecs.astc_roundtrip, codecs.to_rgba8(photo8), block)
    assert rgba.image.shape == (64, 64, 4)
    np.testing.assert_array_equal(rgba.image[..., :3], r.image)


@pytest.mark.parametrize("fn, bpp", [(codecs.bc1_roundtrip, 4.0), (codecs.bc7_roundtrip, 8.0),
                                     (codecs.etc1_roundtrip, 4.0)])
def test_block_codecs(photo8, fn, bpp):
    r = _run(fn, photo8)
    assert r.bpp == bpp and r.nbytes == 64 * 64 * bpp / 8
    assert r.image.shape == photo8.shape and r.image.dtype == np.uint8
    p = metrics.psnr(r.image, photo8, 255.0)
    assert 22.0 < p < 60.0, p


def test_codec_rank_and_errors(photo8):
    bc1 = metrics.psnr(_run(codecs.bc1_roundtrip, photo8).image, photo8, 255.0)
    bc7 = metrics.psnr(_run(codecs.bc7_roundtrip, photo8).image, photo8, 255.0)
    assert bc7 > bc1                                              # twice the bits
    with pytest.raises(codecs.CodecError, match="multiple of the 4x4 block"):
        codecs.bc1_roundtrip(photo8[:30])
    with pytest.raises(ValueError, match="unknown BC codec"):
        codecs.bc_roundtrip(photo8, "BC9")
    assert issubclass(codecs.CodecError, RuntimeError)


def test_etc1_decoder_on_a_hand_made_block():
    # differential mode, no flip: base (16, 8, 31) 5-bit, delta (+1, -1, 0); tables 0 and 7;
    # all pixel indices 0 (+small modifier) except pixel (x=3, y=0): index 3 (-large)
    r, g, b = 16, 8, 31
    word = (r << 59) | (1 << 56) | (g << 51) | (7 << 48) | (b << 43) | (0 << 40) | (0 << 37) | (7 << 34) | (1 << 33)
    p = 3 * 4 + 0
    word |= (1 << (16 + p)) | (1 << p)
    img = codecs.etc1_decode(word.to_bytes(8, "big"), 4, 4)
    e = lambda v: (v << 3) | (v >> 2)                             # noqa: E731 - 5 -> 8 bits
    left = np.array([e(16), e(8), e(31)]) + 2                     # table 0, index 0: +2
    right = np.array([e(17), e(7), e(31)]) + 47                   # table 7, index 0: +47
    np.testing.assert_array_equal(img[:, :2], np.broadcast_to(np.clip(left, 0, 255), (4, 2, 3)))
    np.testing.assert_array_equal(img[1:, 2:], np.broadcast_to(np.clip(right, 0, 255), (3, 2, 3)))
    np.testing.assert_array_equal(img[0, 2], np.clip(right, 0, 255))
    np.testing.assert_array_equal(img[0, 3], np.clip(np.array([e(17), e(7), e(31)]) - 183, 0, 255))
