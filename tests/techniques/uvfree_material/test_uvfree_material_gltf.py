"""uvfree_material --gltf end to end on the procedural tiles torus (geometry/gltf_scenes.py): the quick
preset (as shipped: 120 steps, 2x32 decoder) learns the file's channels on its own mesh; the asset
folder holds the file byte for byte; the split view's left half is the glTF reference pass's render
of the same file and its right half the network view; the network view shows the decoded channels
as torch decodes the visibility buffer's points; the render beats the untrained decoder by a
measured margin; bad input is one error line and exit status 2."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import torch

from inshade.metrics import srgb_eotf
from inshade.techniques.uvfree_material import ERROR_SCALE

from parity import TOL, scaled_error
from uvfree_assets import train_quick

W, H = 128, 128
# measured with the quick preset on this asset (llvmpipe, torch CPU): 16.8 dB display PSNR against the
# reference at the scene camera, the untrained decoder (steps 0) 9.8 dB; the floors leave 1.8 and 2 dB
RENDER_FLOOR_DB = 15.0
GAIN_FLOOR_DB = 5.0


@pytest.fixture(scope="module")
def torus(tmp_path_factory):
    from inshade.geometry import gltf_scenes

    return gltf_scenes.tiles_torus().write(tmp_path_factory.mktemp("gltf") / "tiles_torus.glb")


@pytest.fixture(scope="module")
def asset(tmp_path_factory, torus):
    return train_quick(tmp_path_factory.mktemp("uvg") / "uvfree_material_tiles_torus", gltf_path=torus)


@pytest.fixture(scope="module")
def graph(asset):
    from inshade.bundle import load
    from inshade.models import GraphModule

    return GraphModule.from_bundle(load(asset / "material"))


def test_asset_folder_holds_the_file_the_bundle_and_the_metrics(asset, torus):
    from inshade.bundle import load
    from inshade.geometry.gltf import load_gltf

    assert (asset / "source.glb").read_bytes() == torus.read_bytes()
    bundle = load(asset / "material")
    channels = ["base_color", "metallic", "roughness", "normal", "occlusion", "emissive"]
    assert bundle.kind == "uvfree_material_gltf" and bundle.meta["render"]["channels"] == channels
    assert bundle.out_dim == 12 and [p.dtype for p in bundle.inputs] == ["uint", "float"]
    node = next(n for n in bundle.nodes if n.type == "mesh_features")
    assert node.params["faces"] == len(load_gltf(asset / "source.glb").mesh.faces) == 4096
    scene = json.loads((asset / "scene.json").read_text())
    assert scene["mesh"] == "source.glb" and scene["program"] == "passes/mesh_uvfree_gltf.frag"
    assert scene["settings"]["view"]["choices"] == ["reference", "decoded", "split", "error"]
    m = json.loads((asset / "metrics.json").read_text())
    assert m["preset"] == "quick" and m["channels"] == channels
    assert set(m["torch_quality"]) == {f"psnr_{c}" for c in channels} | {"normal_mean_deg"}
    mem = bundle.tensors["features.table"].size * 2
    assert m["memory"]["features_bytes"] == mem and m["memory"]["neural_bytes"] > mem
    assert m["memory"]["texture_bytes"] == 5 * 128 * 128 * 4      # five RGBA8 128^2 textures
    assert 0 < m["memory"]["texture_bytes_file"] < torus.stat().st_size
    assert m["render"]["covered_pixels"] > 0.1 * 512 * 512


def test_targets_are_each_faces_own_material_and_the_channels_the_file_has(tmp_path):
    """The showcase (several materials, a normal map, no occlusion, no emission): one decoder, each
    point's target its face's material; base colour stored sRGB-encoded, the normal as n * 0.5 + 0.5."""
    from inshade.geometry import gltf_scenes
    from inshade.geometry.gltf import linear_to_srgb, load_gltf
    from inshade.geometry.gltf_sample import material_channels
    from inshade.techniques.uvfree_material.gltf_train import GltfTargets

    asset = load_gltf(gltf_scenes.showcase().write(tmp_path / "showcase.glb"))
    targets = GltfTargets(asset)
    assert targets.channels == ("base_color", "metallic", "roughness", "normal") and targets.width == 8
    rng = np.random.default_rng(1)
    face = rng.integers(0, len(asset.face_material), 4000)
    uv = rng.random((4000, 2))
    got = targets(face, uv)
    assert len(np.unique(asset.face_material[face])) == len(asset.used_materials()) > 2
    for m in asset.used_materials():
        sel = asset.face_material[face] == m
        want = material_channels(asset, m, uv[sel])
        np.testing.assert_allclose(got[sel, 0:3], linear_to_srgb(want["base_color"]), atol=1e-6)
        np.testing.assert_allclose(got[sel, 3], want["metallic"], atol=1e-6)
        np.testing.assert_allclose(got[sel, 4], want["roughness"], atol=1e-6)
        np.testing.assert_allclose(got[sel, 5:8], want["normal"] * 0.5 + 0.5, atol=1e-6)
    paint = next(i for i, m in enumerate(asset.materials) if m.name == "car paint")
    painted = got[asset.face_material[face] == paint, 0:3]
    np.testing.assert_allclose(painted, np.broadcast_to(linear_to_srgb(np.array([0.6, 0.03, 0.02])), painted.shape),
                               atol=1e-6)


def _render(path, **settings):
    from inshade.runtime.headless import render_scene

    return render_scene(path, width=W, height=H, settings=settings)[0]


def test_split_is_the_reference_pass_left_and_the_network_right(asset):
    """Left of the middle: bit-identical to passes/gltf_pbr.frag drawing source.glb (the scene a glTF
    file opens as: same camera, lights, environment); right: the network view's pixels."""
    from inshade.techniques.uvfree_material.gltf_scene import render_views

    split = _render(asset, view="split")
    reference = _render(asset / "source.glb")          # the glTF reference pass, not this technique's
    network = _render(asset, view="decoded")
    half = W // 2
    assert np.array_equal(split[:, :half], reference[:, :half])
    assert np.array_equal(split[:, half:], network[:, half:])
    assert np.array_equal(_render(asset, view="reference"), reference)
    _, covered = render_views(asset, views=("decoded",), size=(W, H))
    assert covered.mean() > 0.1
    assert np.abs(network - reference)[covered].max() > 0.05, "the network view must show the decoder"
    assert np.array_equal(network[~covered], reference[~covered])   # the background is the environment's
    error = _render(asset, view="error")
    np.testing.assert_allclose(error[..., :3], np.abs(network - reference)[..., :3] * ERROR_SCALE, atol=1e-5, rtol=1e-5)


def test_network_view_shows_the_decoded_channels_like_torch(asset, graph):
    """Channel views of the network side at every covered pixel: torch fed the visibility buffer's
    (face, t0, t1), clamped and decoded as the pass does (the parity rule; srgb_eotf adds a few ulp)."""
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    r = SceneRenderer(load_scene(asset), settings={"view": "decoded"})
    shown = {}
    try:
        camera = r.scene.make_camera()
        for channel in ("base_color", "metallic", "roughness", "occlusion", "emissive"):
            r.set_setting("channel", channel)
            r.render_network(camera, W, H)
            shown[channel] = r.read("network")[::-1][..., :3]   # image -> data orientation (the G-buffer's)
        position, *_, primitive, bary = r.gbuffer.read()
    finally:
        r.release()
    covered = position[..., 3] == 1.0
    x = np.c_[primitive[covered].astype(np.float32), bary[covered]]
    with torch.no_grad():
        y = graph(torch.from_numpy(x)).numpy().astype(np.float64)
    lane = lambda a, b: np.clip(y[:, a:b], 0, 1)  # noqa: E731
    want = {"base_color": srgb_eotf(lane(0, 3)), "metallic": lane(3, 4).repeat(3, 1),
            "roughness": np.clip(y[:, 4:5], 0.02, 1).repeat(3, 1), "occlusion": lane(8, 9).repeat(3, 1),
            "emissive": srgb_eotf(lane(9, 12))}
    for channel, values in want.items():
        err = scaled_error(shown[channel][covered], values)
        assert err.max() <= 4 * TOL, f"{channel}: {err.max():.3g}"


def test_render_psnr_beats_the_untrained_decoder(asset, torus, tmp_path):
    trained = json.loads((asset / "metrics.json").read_text())["render"]["render_psnr_vs_reference"]
    untrained = json.loads((train_quick(tmp_path / "u", gltf_path=torus, steps=0) / "metrics.json").read_text())
    assert trained > RENDER_FLOOR_DB
    assert trained > untrained["render"]["render_psnr_vs_reference"] + GAIN_FLOOR_DB


def test_a_file_without_textures_or_uv_learns_its_factors(tmp_path, capsys):
    """Two untextured materials, no TEXCOORD_0: base colour, metallic and roughness only, one decoder
    (through the command line's entry point)."""
    from inshade.bundle import load
    from inshade.geometry.gltf_write import GltfBuilder, Primitive
    from inshade.geometry.shapes import sphere
    from inshade.techniques.uvfree_material.train import main

    b = GltfBuilder()
    mats = [b.material({"pbrMetallicRoughness": {"baseColorFactor": c, "metallicFactor": 0.0, "roughnessFactor": 0.5}})
            for c in ([0.8, 0.1, 0.1, 1.0], [0.1, 0.2, 0.8, 1.0])]
    ball = sphere(0.5, 8)
    for mat, dx in zip(mats, (-0.6, 0.6)):
        b.node(b.mesh([Primitive(np.asarray(ball.vertices), np.asarray(ball.faces), material=mat)]),
               translation=[dx, 0.0, 0.0])
    out = tmp_path / "plain"
    assert main(["--gltf", str(b.write(tmp_path / "plain.glb")), "--preset", "quick", "--steps", "30",
                 "--no-preview", "--out", str(out)]) == 0
    assert "(the file has no textures)" in capsys.readouterr().out
    bundle = load(out / "material")
    assert bundle.meta["render"]["channels"] == ["base_color", "metallic", "roughness"] and bundle.out_dim == 5
    m = json.loads((out / "metrics.json").read_text())
    assert m["memory"]["texture_bytes"] == 0 and m["memory"]["rate_features_mlp"] is None
    assert np.isfinite(_render(out, view="split")).all()


def test_a_gltf_with_files_beside_it_stores_the_same_image_bytes(tmp_path, torus):
    """A .gltf's images (in its .bin) count as the .glb's: the same images."""
    from inshade.geometry import gltf_scenes
    from inshade.techniques.uvfree_material.gltf_source import file_image_bytes

    src = gltf_scenes.tiles_torus().write(tmp_path / "src" / "torus.gltf")
    assert file_image_bytes(src) == file_image_bytes(torus) > 0


def _bad_files(tmp_path) -> dict:
    from inshade.geometry.gltf_write import GltfBuilder, Primitive
    from inshade.geometry.shapes import sphere

    b = GltfBuilder()
    tex = b.texture(b.image(np.full((4, 4, 4), 200, np.uint8)))
    mat = b.material({"pbrMetallicRoughness": {"baseColorTexture": {"index": tex}}})
    ball = sphere(0.5, 6)
    b.node(b.mesh([Primitive(np.asarray(ball.vertices), np.asarray(ball.faces), material=mat)]))
    garbage = tmp_path / "garbage.glb"
    garbage.write_bytes(b"not a glb file at all")
    return {"nouv": b.write(tmp_path / "nouv.glb"), "garbage": garbage}


def test_bad_input_is_one_error_line(tmp_path, torus, capsys):
    from inshade.techniques.uvfree_material.train import main

    files = _bad_files(tmp_path)
    cases = [
        (["--gltf", str(files["nouv"])], f"{files['nouv']}: meshes: materials have textures, but no primitive has "
                                         "TEXCOORD_0"),
        (["--gltf", str(files["garbage"])], f"{files['garbage']}: "),
        (["--gltf", str(tmp_path / "missing.glb")], "missing.glb: --gltf: no such file"),
        (["--gltf", str(tmp_path / "mesh.obj")], "mesh.obj: --gltf: expected a .glb or .gltf file"),
        (["--gltf", str(torus), "--object", "rock"], "--object: goes without --gltf"),
        (["--mesh", str(torus), "--gltf", str(torus)], "--mesh: goes without --gltf"),
    ]
    for i, (args, message) in enumerate(cases):
        code = main(["--preset", "quick", "--steps", "1", "--no-preview", "--out", str(tmp_path / f"o{i}"), *args])
        err = capsys.readouterr().err
        lines = [ln for ln in err.splitlines() if ln.startswith("inshade: error:")]
        assert code == 2 and len(lines) == 1 and message in lines[0], (args, err[-2000:])
    # through the command line too
    res = subprocess.run([sys.executable, "-m", "inshade.cli", "train", "uvfree_material", "--gltf",
                          str(files["nouv"]), "--out", str(tmp_path / "cli")], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 2 and res.stderr.strip().splitlines()[-1].startswith(f"inshade: error: {files['nouv']}: ")
