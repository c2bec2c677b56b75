"""The shipped neural image: bundle, headless render through the real GL driver, files, training.

Tolerance: the GL render and the torch module (``GraphModule.from_bundle``) evaluated at the same
float32 pixel-centre uvs agree to ``ATOL = 1e-5`` absolute in linear RGB (measured ~6e-7 on Mesa
llvmpipe; the headroom is for GPU drivers whose sin/exp differ by a few ulp).

llvmpipe JIT-compiles the fragment shader at the first draw (tens of seconds for this network on
a busy 2-core machine), so the shipped bundle is rendered once per module with one program cache
and the tests share that render.
"""
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from inshade.bundle import load
from inshade.models.graph import GraphModule
from inshade.techniques.neural_image.train import main as train_main
from inshade.pixels import pixel_uvs
from inshade.techniques.neural_image.train import predict
from inshade.runtime.context import gl_info, shared_context
from inshade.runtime.headless import RenderSpecError, render_bundle, save_render
from inshade.scene.image_io import read_exr, write_png

SHIPPED = Path(__file__).resolve().parents[3] / "trained" / "neural_image"
ATOL = 1e-5
SIZE = 64


@pytest.fixture(scope="module")
def shipped():
    return load(SHIPPED)


@pytest.fixture(scope="module")
def rendered(shipped, program_cache):
    return render_bundle(shipped, width=SIZE, height=SIZE, cache=program_cache)


@pytest.fixture(scope="module")
def torch_reference(shipped):
    return predict(GraphModule.from_bundle(shipped).eval(), SIZE, SIZE)


def test_shipped_bundle_is_small_and_described(shipped):
    size = sum(f.stat().st_size for f in SHIPPED.iterdir() if f.name in ("bundle.json", "weights.safetensors"))
    assert size < 200_000
    assert shipped.meta["render"] == {"program": "passes/field2d.frag", "width": 256, "height": 256,
                                      "input": "uv", "output": "rgb"}
    m, p = shipped.meta["metrics"], shipped.meta["provenance"]
    for key in ("psnr_linear", "psnr_srgb", "mse_linear", "params", "train_seconds"):
        assert key in m
    assert m["psnr_linear"] > m["psnr_linear_step0"] + 5
    for key in ("command", "image", "steps", "seed", "torch", "date_utc"):
        assert key in p
    assert (SHIPPED / "preview.png").is_file() and (SHIPPED / "reference.png").is_file()


def test_shipped_asset_is_sharp_and_inside_the_envelope(shipped):
    """The first thing a newcomer renders: >= 30 dB linear PSNR against the 8-bit reference
    (measured on the exported, quantised bundle), built by `--preset ship`, and no parity-envelope
    warning (`inshade info` prints none)."""
    from inshade.envelope import analyse
    from inshade.techniques.neural_image.train import PRESETS

    m, p = shipped.meta["metrics"], shipped.meta["provenance"]
    assert m["psnr_linear"] >= 30.0 and m["psnr_srgb"] >= 30.0
    assert p["preset"] == "ship"
    for key, value in PRESETS["ship"].items():
        assert p[key] == value, key
    assert analyse(shipped).warnings == []


def test_presets_and_explicit_options():
    """`--preset` fills what is not given; an explicit option wins; the old arches still build."""
    import argparse

    import torch

    from inshade.techniques.neural_image.train import PRESETS, TRAINER, add_arguments, build

    parse = add_arguments(argparse.ArgumentParser()).parse_args
    quick = TRAINER.resolve(parse(["--preset", "quick"]))
    assert quick.steps == PRESETS["quick"]["steps"] and quick.levels == PRESETS["quick"]["levels"]
    mine = TRAINER.resolve(parse(["--preset", "ship", "--steps", "7", "--arch", "siren"]))
    assert mine.steps == 7 and mine.arch == "siren" and mine.width == PRESETS["ship"]["width"]
    uv = torch.rand(5, 2)
    for arch in ("siren", "frequency_relu", "multires"):
        g = build(arch, width=16, depth=1, levels="4:4,8:1", grid_bits=32).eval()
        again = GraphModule.from_bundle(g.export("neural_image")).eval()
        with torch.no_grad():
            assert torch.allclose(g(uv), again(uv))


def test_render_matches_torch(rendered, torch_reference):
    """(a) GL at 64x64 vs torch at the same pixel-centre uvs, linear RGB, atol 1e-5."""
    image, info = rendered
    assert image.shape == (SIZE, SIZE, 4) and image.dtype == np.float32
    np.testing.assert_allclose(image[..., :3], torch_reference, atol=ATOL, rtol=0)
    assert np.all(image[..., 3] == 1.0)
    assert info["render"]["width"] == SIZE and info["render"]["height"] == SIZE


def test_orientation_top_left_is_not_flipped(rendered, shipped):
    """(d) Row 0 of the render is the top of the picture: uv (0.5/W, 1 - 0.5/H)."""
    image, _ = rendered
    model = GraphModule.from_bundle(shipped).eval()
    import torch

    uv = pixel_uvs(SIZE, SIZE)
    assert np.allclose(uv[0, 0], [0.5 / SIZE, 1 - 0.5 / SIZE]) and np.allclose(uv[-1, 0], [0.5 / SIZE, 0.5 / SIZE])
    with torch.no_grad():
        top_left, bottom_left = model(torch.from_numpy(uv[[0, -1], 0])).numpy()
    np.testing.assert_allclose(image[0, 0, :3], top_left, atol=ATOL, rtol=0)
    np.testing.assert_allclose(image[-1, 0, :3], bottom_left, atol=ATOL, rtol=0)
    # The picture is not symmetric, so a flipped render would be caught.
    assert np.abs(image[::-1, :, :3] - image[..., :3]).mean() > 0.02


def test_full_size_render_matches_torch_preview(shipped, program_cache, tmp_path):
    """The 256x256 GL render encodes to the PNG torch wrote at training time (same program,
    so no second JIT): at most one 8-bit level apart (rounding at a .5 boundary)."""
    image, _ = render_bundle(shipped, cache=program_cache)
    assert image.shape == (256, 256, 4)
    preview = np.asarray(Image.open(SHIPPED / "preview.png").convert("RGB"), np.int16)
    ours = np.asarray(Image.open(write_png(tmp_path / "gl.png", image[..., :3])), np.int16)
    assert np.abs(ours - preview).max() <= 1


def test_save_render_writes_png_exr_and_sidecars(rendered, shipped, tmp_path):
    """(c) PNG (sRGB 8-bit) + EXR (linear float) + JSON sidecars naming driver and bundle."""
    image, info = rendered
    renderer = gl_info(shared_context())["renderer"]
    png, png_json = save_render(image, info, tmp_path / "shot.png")
    exr, exr_json = save_render(image, info, tmp_path / "shot.exr")
    assert png_json == tmp_path / "shot.png.json" and exr_json == tmp_path / "shot.exr.json"
    assert Image.open(png).size == (SIZE, SIZE)
    np.testing.assert_array_equal(read_exr(exr), image)
    for sidecar, fmt in ((png_json, "png"), (exr_json, "exr")):
        record = json.loads(sidecar.read_text())
        assert record["gl"]["renderer"] == renderer
        assert record["bundle"]["digest"] == shipped.digest()
        assert record["file"]["format"] == fmt
        assert record["timing_s"]["total"] > 0 and record["inshade_version"]
    with pytest.raises(ValueError, match="use .png or .exr"):
        save_render(image, info, tmp_path / "shot.jpg")


def test_bundle_without_render_field_is_refused(shipped):
    meta = {k: v for k, v in shipped.meta.items() if k != "render"}
    from inshade.bundle import Bundle

    bare = Bundle(dict(meta, name="no_render_here"), shipped.tensors)
    with pytest.raises(RenderSpecError, match="no_render_here.*does not say what it is.*--as image"):
        render_bundle(bare)


def test_tiny_training_run(tmp_path):
    """(b) 30 steps on a 32x32 target through the command entry: a valid bundle whose PSNR
    improved over step 0, plus preview and reference PNGs at the target size."""
    out = tmp_path / "ni"
    assert train_main(["--out", str(out), "--steps", "30", "--size", "32", "--seed", "1"]) == 0
    bundle = load(out)
    m = bundle.meta["metrics"]
    assert m["psnr_linear"] > m["psnr_linear_step0"]
    assert bundle.meta["render"]["width"] == 32 and bundle.meta["render"]["height"] == 32
    assert bundle.meta["provenance"]["steps"] == 30 and bundle.meta["provenance"]["seed"] == 1
    assert "--steps 30" in bundle.meta["provenance"]["command"]
    for name in ("preview.png", "reference.png"):
        assert Image.open(out / name).size == (32, 32)
    # Deterministic: the same seed gives the same weights.
    again = tmp_path / "again"
    train_main(["--out", str(again), "--steps", "30", "--size", "32", "--seed", "1"])
    other = load(again)
    assert all(np.array_equal(bundle.tensors[k], other.tensors[k]) for k in bundle.tensors)


def test_a_run_at_a_lower_precision_ends_with_a_quantization_aware_fine_tune(tmp_path):
    """--precision i8: the bundle's dense layers are int8 codes times row scales, the fine-tune after the
    fit raised the quantized network's PSNR, and metrics.json says both."""
    out = tmp_path / "ni8"
    assert train_main(["--out", str(out), "--steps", "30", "--size", "32", "--seed", "1", "--precision", "i8",
                       "--finetune-steps", "30"]) == 0
    bundle = load(out)
    assert {n.params.get("precision") for n in bundle.nodes if n.type == "dense"} == {"i8"}
    m = bundle.meta["metrics"]
    assert m["psnr_linear"] > m["psnr_linear_quantized_without_finetune"]
    recorded = json.loads((out / "metrics.json").read_text())["settings"]
    assert recorded["precision"] == "i8" and recorded["finetune_steps"] == 30
