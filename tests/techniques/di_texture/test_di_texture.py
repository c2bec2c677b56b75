"""DI texture compression (models/texture_cascade.py, techniques/di_texture/train.py) and `inshade bench di_texture --quick`."""
from pathlib import Path

import numpy as np
import pytest

from inshade.metrics import psnr
from inshade.models import texture_cascade as tc
from inshade.runtime.network import evaluate_on_pixels
from inshade.techniques.di_texture import train as trainer

ROOT = Path(__file__).resolve().parents[3]
ASSETS = ["di_texture_astronaut", "di_texture_chelsea", "di_texture_coffee", "di_texture_astronaut_12x"]


def _tiny_image(size=32):
    y, x = np.mgrid[0:size, 0:size] / (size - 1)
    img = np.stack([x, y, 0.5 + 0.4 * np.sin(6 * x) * np.cos(5 * y)], -1)
    return (img * 255).round().astype(np.uint8)


@pytest.mark.parametrize("ratio", [3, 6, 12, 24])
def test_sizing_fits_budget(ratio):
    shape = (256, 256, 3)
    s = tc.plan(shape, ratio)
    budget = tc.uncompressed_bytes(shape) / ratio
    assert s.bytes <= budget
    assert s.n_primary % 8 == 0 and s.n_cascaded % 4 == 0
    assert s.bytes == 4 * s.n_primary ** 2 + 3 * s.n_cascaded ** 4


def test_ratio_that_cannot_be_met():
    with pytest.raises(tc.CompressionError, match="cannot be met"):
        tc.plan((32, 32, 3), 100)
    with pytest.raises(tc.CompressionError, match=">= 1"):
        tc.plan((32, 32, 3), 0.5)


def test_tiny_compression_improves_and_glsl_matches_torch(gl, tmp_path):
    result = tc.compress(_tiny_image(), 3, steps=120, batch=1024, measure=trainer.decoded_metrics)
    m = result.metrics
    assert m["psnr_quantised"] > m["psnr_step0"] + 5
    assert m["ratio"] >= 3
    assert m["max_abs_diff_glsl_exact_vs_torch"] <= 1e-5
    assert m["psnr_srgb8_glsl_exact"] == pytest.approx(m["psnr_srgb8_torch"], abs=0.05)
    b = result.bundle
    assert b.kind == "di_texture" and b.inputs[0].semantic == "uv" and b.outputs[0].dim == 3
    assert all(b.node(n).params["bits"] == 8 for n in ("primary", "cascaded"))
    out = trainer.write_asset(result, tmp_path / "tiny", "tiny")
    for f in ("bundle.json", "weights.safetensors", "scene.json", "preview.png", "reference.png"):
        assert (out / f).is_file()


def test_finish_optimizer_lbfgs_and_paper_protocol():
    """On a small texture "lbfgs" finishes better than "adam" at the same budget; finish 0 (the
    paper's protocol) ignores the finish optimiser; an unknown one is one clear error."""
    img = _tiny_image()
    run = lambda **kw: tc.compress(img, 3, steps=80, batch=512, **{"finish": 0.5, "init": "ramp", **kw}).metrics
    adam, lbfgs = run(finish_optimizer="adam"), run(finish_optimizer="lbfgs")
    assert lbfgs["finish_optimizer"] == "lbfgs" and lbfgs["finish_steps"] == 40
    assert lbfgs["psnr_float"] > adam["psnr_float"]
    paper = [run(finish=0.0, finish_optimizer=o) for o in ("adam", "lbfgs")]
    assert paper[0]["psnr_quantised"] == paper[1]["psnr_quantised"]
    assert paper[0]["history"][-1]["step"] == 80
    with pytest.raises(tc.CompressionError, match="unknown finish optimizer"):
        tc.compress(img, 3, steps=1, finish_optimizer="sgd")


def test_pca_init_is_the_image_at_the_primary_resolution():
    """The "pca" starting point: the cascaded array is exactly the affine map from the primary's
    coordinates to colours along the image's principal axes (multilinear interpolation keeps
    it affine), and the primary holds the image's coordinates on them, so step 0 decodes a
    blurred copy of the image -- where the paper's ramp decodes its mean colour."""
    import torch

    from inshade.models.lookup_array import multilinear

    img = _tiny_image(64).astype(np.float32) / 255
    flipped = np.ascontiguousarray(img[::-1])
    primary, cascaded = tc.pca_init(flipped, 24, 4)
    assert primary.shape == (24, 24, 4) and cascaded.shape == (4, 4, 4, 4, 3)
    assert float(primary.min()) >= 0 and float(primary.max()) <= 1
    p = torch.rand(500, 4, generator=torch.Generator().manual_seed(1))
    # affine: the value at p equals the corner-0 value plus the per-axis steps
    corner = multilinear(cascaded, torch.zeros(1, 4))
    steps = [multilinear(cascaded, torch.eye(4)[i:i + 1]) - corner for i in range(4)]
    affine = corner + sum(p[:, i:i + 1] * steps[i] for i in range(4))
    assert torch.allclose(multilinear(cascaded, p), affine, atol=1e-5)
    assert float(steps[3].abs().max()) == 0.0          # 3 colour axes; the 4th channel keeps the ramp
    ramp = tc.compress(img, 3, steps=0, finish=0.0, init="ramp").metrics["psnr_step0"]
    pca = tc.compress(img, 3, steps=0, finish=0.0, init="pca").metrics["psnr_step0"]
    assert pca > ramp + 10 and pca > 25


# bad input: handled with a note, or one clear error --------------------------------------

def test_non_square_rejected_unless_size_given():
    img = np.zeros((40, 64, 3), np.uint8)
    with pytest.raises(tc.CompressionError, match="not square.*--size"):
        tc.prepare_image(img)
    out, notes = tc.prepare_image(img, size=32)
    assert out.shape == (32, 32, 3) and any("centre-cropped" in n for n in notes)


def test_odd_size_handled():
    out, notes = tc.prepare_image(np.zeros((33, 33, 3), np.uint8))
    assert out.shape == (33, 33, 3) and any("odd size" in n for n in notes)


def test_16bit_converted_with_note():
    img = (np.arange(32 * 32 * 3).reshape(32, 32, 3) * 60).astype(np.uint16)
    out, notes = tc.prepare_image(img)
    assert out.dtype == np.float32 and out.max() <= 1 and any("16-bit" in n for n in notes)


def test_grayscale_is_one_channel(gl):
    out, notes = tc.prepare_image(np.zeros((64, 64), np.uint8))
    assert out.shape == (64, 64, 1) and any("grayscale" in n for n in notes)
    assert tc.plan(out.shape, 3).bytes <= 64 * 64 / 3   # budget of the 1-channel original


def test_alpha_opaque_dropped_translucent_rejected():
    img = np.full((32, 32, 4), 255, np.uint8)
    out, notes = tc.prepare_image(img)
    assert out.shape[-1] == 3 and any("alpha" in n for n in notes)
    img[0, 0, 3] = 10
    with pytest.raises(tc.CompressionError, match="translucent alpha"):
        tc.prepare_image(img)


def test_other_bad_inputs():
    with pytest.raises(tc.CompressionError, match="smaller than"):
        tc.prepare_image(np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(tc.CompressionError, match="at most 8"):
        tc.prepare_image(np.zeros((16, 16, 9), np.uint8))
    with pytest.raises(tc.CompressionError, match="float images"):
        tc.prepare_image(np.full((16, 16, 3), 2.0))
    with pytest.raises(tc.CompressionError, match="no image"):
        tc.load_image("skimage:not_an_image")


def test_cli_reports_one_line_error(tmp_path, capsys):
    from inshade.cli import main

    assert main(["compress", "skimage:astronaut", "--ratio", "100000", "-o", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("inshade: error:") and "cannot be met" in err[-1]


# shipped assets ----------------------------------------------------------------------------

@pytest.mark.parametrize("name", ASSETS)
def test_shipped_asset_renders_like_torch(gl, name):
    from inshade import bundle as bundle_mod
    from inshade.runtime.headless import render_scene

    folder = ROOT / "trained" / name
    assert sum(f.stat().st_size for f in folder.iterdir()) < 300_000
    b = bundle_mod.load(folder)
    m = b.meta["metrics"]
    assert b.kind == "di_texture" and m["ratio"] >= 6 and "command" in b.meta["provenance"]
    ref = tc.torch_decode(b, 64)
    image, info = render_scene(folder, width=64, height=64, settings={"lut_filter": "exact"})
    assert np.max(np.abs(image[..., :3] - ref)) <= 1e-5
    # Hardware filtering: chaining the per-array bound of tests/components/test_lookup_array.py (d 2^-8 D)
    # through a trained cascade is vacuous (its cascaded cells step by up to ~2 between neighbours),
    # so the fast path is held to what the asset records: its PSNR cost (re-measured here), within
    # 0.5 dB of the exact path (the cascade's range is bounded for that: texture_cascade.CASCADED_RANGE).
    # A broken fast path (wrong texel centres, channel order) costs 10+ dB.
    assert m["psnr_srgb8_glsl_exact"] - m["psnr_srgb8_glsl_fast"] < 0.5
    lo, hi = tc.CASCADED_RANGE
    offset, scale = np.asarray(b.tensors["cascaded.offset"]), np.asarray(b.tensors["cascaded.scale"])
    assert np.all(offset >= lo - 1e-6) and np.all(offset + scale <= hi + 1e-6)


# benchmark -----------------------------------------------------------------------------------

def test_bench_quick_writes_files(gl, tmp_path):
    from inshade.techniques.di_texture import bench as di

    assert di.main(["--quick", "--out", str(tmp_path)]) == 0
    for f in ("di_texture.json", "di_texture.md", "di_texture.png"):
        assert (tmp_path / f).is_file()
    import json

    result = json.loads((tmp_path / "di_texture.json").read_text())
    entries = result["images"][0]["entries"]
    assert {e["codec"] for e in entries} >= {"DI (exact)", "DI (fast)", "ASTC 4x4", "BC1", "BC7"}
    for e in entries:   # every baseline either measured or unavailable with a reason
        assert e["available"] or e["reason"]
    exact = next(e for e in entries if e["codec"] == "DI (exact)")
    assert exact["max_abs_diff_vs_torch"] <= 1e-5
