"""neural_appearance --gltf: a glTF file's material learnt as a neural material and shown on the
file's mesh next to the file's own shading.

- the quick preset trains from the procedural tiles torus (through the command line) and writes the
  file byte-identical as the scene's mesh, the bundles and the render PSNR against the reference;
- the training targets are the reference: the BRDF the trainer evaluates (gltf_source.py), at the
  G-buffer's surfaces in the frame gltf_surface builds, reproduces the GL reference's lit pixels;
- the split view's left half is exactly what ``inshade render source.glb`` (the gltf_pbr pass) draws
  at the same camera and settings, its right half the neural view's pixels;
- an anisotropic material of the showcase (brushed metal, a direction texture) trains too, and the
  file's other materials stay the reference on the neural side;
- bad input: no TEXCOORD_0, an unreadable file, a material index the file does not have: one
  ``inshade: error:`` line, exit 2, no folder.

Sizes: the quick preset (32x32 latents, 30 + 30 steps) and the metric renders at 2 samples per
pixel with the 2x32 decoder (the scene's default; llvmpipe compiles it in seconds), so each test
stays well under a minute here. Render PSNR floors (display values, the learnt material's pixels),
measured on this machine (llvmpipe, CPU training) with those sizes: tiles torus 21.8 dB lights only,
17.0 dB shaded; brushed metal 22.9 dB and 17.8 dB. The same runs without a training step (0 + 0
steps) give 16.4 / 13.3 dB and 16.0 / 12.5 dB: the floors (20 / 15.5 and 20.5 / 15.5) sit between.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from inshade.techniques.neural_appearance import GLTF_PROGRAM, KIND, NETWORKS

SPP = 2


def _train(source, out, *extra):
    from inshade.techniques.neural_appearance.train import main

    code = main(["--gltf", str(source), "--preset", "quick", "--out", str(out), "--no-preview",
                 "--render-spp", str(SPP), *extra])
    assert code == 0
    return out


@pytest.fixture(scope="module")
def torus(tmp_path_factory):
    from inshade.geometry import gltf_scenes

    folder = tmp_path_factory.mktemp("na_gltf")
    glb = gltf_scenes.tiles_torus().write(folder / "tiles_torus.glb")
    return glb, _train(glb, folder / "neural_appearance_tiles_torus")


@pytest.fixture(scope="module")
def metal(tmp_path_factory):
    from inshade.geometry import gltf_scenes

    folder = tmp_path_factory.mktemp("na_gltf_showcase")
    glb = gltf_scenes.showcase().write(folder / "showcase.glb")
    return glb, _train(glb, folder / "neural_appearance_showcase_1", "--material", "1")


def _render(asset, settings, spp=1, camera=None):
    """(image [H, W, 4] linear, image orientation; G-buffer; camera; scene) of the asset's scene
    (``camera``: a camera dict, default the scene's)."""
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.camera import camera_from_dict
    from inshade.scene.description import load_scene

    scene = load_scene(asset)
    camera = scene.make_camera() if camera is None else camera_from_dict(camera)
    r = SceneRenderer(scene, settings=settings)
    try:
        r.accumulate(camera, *scene.size, spp)
        image, gbuffer = r.read("network"), r.gbuffer.read()
    finally:
        r.release()
    return image, gbuffer, camera, scene


def test_asset_holds_the_file_the_bundles_and_the_render_metrics(torus):
    from inshade.bundle import load
    from inshade.scene.description import load_scene
    from inshade.techniques.neural_appearance.train import preset_settings

    glb, asset = torus
    assert (asset / "source.glb").read_bytes() == glb.read_bytes()
    for folder, _prefix in NETWORKS:
        assert load(asset / folder).kind == KIND
    scene = load_scene(asset)
    assert scene.program == GLTF_PROGRAM and scene.mesh.gltf is not None and scene.spec.accumulate
    info = json.loads((asset / "gltf_material.json").read_text())
    assert info["material"] == 0 and info["source"] == "source.glb"
    assert np.allclose(info["uv_min"], [0, 0]) and np.allclose(info["uv_max"], [2, 1])   # the torus tiles u twice
    metrics = json.loads((asset / "metrics.json").read_text())
    assert metrics["preset"] == "quick"
    assert metrics["settings"] == {**preset_settings("quick"), "material": "0", "gltf": str(glb)}
    assert metrics["command"].startswith(f"inshade train neural_appearance --gltf {glb} --preset quick")
    assert set(metrics["history"]["holdout"]) == {"level0", "level1", "level2"}
    render = metrics["render"]
    assert render["spp"] == SPP and render["learnt_pixels"] > 0.2 * render["size"][0] * render["size"][1]
    assert render["psnr_lights_2x32"] >= 20.0, render
    assert render["psnr_shaded_2x32"] >= 15.5, render


def _reference_twin(source, gbuffer, camera, width, height, lights, light_count):
    """The GL reference's lights-only pixels (lights + emission) from the trainer's own reference:
    GltfSource.parameters at the G-buffer's uv, the local frame as gltf_surface builds it, the BRDF
    the targets use (reflectance). Linear RGB [H, W, 3] and the learnt material's mask, image orientation."""
    import torch

    from inshade.geometry.gltf_sample import material_channels
    from inshade.models.sdf import camera_rays
    from inshade.techniques.neural_appearance.gltf_scene import learnt_pixels

    mask = learnt_pixels(gbuffer, source.index)
    position, normal, uv, tangent = (a[::-1][mask].astype(np.float64) for a in gbuffer[:4])
    _, rd = camera_rays(camera.uniforms(width, height), width, height)
    v = -rd.numpy().reshape(height, width, 3)[mask]
    ng = normal[:, :3] / np.linalg.norm(normal[:, :3], axis=1, keepdims=True)
    t = tangent[:, :3] - ng * (ng * tangent[:, :3]).sum(1, keepdims=True)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(ng, t) * np.where(tangent[:, 3:] < 0, -1.0, 1.0)

    def local(w):
        return torch.from_numpy(np.stack([(w * t).sum(1), (w * b).sum(1), (w * ng).sum(1)], 1).astype(np.float32))

    params = torch.from_numpy(source.parameters(uv[:, :2]))
    colour = material_channels(source.asset, source.index, uv[:, :2])["emissive"]
    for light in lights[:light_count]:
        d = np.asarray(light["position"], np.float64) - position[:, :3]
        d2 = (d * d).sum(1, keepdims=True)
        f = source.reflectance(params, local(d / np.sqrt(d2)), local(v)).numpy()
        colour = colour + f * light["intensity"] / d2
    out = np.zeros((height, width, 3))
    out[mask] = colour
    return out, mask


@pytest.mark.parametrize("which", ["torus", "metal"])
def test_training_targets_are_the_gl_reference(which, request):
    """The targets' BRDF, frame and channels against the GL reference (lights, no environment) on the
    learnt material's pixels, the camera close to the material (1.5 x its radius) so that GL samples
    the textures' base level as the trainer does: PSNR (linear, peak = the brightest reference pixel)
    >= 50 dB (measured ~58 dB on the torus, ~60 dB on the brushed metal; a normal map read upside
    down gives ~41 dB, an anisotropy direction turned by 90 degrees ~11 dB). Not equal: the targets
    are 0 below the geometric horizon, and GL's texture filtering has its own precision."""
    from inshade.metrics import psnr
    from inshade.techniques.neural_appearance.gltf_source import GltfSource

    glb, asset = request.getfixturevalue(which)
    info = json.loads((asset / "gltf_material.json").read_text())
    source = GltfSource(glb, str(info["material"]))
    data = json.loads((asset / "scene.json").read_text())
    faces = source.asset.mesh.faces[source.asset.face_material == source.index]
    corners = source.asset.mesh.vertices[faces.reshape(-1)]
    lo, hi = corners.min(0), corners.max(0)
    close = {**data["camera"], "target": ((lo + hi) / 2).tolist(), "distance": 0.75 * float(np.linalg.norm(hi - lo))}
    image, gbuffer, camera, scene = _render(asset, {"view": "reference", "lighting": "lights"}, camera=close)
    twin, mask = _reference_twin(source, gbuffer, camera, *scene.size, data["lights"],
                                 data["settings"]["lights"]["default"])
    gl = image[..., :3]
    assert mask.mean() > 0.5          # the material fills the view
    peak = float(gl[mask].max())
    assert peak > 0.05
    assert psnr(twin / peak, gl / peak, mask=mask) >= 50.0


def test_split_is_the_gltf_reference_pass_left_and_the_network_right(torus):
    """Left half: bit-identical to the gltf_pbr pass (what ``inshade render source.glb`` draws) at the
    asset's camera, size and settings, background included; right half: the neural view's pixels."""
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    _glb, asset = torus
    split, gbuffer, camera, scene = _render(asset, {"view": "split"})
    neural, *_ = _render(asset, {"view": "neural"})
    width, height = scene.size
    plain = load_scene(asset / "source.glb")
    assert plain.program == "passes/gltf_pbr.frag"
    r = SceneRenderer(plain, settings={k: scene.settings[k].default for k in ("sky", "lights")})
    try:
        r.accumulate(camera, width, height, 1)
        reference = r.read("network")
    finally:
        r.release()
    half = width // 2
    assert np.array_equal(split[:, :half], reference[:, :half])
    assert np.array_equal(split[:, half:], neural[:, half:])
    from inshade.techniques.neural_appearance.gltf_scene import learnt_pixels

    mask = learnt_pixels(gbuffer, 0)[:, half:]
    assert mask.sum() > 1000
    diff = np.abs(split[:, half:, :3] - reference[:, half:, :3])[mask]
    assert diff.max() > 1e-3     # the right half is the network, not the reference


def test_anisotropic_material_trains_and_the_others_stay_the_reference(metal):
    """Showcase material 1 (brushed metal: anisotropy with a direction texture) learnt alone: its
    render PSNR clears the floor measured here, and every pixel of another material is the same
    in the neural and the reference views."""
    from inshade.techniques.neural_appearance.gltf_scene import learnt_pixels

    _glb, asset = metal
    metrics = json.loads((asset / "metrics.json").read_text())
    assert metrics["settings"]["material"] == "1"
    render = metrics["render"]
    assert render["learnt_pixels"] > 500
    assert render["psnr_lights_2x32"] >= 20.5, render
    assert render["psnr_shaded_2x32"] >= 15.5, render
    neural, gbuffer, _, _ = _render(asset, {"view": "neural", "lighting": "lights"})
    reference, *_ = _render(asset, {"view": "reference", "lighting": "lights"})
    others = (gbuffer[0][::-1, :, 3] != 0) & ~learnt_pixels(gbuffer, 1)
    assert others.sum() > 1000
    assert np.array_equal(neural[others], reference[others])


# ---------------------------------------------------------------------------------------------
# bad input

def _untextured_without_uv(path):
    from inshade.geometry.gltf_write import GltfBuilder, Primitive
    from inshade.geometry.shapes import sphere

    b = GltfBuilder()
    mat = b.material({"name": "plain", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0]}})
    ball = sphere(0.5, 8)
    b.node(b.mesh([Primitive(np.asarray(ball.vertices), np.asarray(ball.faces), material=mat)]))
    return b.write(path)


@pytest.mark.parametrize("case", ["no_uv", "unreadable", "material_index", "not_gltf"])
def test_bad_input_is_one_line_and_exit_2(case, tmp_path, capsys):
    from inshade.geometry import gltf_scenes
    from inshade.techniques.neural_appearance.train import main

    extra = []
    if case == "no_uv":
        path = _untextured_without_uv(tmp_path / "plain.glb")
        expect = f"inshade: error: {path}: meshes: no primitive has TEXCOORD_0"
    elif case == "unreadable":
        path = tmp_path / "broken.glb"
        path.write_bytes(b"glTF\x02\x00\x00\x00garbage")
        expect = f"inshade: error: {path}: "
    elif case == "material_index":
        path = gltf_scenes.tiles_torus().write(tmp_path / "torus.glb")
        extra = ["--material", "3"]
        expect = "inshade: error: --material: with --gltf, a material index of torus.glb (0..0), got '3'"
    else:
        path = tmp_path / "mesh.obj"
        path.write_text("v 0 0 0\n")
        expect = f"inshade: error: --gltf: {path}: expected a .glb or .gltf file"
    out = tmp_path / "out"
    code = main(["--gltf", str(path), "--preset", "quick", "--out", str(out), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith(expect), err
    assert not out.exists()
