"""The glTF reference pass (techniques/gltf_pbr: lib/gltf_material + lib/gltf_brdf) through the GL
runtime on the procedural glTF assets: its light transport against the numpy twin at the G-buffer's
pixels, its material channels against the CPU reading (geometry/gltf_sample.py), and the ways a
user reaches it (``inshade render | info | view FILE.glb``).

The lights' share is isolated as the difference of two renders (lights on / off): the twin
(models/gltf_brdf.py) evaluated at each pixel's G-buffer position and normal with the material's
factors must match it under the parity rule, with the float32 rounding of the difference (a few
ulps of the larger render) on top.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from inshade.geometry import gltf_scenes
from inshade.geometry.gltf import load_gltf
from inshade.geometry.gltf_sample import material_channels
from inshade.models import gltf_brdf as G
from inshade.runtime.renderer import SceneRenderer
from inshade.scene.description import load_scene


@pytest.fixture(scope="module")
def assets(tmp_path_factory):
    return gltf_scenes.write_all(tmp_path_factory.mktemp("gltf_pbr"))


def _draw(renderer, camera, w, h, **settings):
    for k, v in settings.items():
        renderer.set_setting(k, v)
    renderer.render_network(camera, w, h)
    return renderer.read("network")[..., :3].astype(np.float64)


def test_lights_share_matches_the_numpy_twin_at_every_untextured_pixel(gl, assets):
    scene = load_scene(assets["showcase"])
    asset = scene.mesh.gltf
    renderer = SceneRenderer(scene, gl)
    try:
        camera = scene.make_camera()
        w = h = 128
        lit = _draw(renderer, camera, w, h, lights=2)
        unlit = _draw(renderer, camera, w, h, lights=0)
        position, normal, uv, _, _ = (a[::-1] for a in renderer.gbuffer.read())   # image orientation
    finally:
        renderer.release()
    material = np.rint(uv[..., 2]).astype(int)
    untextured = [i for i, m in enumerate(asset.materials) if not m.textures()]
    assert {asset.materials[i].name for i in untextured} == {"car paint", "default"}
    mask = (position[..., 3] > 0) & np.isin(material, untextured)
    assert mask.sum() > 300
    p, n, m = position[mask][:, :3], normal[mask][:, :3], material[mask]
    eye = np.asarray(camera.eye(), np.float64)
    v = eye - p
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    # the surface: factors only; the coat normal is the geometric one; tangent-free lobes
    s = G.Shading(**{k: np.concatenate([getattr(G.shading_from_material(asset.materials[i], int((m == i).sum())), k)
                                        for i in untextured]) for k in vars(G.shading_from_material(asset.materials[0], 1))})
    order = np.concatenate([np.flatnonzero(m == i) for i in untextured])
    p, n, v = p[order], n[order], v[order]
    s.roughness = np.maximum(s.roughness, np.float32(0.02))
    s.clearcoat_roughness = np.maximum(s.clearcoat_roughness, np.float32(0.02))
    expect = np.zeros_like(p)
    for light in scene.lights[:2]:
        d = np.asarray(light.position) - p
        d2 = np.sum(d * d, 1)
        l = d / np.sqrt(d2)[:, None]
        expect += G.brdf(s, n, np.zeros_like(n), np.zeros_like(n), n, v, l) * (light.intensity / d2)[:, None]
    got = (lit - unlit)[mask][order]
    scale = np.maximum(1.0, np.abs(expect))
    err = np.abs(got - expect) / scale
    bound = 1e-5 + 4 * 2.0 ** -23 * np.abs(lit[mask][order]) / scale
    worst = np.unravel_index(np.argmax(err / bound), err.shape)
    assert (err <= bound).all(), f"pixel {worst}: {got[worst]} vs twin {expect[worst]}"


def test_channel_views_match_the_cpu_reading(gl, assets):
    """Where the textures are seen at their base level (a pixel's footprint under one texel), the
    base-colour view equals material_channels' bilinear reading of the file (8-bit texels sRGB-decoded,
    then filtered) within 0.01: the hardware's 8-bit filter weights and the half-float texels."""
    scene = load_scene(assets["tiles_torus"])
    renderer = SceneRenderer(scene, gl)
    try:
        camera = scene.make_camera()
        view = _draw(renderer, camera, 384, 384, view="base_color")
        position, _, uv, _, grad = (a[::-1] for a in renderer.gbuffer.read())
    finally:
        renderer.release()
    asset = scene.mesh.gltf
    texels = asset.images[asset.materials[0].base_color_texture.image].shape[0]
    # pixels whose footprint (after the transform's x2 scale) stays under one texel: the base level
    footprint = 2.0 * texels * np.max(np.abs(grad), -1)
    mask = (position[..., 3] > 0) & (footprint < 1.0)
    assert mask.sum() > 500
    expect = material_channels(asset, 0, uv[mask][:, :2])["base_color"]
    err = np.abs(view[mask] - expect)
    assert err.max() < 0.01, (np.percentile(err, 99), err.max())


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "inshade.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=600, cwd=cwd, env=dict(os.environ))


def test_render_and_info_take_a_glb(assets, tmp_path):
    out = tmp_path / "shot.png"
    r = _cli("render", assets["tiles_torus"], "-o", out, "--width", "64", "--height", "64", "--set", "view=normal")
    assert r.returncode == 0, r.stderr
    sidecar = json.loads((tmp_path / "shot.png.json").read_text())
    assert sidecar["view"]["settings"]["view"] == "normal"
    r = _cli("info", assets["showcase"])
    assert r.returncode == 0, r.stderr
    assert "passes/gltf_pbr.frag" in r.stdout and "geometry: mesh showcase.glb" in r.stdout


def test_a_textured_file_without_uv_is_one_line(tmp_path):
    from inshade.geometry.gltf_write import GltfBuilder, Primitive

    b = GltfBuilder()
    image = np.full((4, 4, 4), 200, np.uint8)
    mat = b.material({"pbrMetallicRoughness": {"baseColorTexture": {"index": b.texture(b.image(image))}}})
    b.node(b.mesh([Primitive(np.eye(3), np.array([[0, 1, 2]]), material=mat)]))
    path = b.write(tmp_path / "no_uv.glb")
    r = _cli("render", path, "-o", tmp_path / "x.png")
    assert r.returncode == 2
    assert r.stderr.strip().splitlines()[-1] == (f"inshade: error: {path}: meshes: materials have textures, "
                                                 "but no primitive has TEXCOORD_0")


def test_viewer_opens_a_glb(assets, tmp_path):
    r = subprocess.run(["xvfb-run", "-a", sys.executable, "-m", "inshade.cli", "view", str(assets["showcase"]),
                        "--frames", "2", "--screenshot", str(tmp_path / "view.png")],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "view.png").is_file()


def test_reference_pass_is_deterministic_and_lit(gl, assets):
    scene = load_scene(assets["tiles_torus"])
    renderer = SceneRenderer(scene, gl)
    try:
        camera = scene.make_camera()
        a = _draw(renderer, camera, 64, 64)
        renderer.release()
        renderer = SceneRenderer(load_scene(assets["tiles_torus"]), gl)
        b = _draw(renderer, camera, 64, 64)
    finally:
        renderer.release()
    np.testing.assert_array_equal(a, b)
    assert np.isfinite(a).all() and a.max() > 0.2
    assert math.isclose(load_gltf(assets["tiles_torus"]).materials[0].emissive[0], 1.0)


def test_minified_colour_textures_average_light(gl, tmp_path):
    """A base colour texture of black and white texels seen from afar reads as their mean in light,
    0.5, as the spec asks (filtering in linear light): decoding after an 8-bit filter reads 0.22."""
    from inshade.geometry.gltf_write import GltfBuilder, Primitive

    side = 64
    i = np.arange(side)
    image = np.full((side, side, 4), 255, np.uint8)
    image[..., :3] = np.where((i[:, None] + i[None, :]) % 2 == 0, 0, 255)[..., None]
    b = GltfBuilder()
    mat = b.material({"pbrMetallicRoughness": {"baseColorTexture": {"index": b.texture(b.image(image))},
                                               "metallicFactor": 0.0}})
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
    b.node(b.mesh([Primitive(v, np.array([[0, 1, 2], [0, 2, 3]]), np.tile([0.0, 0.0, 1.0], (4, 1)), uv,
                             np.tile([1.0, 0.0, 0.0, 1.0], (4, 1)), mat)]))
    scene = load_scene(b.write(tmp_path / "checker.glb"))
    renderer = SceneRenderer(scene, gl)
    try:
        view = _draw(renderer, scene.make_camera(), 16, 16, view="base_color")   # ~8 texels a pixel
        covered = renderer.gbuffer.read()[0][::-1][..., 3] > 0
    finally:
        renderer.release()
    inner = covered & np.roll(covered, 1, 0) & np.roll(covered, -1, 0) & np.roll(covered, 1, 1) & np.roll(covered, -1, 1)
    assert inner.sum() > 10
    np.testing.assert_allclose(view[inner], 0.5, atol=0.03)


def test_each_resampled_image_is_named_with_what_it_costs():
    from inshade.runtime.materials import resampling_notes

    images = [np.zeros((64, 64, 4), np.uint8), np.zeros((16, 32, 4), np.uint8), np.zeros((128, 128, 4), np.uint8)]
    notes = resampling_notes(images, [0, 1, 2], 64)
    assert notes == ["image 1 (32x16) resampled to the 64x64 layers of one array: enlarged (no detail lost)",
                     "image 2 (128x128) resampled to the 64x64 layers of one array: reduced (detail is lost: "
                     "GL_MAX_TEXTURE_SIZE or the 512 MB budget caps the layers)"]
