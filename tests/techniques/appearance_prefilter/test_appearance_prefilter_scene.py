"""`inshade train appearance_prefilter --scene FILE` (techniques/appearance_prefilter/user_scene.py,
user_asset.py, train.py, passes/appearance_prefilter_gltf.frag): a user's glTF or OBJ file voxelised
and prefiltered in place of a procedural scene.

- user_scene: the per-face material is the mean of the glTF material's channels (geometry/
  gltf_sample.py) at the face's 9 equal-area points; one part per material, two-sided where the
  material says so; the file normalised into the unit box with its map kept; an OBJ takes the
  constant material and an open one-sided mesh is prefiltered as two-sided, with a note.
- One asset is trained on gltf_scenes.tiles_torus() at settings below the quick preset (decoder
  width 8, latent 12, 40 steps of 256 samples: llvmpipe compiles the quick preset's width-32
  decoders inside the glTF pass in ~60 s cold, these in ~5 s; the bake is the quick preset's):
  the file copied byte-identical as the scene's mesh, the bundle's render.world the file's map;
  the split view's left half (and the reference view) bit-identical to the glTF reference pass
  (techniques/gltf_pbr) at the same camera, sun and sky, its right half the prefiltered view; the
  prefiltered view equal to the procedural scenes' pass from the same camera taken into the unit
  box (>= 50 dB, the march's parity bound; measured 71.6 dB on a larger asset); the voxels where
  the file's mesh is drawn (coverage >= 0.5 on >= 90 % of its pixels, 0 on >= 95 % of the pixels
  10 away from it).
- metrics.json reports the prefiltered render's PSNR against the file's reference and against the
  ray-traced one at the scene's camera (measured 11.3 / 10.9 dB here, 14.3 / 13.3 dB at the quick
  preset, 15.3 / 14.4 dB at scales 3..5 after 1500 steps). Those numbers are not a quality bound: at
  these training budgets the prefiltered surfaces come out at 0.3-0.5x the ray-traced brightness
  (as the procedural slabs' quick asset does, 0.3x), so a black surface would score about as well.
  Checked: both finite and >= 9 dB (a NaN or blown-up image fails).
- A malformed file, a textured file without TEXCOORD_0, a missing file and --detail with a file:
  one ``inshade: error:`` line each, exit 2, no asset folder.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch
import trimesh
from scipy import ndimage

from inshade.bundle import load
from inshade.geometry import gltf_scenes
from inshade.geometry.gltf import load_gltf
from inshade.geometry.gltf_sample import material_channels
from inshade.geometry.mesh import mesh_uv, write_torus
from inshade.metrics import psnr
from inshade.runtime.render import read_rgba
from inshade.runtime.renderer import SceneRenderer
from inshade.scene.description import load_scene
from inshade.techniques.appearance_prefilter import GLTF_PROGRAM, GLTF_VIEWS, train
from inshade.techniques.appearance_prefilter.scene import MARGIN
from inshade.techniques.appearance_prefilter.user_scene import PLAIN, face_samples, load_user_scene

from gltf_inputs import textured_without_uv

SIZE = 64
SMALL = ["--preset", "quick", "--width", "8", "--latent", "12", "--steps", "40", "--batch", "256", "--device", "cpu"]


# --- the file as a prefiltering scene -------------------------------------------------------------

def test_gltf_faces_take_the_materials_mean_at_their_sample_points(tmp_path):
    path = gltf_scenes.tiles_torus().write(tmp_path / "tiles_torus.glb")
    user = load_user_scene(path)
    asset = load_gltf(path)
    mesh = asset.mesh
    assert user.kind == "gltf" and user.scene.parts == [("tiles", 0, len(mesh.faces))]
    faces = np.asarray(mesh.faces)[[0, 777, 4095]]
    uv = mesh_uv(mesh)
    w = face_samples()
    assert w.shape == (9, 3) and np.allclose(w.sum(1), 1.0) and len({tuple(r) for r in w.round(9)}) == 9
    for row, f in zip((0, 777, 4095), faces):
        ch = material_channels(asset, 0, w @ uv[f])
        np.testing.assert_allclose(user.scene.base_colour[row], ch["base_color"].mean(0), rtol=1e-6)
        np.testing.assert_allclose(user.scene.roughness[row], ch["roughness"].mean(), rtol=1e-6)
        np.testing.assert_allclose(user.scene.metallic[row], ch["metallic"].mean(), rtol=1e-6)
    assert user.scene.base_colour.std(0).min() > 0.05          # the texture, not one colour
    box = np.asarray(user.scene.mesh.vertices)
    centre, scale = np.asarray(user.world["centre"]), user.world["scale"]
    np.testing.assert_allclose(box, (np.asarray(mesh.vertices) - centre) * scale + 0.5, atol=1e-12)
    assert box.min() >= MARGIN - 1e-9 and box.max() <= 1 - MARGIN + 1e-9
    assert np.isclose(np.ptp(box, 0).max(), 1 - 2 * MARGIN)


def test_materials_become_parts_and_double_sided_is_kept(tmp_path):
    user = load_user_scene(gltf_scenes.showcase().write(tmp_path / "showcase.glb"))
    names = [name for name, _, _ in user.scene.parts]
    assert names == ["car paint", "brushed metal", "fabric", "specular-glossiness", "default"]
    for name, start, stop in user.scene.parts:
        assert user.scene.two_sided[start:stop].all() == (name == "fabric"), name
    assert any("specular-glossiness" in note for note in user.notes)


def test_an_obj_takes_the_plain_material_and_open_one_sided_parts_become_two_sided(tmp_path):
    user = load_user_scene(write_torus(tmp_path / "torus.obj"))
    assert user.kind == "mesh" and not user.scene.two_sided.any()
    assert np.allclose(user.scene.base_colour, PLAIN["base_colour"]) and np.allclose(user.scene.roughness, 0.5)
    sheet = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 1]], [[0, 2, 1], [1, 2, 3]], process=False)
    sheet.export(tmp_path / "sheet.obj")
    user = load_user_scene(tmp_path / "sheet.obj")
    assert user.scene.two_sided.all() and any("not closed" in note for note in user.notes)


# --- a trained glTF asset -------------------------------------------------------------------------

@pytest.fixture(scope="module")
def asset(tmp_path_factory):
    root = tmp_path_factory.mktemp("dap_scene")
    source = gltf_scenes.tiles_torus().write(root / "tiles_torus.glb")
    out = root / "appearance_prefilter_tiles_torus"
    threads = torch.get_num_threads()
    torch.set_num_threads(1)     # two spinning OpenMP threads on a shared 2-core machine: ~10x slower steps
    try:
        assert train.main(["--scene", str(source), "--out", str(out), "--cache", str(root / "cache"), *SMALL]) == 0
    finally:
        torch.set_num_threads(threads)
    return source, out



def _draw(renderer, camera, **settings):
    for k, v in settings.items():
        renderer.set_setting(k, v)
    return read_rgba(renderer.render_network(camera, SIZE, SIZE))


def test_the_asset_carries_the_file_and_the_glTF_pass(asset):
    source, out = asset
    assert (out / "source.glb").read_bytes() == source.read_bytes()
    scene = json.loads((out / "scene.json").read_text())
    assert scene["program"] == GLTF_PROGRAM and scene["mesh"] == "source.glb"
    assert scene["settings"]["view"]["choices"] == list(GLTF_VIEWS) and "distance" not in scene["settings"]
    assert scene["reference"]["image"] == "reference.exr" and (out / "reference.exr").is_file()
    assert "differ by design" in scene["notes"]
    assert load(out).meta["render"]["world"] == load_user_scene(source).world
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["settings"]["scene"] == str(source) and "detail" not in metrics["settings"]
    assert metrics["user_scene"]["kind"] == "gltf"


def _scene_folder(folder, scene: dict, files: dict):
    folder.mkdir()
    for name, source in files.items():
        (folder / name).write_bytes(source.read_bytes())
    (folder / "scene.json").write_text(json.dumps({"format": "inshade.scene", "version": 1, "name": folder.name,
                                                   "size": [SIZE, SIZE], **scene}))
    return load_scene(folder)


def test_split_is_the_reference_pass_beside_the_prefiltered_voxels(asset, program_cache, tmp_path):
    _, out = asset
    dap = json.loads((out / "scene.json").read_text())
    scene = load_scene(out)
    renderer = SceneRenderer(scene, cache=program_cache)
    try:
        camera = scene.make_camera()
        split = _draw(renderer, camera, view="split")
        prefiltered = _draw(renderer, camera, view="prefiltered")
        reference_view = _draw(renderer, camera, view="reference")
        coverage = _draw(renderer, camera, view="coverage")[..., 0]
        drawn = renderer.gbuffer.read()[0][::-1, :, 3] > 0          # the file's pixels, image orientation
    finally:
        renderer.release()
    reference = SceneRenderer(_scene_folder(tmp_path / "reference", {
        "program": "passes/gltf_pbr.frag", "networks": [], "mesh": "source.glb", "camera": dap["camera"],
        "lights": dap["lights"], "environment": dap["environment"],
        "settings": {"lights": {"type": "int", "default": 1, "min": 0, "max": 2, "uniform": "u_light_count"}}},
        {"source.glb": out / "source.glb"}), cache=program_cache)
    try:
        shaded = _draw(reference, camera)
    finally:
        reference.release()
    half = SIZE // 2
    assert np.array_equal(split[:, :half, :3], shaded[:, :half, :3])
    assert np.array_equal(reference_view[..., :3], shaded[..., :3])
    assert np.array_equal(split[:, half:, :3], prefiltered[:, half:, :3]) and (split[..., 3] == 1.0).all()
    # the voxels sit where the file is drawn
    assert drawn.mean() > 0.1
    assert (coverage[drawn] >= 0.5).mean() >= 0.9
    far = ~ndimage.binary_dilation(drawn, iterations=10)
    assert (coverage[far] == 0).mean() >= 0.95


def test_the_glTF_pass_marches_the_voxels_as_the_box_pass_does(asset, program_cache, tmp_path):
    """The prefiltered view from the file's camera equals the procedural scenes' pass
    (passes/appearance_prefilter.frag) from the same camera taken into the unit box (user_asset.py
    cameras): >= 50 dB, the march's parity bound (a few pixels take another DDA step where the
    world-to-box rounding moves a ray across a cell boundary)."""
    from inshade.techniques.appearance_prefilter import PROGRAM, SETTINGS
    from inshade.techniques.appearance_prefilter.user_asset import cameras

    source, out = asset
    dap = json.loads((out / "scene.json").read_text())
    _, box_camera = cameras(load_user_scene(source))
    box = _scene_folder(tmp_path / "box", {
        "program": PROGRAM, "networks": [{"bundle": ".", "prefix": "dap"}], "camera": box_camera,
        "lights": dap["lights"], "environment": dap["environment"], "settings": SETTINGS},
        {"bundle.json": out / "bundle.json", "weights.safetensors": out / "weights.safetensors"})
    images = []
    for scene in (load_scene(out), box):
        renderer = SceneRenderer(scene, cache=program_cache)
        try:
            images.append(_draw(renderer, scene.make_camera(), view="prefiltered"))
        finally:
            renderer.release()
    assert images[0][..., 3].mean() > 0.1
    assert psnr(images[0], images[1]) >= 50.0


def test_metrics_report_psnr_against_both_references(asset):
    _, out = asset
    metrics = json.loads((out / "metrics.json").read_text())
    reference = metrics["reference"]
    assert reference["size"] == [320, 320] and reference["gltf"]["surface_pixels"] > 1000
    assert reference["gltf"]["psnr"] >= 9.0 and reference["traced"]["psnr"] >= 9.0, reference
    assert np.isfinite(metrics["losses"]["total"]) and metrics["voxels"] > 0


# --- bad input ------------------------------------------------------------------------------------

def _one_line(capsys) -> str:
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def test_bad_files_are_one_line_before_any_work(tmp_path, capsys):
    for name, path in gltf_scenes.malformed(tmp_path / "corpus").items():
        out = tmp_path / f"x_{name}"
        assert train.main(["--scene", str(path), "--out", str(out), *SMALL]) == 2, name
        assert _one_line(capsys).startswith(f"inshade: error: {path}: {gltf_scenes.MALFORMED[name][1]}"), name
        assert not out.exists()
    path = textured_without_uv(tmp_path / "no_uv.glb")
    assert train.main(["--scene", str(path), "--out", str(tmp_path / "x"), *SMALL]) == 2
    assert _one_line(capsys) == (f"inshade: error: {path}: meshes: materials have textures, but no primitive "
                                 "has TEXCOORD_0")
    absent = tmp_path / "absent.glb"
    assert train.main(["--scene", str(absent), "--out", str(tmp_path / "x"), *SMALL]) == 2
    assert _one_line(capsys) == f"inshade: error: --scene: {absent}: no such file (the procedural scenes: forest, grove, slabs)"
    torus = write_torus(tmp_path / "torus.obj")
    assert train.main(["--scene", str(torus), "--detail", "quick", "--out", str(tmp_path / "x"), *SMALL]) == 2
    assert _one_line(capsys) == "inshade: error: --detail: only with scene forest or grove or slabs"
    assert not (tmp_path / "x").exists()
