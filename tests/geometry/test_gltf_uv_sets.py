"""A texture reads the uv set its textureInfo names (TEXCOORD_0 or TEXCOORD_1). Two files of one card
differ only in which set holds which mapping: in one the base colour texture reads TEXCOORD_0 = U and
the occlusion texture TEXCOORD_1 = W, in the other the sets are swapped and so are the texCoords. They
must draw the same pixels, bit for bit on one renderer (the same uv values and footprints reach the
same samplers), opaque, alpha-masked and blended, on the desktop and in the exported page; a third
file that swaps the sets but not the base colour's texCoord draws a different picture (the check can
fail)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from inshade.geometry.gltf import GltfError, load_gltf
from inshade.geometry.gltf_write import GltfBuilder, Primitive

SIZE = 96
U = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
W = np.array([[0.1, 1.7], [0.1, -0.3], [2.3, -0.3], [2.3, 1.7]], np.float64)   # another mapping: turned, scaled


def _images() -> tuple[np.ndarray, np.ndarray]:
    """(base colour: an RGB checker whose alpha is another checker, occlusion: a red ramp), RGBA8 32^2."""
    i = np.arange(32)
    base = np.zeros((32, 32, 4), np.uint8)
    base[..., 0] = np.where((i[:, None] // 8 + i[None, :] // 8) % 2 == 0, 230, 40)
    base[..., 1] = np.where((i[:, None] // 4) % 2 == 0, 200, 30)[:, :1]
    base[..., 2] = 90
    base[..., 3] = np.where((i[:, None] // 16 + i[None, :] // 16) % 2 == 0, 60, 240)
    occlusion = np.full((32, 32, 4), 255, np.uint8)
    occlusion[..., 0] = np.round(np.linspace(40, 255, 32))[None, :]
    return base, occlusion


def _file(path, *, swapped: bool, mode: str = "OPAQUE", base_set: int | None = None):
    """The card before an opaque wall; ``swapped``: TEXCOORD_0 = W, TEXCOORD_1 = U and the texCoords
    swapped with them; ``base_set``: the base colour's texCoord regardless (a wrong file)."""
    b = GltfBuilder()
    base_img, occ_img = _images()
    base_tex, occ_tex = b.texture(b.image(base_img)), b.texture(b.image(occ_img))
    uv0, uv1 = (W, U) if swapped else (U, W)
    base_set = (1 if swapped else 0) if base_set is None else base_set
    card = b.material({"name": "card", "alphaMode": mode, **({"alphaCutoff": 0.5} if mode == "MASK" else {}),
                       "pbrMetallicRoughness": {"baseColorTexture": {"index": base_tex, "texCoord": base_set},
                                                "metallicFactor": 0.0, "roughnessFactor": 0.6},
                       "occlusionTexture": {"index": occ_tex, "texCoord": 0 if swapped else 1}})
    wall = b.material({"name": "wall", "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.8, 0.2, 1.0],
                                                                 "metallicFactor": 0.0}})
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    n, t = np.tile([0.0, 0.0, 1.0], (4, 1)), np.tile([1.0, 0.0, 0.0, 1.0], (4, 1))
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    b.node(b.mesh([Primitive(v, faces, n, uv0, t, card, uv1=uv1)], "card"), name="card")
    b.node(b.mesh([Primitive(v - [0, 0, 0.5], faces, n, U, t, wall)], "wall"), scale=[1.5, 1.5, 1.0], name="wall")
    return b.write(path)


def _render(path) -> np.ndarray:
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene

    image, _ = render_scene(load_scene(path), width=SIZE, height=SIZE)
    return image


def test_the_reader_keeps_the_second_set_where_a_texture_reads_it(tmp_path):
    asset = load_gltf(_file(tmp_path / "a.glb", swapped=False))
    uv1 = asset.mesh.vertex_attributes["uv1"]
    card = np.unique(asset.mesh.faces[asset.face_material == 0])
    np.testing.assert_allclose(uv1[card], W, atol=1e-6)
    assert asset.materials[0].occlusion_texture.texcoord == 1
    # without a texture on the second set the mesh carries none (and the G-buffer draws no targets for it)
    path = _file(tmp_path / "b.gltf", swapped=False)
    doc = json.loads(path.read_text())
    doc["materials"][0]["occlusionTexture"]["texCoord"] = 0
    path.write_text(json.dumps(doc))
    assert "uv1" not in load_gltf(path).mesh.vertex_attributes


@pytest.mark.parametrize("texcoord, field, message", [
    (2, "materials (card).occlusion", "reads uv set 2; TEXCOORD_0 and TEXCOORD_1 are supported"),
    (1, "meshes[0].primitives[0]", "reads TEXCOORD_1, but the primitive has none")])
def test_a_set_the_file_lacks_is_one_error(tmp_path, texcoord, field, message):
    path = tmp_path / "a.gltf"
    _file(path, swapped=False)
    doc = json.loads(path.read_text())
    doc["materials"][0]["occlusionTexture"]["texCoord"] = texcoord
    if texcoord == 1:
        del doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_1"]
    path.write_text(json.dumps(doc))
    with pytest.raises(GltfError) as err:
        load_gltf(path)
    assert field in str(err.value) and message in str(err.value), err.value


@pytest.mark.parametrize("mode", ["OPAQUE", "MASK", "BLEND"])
def test_swapping_the_sets_and_the_texcoords_draws_the_same_pixels(gl, tmp_path, mode):
    a = _render(_file(tmp_path / "a.gltf", swapped=False, mode=mode))
    b = _render(_file(tmp_path / "b.gltf", swapped=True, mode=mode))
    assert np.array_equal(a, b), f"{mode}: max difference {np.abs(a - b).max()}"
    if mode == "OPAQUE":   # the base colour reading the other set: a different picture
        wrong = _render(_file(tmp_path / "c.gltf", swapped=True, base_set=0))
        assert np.abs(wrong - a).max() > 0.2


@pytest.mark.parametrize("api", ["webgl2", "webgpu"])
def test_the_page_reads_the_second_set(gl, api, tmp_path):
    """The exported page's G-buffer carries the second set (two more targets) and its BLEND layers read
    it: the page is the desktop render's picture (within 3 levels; a few pixels along the checker's
    edges, where the two texture units filter differently, up to 10)."""
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene
    from inshade.web.browser import Browser, serve, srgb8
    from inshade.web.export import export_web

    path = _file(tmp_path / "b.gltf", swapped=True, mode="BLEND")
    export_web(path, tmp_path / "page", width=SIZE, height=SIZE, api=api)
    manifest = json.loads((tmp_path / "page" / "manifest.json").read_text())
    assert [t["uniform"] for t in manifest["mesh"]["targets"]][-2:] == ["u_gbuffer_uv1", "u_gbuffer_uv1_dy"]
    with Browser() as browser, serve(tmp_path / "page") as url:
        state = browser.open(url + "index.html")
        assert state["error"] is None, state
        assert browser.driver.execute_script("return window.inshade.api;") == api
        page = browser.canvas().astype(int)
    image, info = render_scene(load_scene(path), width=SIZE, height=SIZE)
    desktop = srgb8(image, tonemap=info["view"]["settings"]["tonemap"]).astype(int)
    diff = np.abs(page - desktop).max(-1)
    assert (diff > 3).mean() < 0.01, f"{(diff > 3).sum()} pixels differ by more than 3 levels"
    assert (diff > 10).mean() < 0.005, f"{(diff > 10).sum()} pixels differ by more than 10 levels"


@pytest.mark.parametrize("technique", ["uvfree_material", "neural_appearance", "di_pbr_set"])
def test_a_learnt_material_refuses_the_second_set_before_any_work(tmp_path, capsys, technique):
    """Learnt materials sample the file over TEXCOORD_0: a texture on TEXCOORD_1 is one line, exit 2,
    and no asset folder."""
    from inshade.cli import main

    path = _file(tmp_path / "a.glb", swapped=False)
    out = tmp_path / "out"
    assert main(["-q", "train", technique, "--gltf", str(path), "--out", str(out), "--preset", "quick"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"inshade: error: {path}: materials (card).occlusion: reads TEXCOORD_1; a learnt material is "
                   "sampled over TEXCOORD_0 (gltf_pbr draws the file as it is)"], err
    assert not out.exists()
