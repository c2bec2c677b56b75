"""di_pbr_set's glTF mode (``inshade train di_pbr_set --gltf FILE``: techniques/di_pbr_set/gltf_lanes.py,
gltf_asset.py, passes/mesh_pbr_set_gltf.frag) on the procedural tiles torus: the uv rectangle the
lanes are baked over, the asset folder, the split view against the glTF reference pass, and the
one-line refusals.

The asset is trained smaller than the quick preset (a 128^2 bake instead of the 512^2 the textures
ask for, 300 steps instead of 3000: ~15 s of training here instead of ~4 min), so its quality
floors are this run's, measured on llvmpipe with seed 0: 23.3 dB render PSNR against the reference
at the scene camera (floor 21 dB) and 18.9 dB over all GLSL-decoded lanes against the bake (floor
17 dB).

Bounds:
- the split view's left half and the reference view against techniques/gltf_pbr's pass drawn from
  the same file, camera, lights and environment: bit-identical (the same gltf_surface and
  gltf_shade, the same G-buffer);
- the split view's right half against the DI view: bit-identical (the same program, another uniform).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from inshade.geometry import gltf_scenes
from inshade.geometry.gltf_sample import material_channels
from inshade.geometry.gltf_write import GltfBuilder, Primitive
from inshade.geometry.mesh import mesh_uv, shading_normals, torus
from inshade.techniques.di_pbr_set import ERROR_SCALE, GLTF_VIEWS
from inshade.techniques.di_pbr_set import gltf_lanes as L
from inshade.techniques.di_pbr_set.render import render_views
from inshade.techniques.di_pbr_set.report import render_psnr

SIZE, STEPS, RENDER = 128, 300, 128
RENDER_FLOOR_DB = 21.0      # measured 23.3 dB
LANES_FLOOR_DB = 17.0       # measured 18.9 dB


def _train(argv: list[str]) -> int:
    from inshade import cli

    before = torch.get_num_threads()
    torch.set_num_threads(1)        # many small ops: one thread is faster on a shared machine
    try:
        return cli.main(["train", "di_pbr_set", *argv])
    finally:
        torch.set_num_threads(before)


@pytest.fixture(scope="module")
def torus_file(tmp_path_factory) -> Path:
    return gltf_scenes.tiles_torus().write(tmp_path_factory.mktemp("gltf") / "tiles_torus.glb")


@pytest.fixture(scope="module")
def asset(torus_file, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("pbr_gltf") / "tiles"
    rc = _train(["--gltf", str(torus_file), "--size", str(SIZE), "--steps", str(STEPS), "--render", str(RENDER),
                 "-o", str(out)])
    assert rc == 0
    return out


# -- the uv rectangle ------------------------------------------------------------------------------

def _same_content(asset, m, domain, gen):
    """The material at random mesh uv equals the material at the uv the bake's texel stands for."""
    corners = mesh_uv(asset.mesh)[asset.mesh.faces.reshape(-1)]
    lo, hi = corners.min(0), corners.max(0)
    uv = lo + gen.random((2000, 2)) * (hi - lo)
    a = material_channels(asset, m, uv)
    b = material_channels(asset, m, domain.from_bake(domain.to_bake(uv)))
    return max(float(np.abs(a[k] - b[k]).max()) for k in ("base_color", "normal", "roughness", "occlusion",
                                                          "metallic"))


def test_a_rotated_transform_makes_the_bake_span_the_mesh_uv(torus_file):
    asset, m, domain = L.load(torus_file, None)
    # the torus's uv run over [0, 2] x [0, 1]; base colour and normal are scaled 2x and rotated 0.3 rad,
    # so no whole step of u or v is a whole texture period: the bake spans the mesh's rectangle
    assert (m, domain.origin, domain.extent, domain.repeat) == (0, (0.0, 0.0), (2.0, 1.0), (False, False))
    # 128-texel textures at 2x along u over 2 units of u: 512 texels keep their resolution
    assert L.bake_size(asset, m, domain) == (512, False)
    gen = np.random.default_rng(0)
    assert _same_content(asset, m, domain, gen) < 1e-9
    # what fract(uv) would have read instead is another part of the texture
    uv = np.stack([1.0 + gen.random(500), gen.random(500)], 1)
    moved = material_channels(asset, m, uv - [1.0, 0.0])["base_color"]
    assert np.abs(material_channels(asset, m, uv)["base_color"] - moved).max() > 0.1


def test_untransformed_textures_repeat_every_unit(tmp_path):
    b = gltf_scenes.tiles_torus()
    mat = b.doc["materials"][0]
    for info in (mat["pbrMetallicRoughness"]["baseColorTexture"], mat["normalTexture"]):
        info.pop("extensions")
    path = b.write(tmp_path / "plain.glb")
    asset, m, domain = L.load(path, None)
    assert (domain.origin, domain.extent, domain.repeat) == ((0.0, 0.0), (1.0, 1.0), (True, False))
    assert L.bake_size(asset, m, domain) == (128, False)
    assert _same_content(asset, m, domain, np.random.default_rng(1)) < 1e-9


def test_bake_lanes_hold_the_material(torus_file):
    asset, m, domain = L.load(torus_file, None)
    lanes = L.bake_lanes(asset, m, domain, 64)
    assert lanes.shape == (64, 64, 8) and np.array_equal(lanes, np.round(lanes * 255) / 255)
    from inshade.geometry.gltf_sample import texel_uv
    from inshade.metrics import srgb_oetf

    c = material_channels(asset, m, domain.from_bake(texel_uv(64)))
    flat = lanes.reshape(-1, 8)
    assert np.abs(flat[:, :3] - srgb_oetf(c["base_color"])).max() <= 0.5 / 255 + 1e-6
    assert np.abs(flat[:, 7] - c["metallic"]).max() <= 0.5 / 255 + 1e-6
    assert c["metallic"].max() > 0.5 and c["metallic"].min() == 0.0     # the tiles hold metal and dielectric
    angle = np.degrees(np.arccos(np.clip(np.sum(L.unit_normals(flat) * c["normal"], -1), -1, 1)))
    assert angle.max() < 2.0, angle.max()        # two 8-bit lanes and a rebuilt z


# -- the asset -------------------------------------------------------------------------------------

def test_asset_folder_and_metrics(asset, torus_file):
    for f in ("bundle.json", "weights.safetensors", "scene.json", "metrics.json", "report.md", "preview.png"):
        assert (asset / f).is_file(), f
    assert (asset / "source.glb").read_bytes() == torus_file.read_bytes()
    scene = json.loads((asset / "scene.json").read_text())
    assert scene["program"] == "passes/mesh_pbr_set_gltf.frag" and scene["mesh"] == "source.glb"
    assert scene["settings"]["view"]["choices"] == list(GLTF_VIEWS)
    bundle = json.loads((asset / "bundle.json").read_text())
    assert bundle["render"]["uv_domain"] == {"material": 0, "origin": [0.0, 0.0], "extent": [2.0, 1.0],
                                             "repeat": [False, False]}
    m = json.loads((asset / "metrics.json").read_text())
    assert m["settings"]["gltf"] == str(torus_file) and m["settings"]["material"] == 0
    assert m["settings"]["size"] == SIZE and m["bake"]["size_from_textures"] == 512
    assert m["texture"]["channels"] == 8 and m["texture"]["steps"] == STEPS
    exact = m["di_glsl_exact"]
    assert set(exact) >= {"psnr_albedo", "psnr_normal", "psnr_roughness", "psnr_occlusion", "psnr_metallic"}
    assert exact["psnr_all_lanes"] >= LANES_FLOOR_DB, exact
    assert m["render"]["psnr_di_vs_reference"] >= RENDER_FLOOR_DB, m["render"]
    assert "| DI (GLSL exact) |" in (asset / "report.md").read_text()


def _reference_scene(asset: Path):
    """techniques/gltf_pbr's pass over the asset's own file, camera, lights and environment."""
    from inshade.scene.description import parse_scene

    data = json.loads((asset / "scene.json").read_text())
    data.update(program="passes/gltf_pbr.frag", networks=[], labels=[])
    data["settings"]["view"] = {"type": "choice", "default": "shaded", "choices": ["shaded"],
                                "uniform": "u_gltf_view"}
    return parse_scene(data, root=asset, path=asset / "scene.json")


def test_split_is_the_reference_left_and_di_right(gl, asset):
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer

    views = render_views(asset, views=GLTF_VIEWS, ctx=gl)
    scene = _reference_scene(asset)
    r = SceneRenderer(scene, gl)
    try:
        reference = read_rgba(r.render_network(scene.make_camera(), RENDER, RENDER)).copy()
    finally:
        r.release()
    half = RENDER // 2
    covered = views["_gbuffer"][0][::-1, :, 3] != 0
    assert 0.1 < covered.mean() < 0.9
    assert np.array_equal(views["reference"], reference)
    assert np.array_equal(views["split"][:, :half], reference[:, :half])
    assert np.array_equal(views["split"][:, half:], views["di"][:, half:])
    # the error view: |DI - reference| x the scale, on every pixel (0 off the compressed material)
    np.testing.assert_allclose(views["error"][..., :3], np.abs(views["di"] - reference)[..., :3] * ERROR_SCALE,
                               atol=1e-5, rtol=1e-5)
    # the network is what the right half shows: it differs from the file's material on the mesh only
    assert np.abs(views["di"] - reference)[covered].max() > 0.05
    assert np.array_equal(views["di"][~covered], reference[~covered])
    on_material = covered & (np.rint(views["_gbuffer"][2][::-1, :, 2]) == 0)
    assert np.array_equal(on_material, covered)        # one material: every mesh pixel is compressed
    db = render_psnr(views["di"], reference, on_material)
    assert db >= RENDER_FLOOR_DB, db
    assert db == pytest.approx(json.loads((asset / "metrics.json").read_text())["render"]["psnr_di_vs_reference"],
                               abs=1e-3)


def test_cli_render_draws_the_asset(asset, tmp_path):
    from inshade import cli

    out = tmp_path / "frame.png"
    assert cli.main(["render", str(asset), "-o", str(out), "--width", "64", "--height", "64", "--set", "view=di"]) == 0
    assert out.is_file()


def test_export_gltf_writes_the_decoded_material_back(gl, asset, tmp_path):
    """export-gltf bakes the DI lanes through their GLSL into textures mapped onto the mesh's uv by a
    texture transform; the file passes the Khronos validator, and read back at points of the mesh
    (CPU bilinear of its textures) it holds what DI decodes there, up to 8-bit texels and the
    bilinear reconstruction of a 512-texel bake; the channels DI does not hold are the file's."""
    from inshade.bundle import load
    from inshade.codegen.network import generate
    from inshade.geometry.gltf import load_gltf
    from inshade.geometry.gltf_sample import material_channels
    from inshade.geometry.mesh import mesh_uv
    from inshade.runtime.gltf_export import export_gltf
    from inshade.runtime.network import NetworkEvaluator
    from inshade.techniques.di_pbr_set.gltf_lanes import UvDomain, decoded_channels
    from test_gltf import validate

    out = tmp_path / "decoded.glb"
    done = export_gltf(asset, out, size=512)
    assert done.material == "decoded"
    assert validate(out)[0]["errors"] == 0
    back, source = load_gltf(out), load_gltf(asset / "source.glb")
    (m,) = back.materials
    assert m.emissive_texture is not None and m.emissive == source.materials[0].emissive
    rng = np.random.default_rng(0)
    faces = back.mesh.faces[rng.integers(0, len(back.mesh.faces), 2000)]
    w = rng.dirichlet(np.ones(3), 2000)
    uv = np.einsum("nk,nkj->nj", w, mesh_uv(back.mesh)[faces])
    got = material_channels(back, 0, uv)
    bundle = load(asset)
    domain = UvDomain.from_dict(bundle.meta["render"]["uv_domain"], "bundle")
    ev = NetworkEvaluator(gl, generate(bundle))
    try:
        lanes = ev(domain.to_bake(uv).astype(np.float32))
    finally:
        ev.release()
    want = decoded_channels(lanes)
    for k in ("base_color", "roughness", "occlusion", "metallic"):
        err = np.abs(got[k] - want[k])
        assert np.median(err) < 2 / 255 and np.percentile(err, 99) < 0.05, (k, np.median(err), err.max())


# -- refusals --------------------------------------------------------------------------------------

def _untextured(tmp_path) -> Path:
    b = GltfBuilder()
    mesh = torus(segments=(16, 8), tiles=(1.0, 1.0))
    mat = b.material({"name": "plain", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0]}})
    b.node(b.mesh([Primitive(mesh.vertices, mesh.faces, shading_normals(mesh), mesh_uv(mesh), None, mat)]))
    return b.write(tmp_path / "untextured.glb")


def _textured_without_uv(tmp_path, with_other_uv: bool, textured_uv: bool = False) -> Path:
    """A textured material on triangles without TEXCOORD_0 (unless ``textured_uv``; and, if
    ``with_other_uv``, a second primitive of a plain material that has them)."""
    b = GltfBuilder()
    tex = b.texture(b.image(gltf_scenes.tile_textures(16)["base_color"]))
    textured = b.material({"name": "tiles", "pbrMetallicRoughness": {"baseColorTexture": {"index": tex}}})
    mesh = torus(segments=(16, 8), tiles=(1.0, 1.0))
    prims = [Primitive(mesh.vertices, mesh.faces, shading_normals(mesh), mesh_uv(mesh) if textured_uv else None,
                       None, textured)]
    if with_other_uv:
        other = b.material({"name": "plain"})
        prims.append(Primitive(mesh.vertices * 0.5, mesh.faces[:10], None, mesh_uv(mesh), None, other))
    b.node(b.mesh(prims))
    return b.write(tmp_path / f"no_uv_{int(with_other_uv)}{int(textured_uv)}.glb")


@pytest.mark.parametrize("case", ["no_uv_file", "no_uv_material", "unreadable", "missing", "untextured",
                                  "untextured_material", "material_index", "material_alone"])
def test_bad_input_is_one_line(case, tmp_path, torus_file, capsys):
    argv = {"no_uv_file": lambda: ["--gltf", str(_textured_without_uv(tmp_path, False))],
            "no_uv_material": lambda: ["--gltf", str(_textured_without_uv(tmp_path, True))],
            "unreadable": lambda: ["--gltf", str(_write(tmp_path / "junk.glb", b"glTF but not really"))],
            "missing": lambda: ["--gltf", str(tmp_path / "absent.glb")],
            "untextured": lambda: ["--gltf", str(_untextured(tmp_path))],
            "untextured_material": lambda: ["--gltf", str(_textured_without_uv(tmp_path, True, True)), "--material", "1"],
            "material_index": lambda: ["--gltf", str(torus_file), "--material", "3"],
            "material_alone": lambda: ["--material", "0"]}[case]()
    expected = {"no_uv_file": ": meshes: materials have textures, but no primitive has TEXCOORD_0",
                "no_uv_material": ": meshes[0].primitives[0]: material 0 (tiles).base_color reads TEXCOORD_0, but the "
                                  "primitive has none",
                "unreadable": "junk.glb: ",
                "missing": "absent.glb: no such file",
                "untextured": ": materials: no material has a base colour",
                "untextured_material": ": materials[1] (plain): has no base colour",
                "material_index": ": materials: --material 3: the file has 1 material(s)",
                "material_alone": "--material: only with gltf"}[case]
    out = tmp_path / "never"
    capsys.readouterr()
    assert _train([*argv, "--steps", "1", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("inshade: error: ") and expected in err[0], err
    if case != "material_alone":
        assert err[0].startswith(f"inshade: error: {argv[1]}: ")
    assert not out.exists()          # refused before the asset folder is made


def _write(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path
