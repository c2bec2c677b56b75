"""neural_appearance end to end: the quick preset trains an asset; the pass renders it and agrees
with the torch twin (techniques/neural_appearance/twin.py); every view and lighting mode draws;
checkpoints resume only their own run; the CLI renders with --spp."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from inshade.metrics import psnr_from_mse

W, H = 96, 72


@pytest.fixture(scope="module")
def asset(tmp_path_factory):
    from inshade.techniques.neural_appearance.train import train

    out = tmp_path_factory.mktemp("na") / "neural_appearance_test"
    train(material="ceramic", preset="quick", out=out, steps1=20, steps2=20, write_preview=False, progress=False)
    return out


def test_asset_holds_every_network_and_the_material(asset):
    from inshade.bundle import load
    from inshade.scene.description import load_scene
    from inshade.techniques.neural_appearance import KIND, NETWORKS

    for folder, _prefix in NETWORKS:
        assert load(asset / folder).kind == KIND
    node = next(n for n in load(asset / "latents").nodes if n.type == "latent_pyramid")
    assert (node.params["resolution"], node.params["levels"], node.params["channels"]) == (32, 6, 8)
    assert node.params["precision"] == "f16"
    lat = load(asset / "latents").tensors
    assert all(np.array_equal(lat[f"pyramid.level{k}"], lat[f"pyramid.level{k}"].astype(np.float16).astype(np.float32))
               for k in range(6))
    scene = load_scene(asset)
    assert scene.mesh is not None and scene.spec.accumulate
    metrics = json.loads((asset / "metrics.json").read_text())
    assert metrics["command"].startswith("inshade train neural_appearance --material ceramic --preset quick")
    assert not (asset / "checkpoint.safetensors").exists()


def _render(asset, settings, spp=1, camera=None):
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(asset)
    r = SceneRenderer(scene, settings={"decoder": 16, **settings})   # 2x16 unless asked: llvmpipe JITs it in seconds
    cam = scene.make_camera(camera)
    try:
        r.accumulate(cam, W, H, spp)
        image = r.read("network")
        gbuffer = r.gbuffer.read()
    finally:
        r.release()
    return scene, cam, image, gbuffer


@pytest.mark.parametrize("decoder", [16, 64])
def test_pass_matches_torch_twin(asset, decoder):
    """One sample, scene lights: GL against the torch twin on the same G-buffer, >= 50 dB."""
    from inshade.techniques.neural_appearance.twin import render_lights

    scene, cam, image, gbuffer = _render(asset, {"view": "neural", "lighting": "lights", "decoder": decoder,
                                                 "lights": 2})
    data = json.loads((asset / "scene.json").read_text())
    twin, covered = render_lights(asset, gbuffer, cam, W, H, lights=data["lights"], decoder=decoder, light_count=2)
    gl = image[::-1, :, :3]          # read() is image orientation; the twin keeps data orientation
    assert covered.mean() > 0.2      # the teapot fills a good part of the view
    assert np.isfinite(gl).all()
    err = float(((gl - twin)[covered] ** 2).mean())
    peak = float(twin[covered].max())
    assert peak > 0.01
    assert psnr_from_mse(err / peak ** 2) >= 50.0


@pytest.mark.parametrize("settings", [
    {"view": "reference"}, {"view": "split"}, {"view": "error"}, {"view": "level"}, {"view": "latents", "latent_page": 2},
    {"lighting": "environment", "sampling": "learned"}, {"lighting": "environment", "sampling": "isotropic", "mis": False},
    {"lighting": "environment", "sampling": "cosine", "view": "reference"}])
def test_every_view_and_lighting_draws(asset, settings):
    _, _, image, _ = _render(asset, settings, spp=2)
    covered = image[..., 3] > 0
    assert covered.any() and np.isfinite(image).all()
    assert image[covered][:, :3].max() > 0


def test_environment_estimate_converges_the_same_with_every_sampler(asset):
    """Learned, isotropic and cosine BRDF sampling (with MIS) estimate the same integral: their
    16-sample means agree far better than their difference to zero (the estimators are unbiased)."""
    means = {}
    for s in ("learned", "isotropic", "cosine"):
        _, _, image, _ = _render(asset, {"lighting": "environment", "sampling": s, "view": "reference"}, spp=16)
        means[s] = float(image[image[..., 3] > 0][:, :3].mean())
    assert means["learned"] > 0
    for s in ("isotropic", "cosine"):
        assert abs(means[s] - means["learned"]) < 0.1 * means["learned"], means


def test_checkpoint_belongs_to_its_run(tmp_path):
    import torch

    from inshade.techniques.neural_appearance.model import NeuralMaterial
    from inshade.techniques.neural_appearance.train import _load_checkpoint, _optimizer, _restore, _save_checkpoint

    model = NeuralMaterial(20, 8, 4)
    opt = _optimizer(model, 1, 1e-3, 1e-2)
    model.decoders["2x16"](torch.zeros(1, 14)).sum().backward()
    opt.step()
    path = tmp_path / "checkpoint.safetensors"
    _save_checkpoint(path, model, opt, 1, 7, {"a": 1})
    phase, step, tensors, groups = _load_checkpoint(path, {"a": 1})
    assert (phase, step) == (1, 7)
    other = NeuralMaterial(20, 8, 4)
    opt2 = _optimizer(other, 1, 1e-3, 1e-2)
    _restore(other, opt2, tensors, groups)
    for (k, a), (_, b) in zip(model.state_dict().items(), other.state_dict().items()):
        assert torch.equal(a, b), k
    with pytest.raises(ValueError, match="config.a"):
        _load_checkpoint(path, {"a": 2})


def test_cli_render_with_spp(asset, tmp_path):
    out = tmp_path / "teapot.png"
    proc = subprocess.run([sys.executable, "-m", "inshade.cli", "render", str(asset), "-o", str(out), "--spp", "3",
                           "--width", str(W), "--height", str(H), "--set", "lighting=environment"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    sidecar = json.loads(out.with_name(out.name + ".json").read_text())
    assert sidecar["spp"] == 3


def test_networks_that_together_exceed_a_limit_are_one_clear_error(asset):
    """Six networks of ubo weights: codegen plans each alone; the renderer checks their sum."""
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import SceneError, load_scene

    scene = load_scene(asset)
    with pytest.raises(SceneError, match="uniform blocks together; GL_MAX_FRAGMENT_UNIFORM_BLOCKS is 8"):
        SceneRenderer(scene, settings={"storage": "ubo", "decoder": 16},
                      limits={"GL_MAX_FRAGMENT_UNIFORM_BLOCKS": 8})


def test_asset_without_its_material_is_one_clear_error(asset, tmp_path):
    import shutil

    broken = tmp_path / "broken"
    shutil.copytree(asset, broken)
    (broken / "material.json").unlink()
    proc = subprocess.run([sys.executable, "-m", "inshade.cli", "render", str(broken), "-o", str(tmp_path / "x.png")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("inshade: error:") and "material" in lines[0], proc.stderr


@pytest.mark.parametrize("network", ["latents", "decoder_2x16", "decoder_3x64", "sampler", "sampler_isotropic"])
def test_trained_networks_match_torch_under_the_rule(gl, asset, network):
    """The shipped pipeline's own networks (frames + MLP + expm1, MLP + proxy activation, the fp16
    pyramid on the exact path) through the real driver against their torch twins."""
    from parity import check_parity, unit_directions, uniform_inputs

    from inshade.bundle import load

    bundle = load(asset / network)
    n = 512
    if network == "latents":
        uv = uniform_inputs(1, n, 2, -0.5, 1.5)      # beyond [0, 1): the repeat wrap
        x = np.concatenate([uv, np.random.default_rng(2).integers(0, 6, (n, 1))], 1)
    else:
        z = np.asarray(load(asset / "latents").tensors["pyramid.level0"]).reshape(-1, 8)[:n]
        dirs = [unit_directions(3 + k, n) for k in range(2)]
        dirs = [np.where(d[:, 2:] < 0, d * [1, 1, -1], d) for d in dirs]   # the upper hemisphere, as drawn
        x = np.concatenate([z, *dirs] if network.startswith("decoder") else [z, dirs[1]], 1)
    check_parity(gl, bundle, x.astype(np.float32), what=network)


def test_a_lower_precision_ends_with_a_quantization_aware_fine_tune(tmp_path, gl):
    """--precision i8: the fit ends with --finetune-steps seen through the quantizer; the asset's decoders
    are int8 rows, its latents u8 codes (the very values the fine-tune saw: the twin of the bundle is
    what the holdout measured), the holdout before the fine-tune recorded beside the one after, and
    the networks hold the parity rule."""
    from parity import check_parity, unit_directions

    from inshade.bundle import load
    from inshade.techniques.neural_appearance.train import train

    out = tmp_path / "neural_appearance_i8"
    train(material="ceramic", preset="quick", out=out, steps1=10, steps2=10, precision="i8", finetune_steps=10,
          write_preview=False, progress=False)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["settings"]["precision"] == "i8" and metrics["settings"]["finetune_steps"] == 10
    history = metrics["history"]
    assert set(history["holdout_quantized_without_finetune"]) == set(history["holdout"]) == {"level0", "level1",
                                                                                              "level2"}
    latents, decoder = load(out / "latents"), load(out / "decoder_2x16")
    assert latents.node("pyramid").params["precision"] == "u8"
    assert {n.params["precision"] for n in decoder.nodes if n.type == "dense"} == {"i8"}
    z = np.asarray(latents.tensors["pyramid.level0"]).reshape(-1, 8)[:256].astype(np.float32)
    z = latents.tensors["pyramid.offset"] + latents.tensors["pyramid.scale"] * (z / 255)   # the decoded codes
    dirs = [unit_directions(7 + k, 256) for k in range(2)]
    dirs = [np.where(d[:, 2:] < 0, d * [1, 1, -1], d) for d in dirs]
    check_parity(gl, decoder, np.concatenate([z, *dirs], 1).astype(np.float32), what="i8 decoder")
