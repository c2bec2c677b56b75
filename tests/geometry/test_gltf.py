"""glTF in and out: the reader (geometry/gltf.py) on the procedural assets (geometry/gltf_scenes.py)
and on the malformed corpus, the writer checked by the Khronos glTF validator (npm
``gltf-validator``), generated tangents against the reference MikkTSpace (npm ``mikktspace``).

Both npm packages are pinned in tests/gltf_tools/package.json; ``.ci/run`` installs them with
``npm ci --prefix tests/gltf_tools``.
"""
from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from inshade.geometry import gltf_scenes
from inshade.geometry.gltf import GltfError, gltf_uv, load_gltf, mikktspace_tangents, specular_glossiness_to_metallic
from inshade.geometry.gltf_write import GltfBuilder, Primitive
from inshade.geometry.mesh import load_mesh, mesh_uv, shading_normals, torus
from inshade.geometry.shapes import sphere, teapot

TOOLS = Path(__file__).resolve().parents[1] / "gltf_tools"


def _node(script: str, *args) -> str:
    node = shutil.which("node")
    assert node, "node is needed for the glTF validator tests (Debian nodejs; .ci/run installs it)"
    assert (TOOLS / "node_modules").is_dir(), f"run: npm ci --prefix {TOOLS}"
    return subprocess.run([node, str(TOOLS / script), *map(str, args)], check=True, capture_output=True,
                          text=True).stdout


def validate(*files) -> list[dict]:
    return [json.loads(line) for line in _node("validate.mjs", *files).splitlines()]


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    return gltf_scenes.write_all(tmp_path_factory.mktemp("gltf"))


def test_written_assets_pass_the_khronos_validator(written):
    for report in validate(*written.values()):
        assert report["errors"] == 0, report
        # the one warning allowed: the fabric's normal map without tangents, left out on purpose
        codes = {m[0] for m in report["messages"]}
        assert codes <= {"MESH_PRIMITIVE_GENERATED_TANGENT_SPACE"}, report


def test_writing_is_deterministic(tmp_path):
    a = gltf_scenes.showcase().glb()
    assert a == gltf_scenes.showcase().glb()
    assert len(a) % 4 == 0


def test_tiles_torus_reads_back_what_was_written(written):
    asset = load_gltf(written["tiles_torus"])
    mesh = torus(segments=(64, 32), tiles=(2.0, 1.0))
    # the node: translation (0, 0.1, 0), 20 degrees about x
    c, s = math.cos(math.radians(20)), math.sin(math.radians(20))
    rot = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    np.testing.assert_allclose(asset.mesh.vertices, np.asarray(mesh.vertices) @ rot.T + [0, 0.1, 0], atol=1e-6)
    np.testing.assert_array_equal(asset.mesh.faces, mesh.faces)
    np.testing.assert_allclose(mesh_uv(asset.mesh), mesh_uv(mesh), atol=1e-7)
    np.testing.assert_allclose(asset.mesh.vertex_attributes["normal"], shading_normals(mesh) @ rot.T, atol=1e-6)
    (m,) = asset.materials
    assert set(m.textures()) == {"base_color", "metallic_roughness", "normal", "occlusion", "emissive"}
    assert m.normal_texture.scale == pytest.approx(0.8) and m.occlusion_texture.scale == pytest.approx(0.9)
    assert m.base_color == pytest.approx((1.0, 0.95, 0.9, 1.0))
    # KHR_texture_transform: T * R * S on glTF uv
    t = m.base_color_texture.transform
    uv = np.array([0.3, 0.7, 1.0])
    cr, sr = math.cos(0.3), math.sin(0.3)
    x, y = 2.0 * 0.3, 1.0 * 0.7
    np.testing.assert_allclose(t @ uv, [cr * x + sr * y + 0.1, -sr * x + cr * y + 0.05, 1.0], atol=1e-12)
    np.testing.assert_array_equal(m.metallic_roughness_texture.transform, np.eye(3))
    tex = gltf_scenes.tile_textures()
    np.testing.assert_array_equal(asset.images[m.base_color_texture.image], tex["base_color"])
    assert asset.notes == [] and asset.extensions == ("KHR_texture_transform",)


def test_showcase_nodes_instances_and_materials(written):
    asset = load_gltf(written["showcase"])
    names = [m.name for m in asset.materials]
    assert names == ["car paint", "brushed metal", "fabric", "specular-glossiness", "default"]
    ball = sphere(0.5, 16)
    per = len(ball.faces)
    counts = np.bincount(asset.face_material, minlength=5)
    # paint ball twice (two nodes), metal and spec-gloss once, 5 instanced flat balls, 4x4x2 ground
    assert counts.tolist() == [2 * per, per, 32, per, 5 * len(sphere(0.2, 6).faces)]
    paint, brushed, fabric, spec, _ = asset.materials
    assert paint.clearcoat == 1.0 and paint.clearcoat_roughness == pytest.approx(0.05)
    assert brushed.anisotropy_strength == pytest.approx(0.8) and brushed.anisotropy_texture is not None
    assert fabric.sheen_color == pytest.approx((0.9, 0.8, 1.0)) and fabric.double_sided
    assert spec.converted_from == "KHR_materials_pbrSpecularGlossiness"
    assert any("converted to metallic-roughness" in n for n in asset.notes)
    assert any("MikkTSpace" in n for n in asset.notes)
    # the mirrored instance (scale x -1) keeps its triangles facing out: winding flipped back
    v, f = asset.mesh.vertices, asset.mesh.faces
    normal = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    corner = asset.mesh.vertex_attributes["normal"][f].mean(1)
    assert (np.sum(normal * corner, 1) > 0).mean() > 0.99
    # every vertex normal and tangent is unit, tangents orthogonal to normals where uv exist
    n, t = asset.mesh.vertex_attributes["normal"], asset.mesh.vertex_attributes["tangent"]
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)
    has = np.abs(t[:, 3]) == 1.0
    np.testing.assert_allclose(np.linalg.norm(t[has, :3], axis=1), 1.0, atol=1e-6)
    assert np.abs(np.sum(n[has] * t[has, :3], 1)).max() < 1e-3


def test_instancing_places_each_copy(written):
    asset = load_gltf(written["showcase"])
    rows = asset.mesh.vertices[np.unique(asset.mesh.faces[asset.face_material == 4])]
    centres = sorted(round(float(x)) for x in np.unique(np.round(rows[:, 0] + 0.0, 0)))
    assert {-2, -1, 0, 1, 2} <= set(centres)
    np.testing.assert_allclose(rows[:, 2].mean(), 2.2, atol=0.05)


@pytest.mark.parametrize("name", sorted(gltf_scenes.MALFORMED))
def test_malformed_files_are_refused_with_one_line(tmp_path, name):
    path = gltf_scenes.malformed(tmp_path)[name]
    field = gltf_scenes.MALFORMED[name][1]
    with pytest.raises(GltfError) as err:
        load_gltf(path)
    message = str(err.value)
    assert message.startswith(f"{path}: {field}"), message
    assert "\n" not in message


def test_malformed_corpus_is_malformed_for_the_validator_too(tmp_path):
    """The corpus is not our reader's taste: the Khronos validator reports an error for each file
    that breaks the spec (lines and a vendor extension are valid glTF that we cannot draw)."""
    files = gltf_scenes.malformed(tmp_path)
    reports = {Path(r["file"]).stem: r for r in validate(*files.values())}
    for name in ("missing_buffer", "accessor_out_of_range", "index_out_of_range", "not_gltf_2", "truncated_glb"):
        assert reports[name]["errors"] >= 1, reports[name]
    for name in ("lines", "unknown_required_extension"):
        assert reports[name]["errors"] == 0, reports[name]


def test_mesh_loader_reads_gltf_through_the_same_reader(written):
    mesh = load_mesh(written["tiles_torus"])
    asset = load_gltf(written["tiles_torus"])
    assert mesh_uv(mesh) is not None and len(mesh.faces) == len(asset.mesh.faces)
    np.testing.assert_allclose(mesh.bounds, asset.mesh.bounds, atol=1e-12)


def test_cli_refuses_a_malformed_file_with_one_line(tmp_path, capsys):
    from inshade.cli import main

    path = gltf_scenes.malformed(tmp_path)["accessor_out_of_range"]
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"inshade: error: {path}: accessors[0]"), err


@pytest.mark.parametrize("shape", ["torus", "sphere", "teapot"])
def test_generated_tangents_match_the_reference_mikktspace(tmp_path, shape):
    mesh = {"torus": lambda: torus(segments=(48, 24)), "sphere": lambda: sphere(0.5, 16), "teapot": lambda: teapot(6)}[shape]()
    v, f, n = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces), shading_normals(mesh)
    uv = gltf_uv(mesh_uv(mesh))
    ours = mikktspace_tangents(v, n, uv, f)[f.reshape(-1)]
    corners = f.reshape(-1)
    np.concatenate([v[corners], n[corners], uv[corners]], 1).astype(np.float32).tofile(tmp_path / "in.bin")
    _node("mikktspace.mjs", tmp_path / "in.bin", tmp_path / "out.bin")
    ref = np.fromfile(tmp_path / "out.bin", np.float32).reshape(-1, 4).astype(np.float64)
    cos = np.sum(ours[:, :3] * ref[:, :3], 1) / np.linalg.norm(ref[:, :3], axis=1)
    angle = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    assert angle.max() < 0.05, f"{shape}: tangents differ from MikkTSpace by up to {angle.max():.3g} degrees"
    # glTF's tangent w is MikkTSpace's sign negated (its uv run v down)
    np.testing.assert_array_equal(np.sign(ours[:, 3]), -np.sign(ref[:, 3]))


def test_specular_glossiness_conversion_keeps_pure_cases():
    # a black diffuse with a coloured specular is a metal of that colour; a grey diffuse with
    # F0 = 0.04 specular is a dielectric of that colour
    base, metal = specular_glossiness_to_metallic(np.array([[0.0, 0.0, 0.0], [0.5, 0.4, 0.3]]),
                                                  np.array([[0.9, 0.6, 0.3], [0.04, 0.04, 0.04]]))
    assert metal[0] == pytest.approx(1.0, abs=1e-3) and metal[1] == pytest.approx(0.0, abs=1e-6)
    np.testing.assert_allclose(base[0], [0.9, 0.6, 0.3], atol=1e-3)
    np.testing.assert_allclose(base[1], np.array([0.5, 0.4, 0.3]) * 0.96 / 0.96, atol=1e-6)


def test_builder_refuses_nothing_it_cannot_write_and_round_trips_flat_normals(tmp_path):
    b = GltfBuilder()
    b.node(b.mesh([Primitive(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]), np.array([[0, 1, 2]]))]))
    asset = load_gltf(b.write(tmp_path / "t.glb"))
    np.testing.assert_allclose(asset.mesh.vertex_attributes["normal"], [[0, 0, 1]] * 3)
    assert asset.materials[-1].name == "default" and mesh_uv(asset.mesh) is None
    assert validate(tmp_path / "t.glb")[0]["errors"] == 0


def test_separate_files_and_data_uris_read_the_same(tmp_path, written):
    import base64

    glb = load_gltf(written["showcase"])
    sep = load_gltf(gltf_scenes.showcase().write(tmp_path / "showcase.gltf"))
    assert (tmp_path / "showcase.bin").is_file()
    doc = json.loads((tmp_path / "showcase.gltf").read_text())
    doc["buffers"][0]["uri"] = ("data:application/octet-stream;base64,"
                                + base64.b64encode((tmp_path / "showcase.bin").read_bytes()).decode())
    (tmp_path / "inline.gltf").write_text(json.dumps(doc))
    inline = load_gltf(tmp_path / "inline.gltf")
    for other in (sep, inline):
        np.testing.assert_array_equal(other.mesh.vertices, glb.mesh.vertices)
        np.testing.assert_array_equal(other.face_material, glb.face_material)
        assert all(np.array_equal(x, y) for x, y in zip(other.images, glb.images))
    assert validate(tmp_path / "showcase.gltf")[0]["errors"] == 0


def _one_primitive(tmp_path, accessors: list, views: bytes, primitive: dict, name: str):
    """A GLB of one primitive from raw accessors over one buffer (for layouts the builder never writes)."""
    doc = {"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [primitive]}], "accessors": accessors,
           "bufferViews": [{"buffer": 0, "byteOffset": v[0], "byteLength": v[1], **({"byteStride": v[2]} if len(v) > 2 else {})}
                           for v in views[1]],
           "buffers": [{"byteLength": len(views[0])}]}
    path = tmp_path / name
    path.write_bytes(gltf_scenes._glb(doc, views[0]))
    return load_gltf(path)


def test_strips_fans_quantised_and_sparse_accessors(tmp_path):
    square = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
    data = square.tobytes()
    # a strip 0 1 2 3 is two triangles (0 1 2) (2 1 3): both counter-clockwise about +z
    strip = _one_primitive(tmp_path, [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                                       "min": [0, 0, 0], "max": [1, 1, 0]}], (data, [(0, 48)]),
                           {"attributes": {"POSITION": 0}, "mode": 5}, "strip.glb")
    np.testing.assert_array_equal(strip.mesh.faces.reshape(-1, 3).shape, (2, 3))
    np.testing.assert_allclose(strip.mesh.vertex_attributes["normal"], [[0, 0, 1]] * 6)
    fan = _one_primitive(tmp_path, [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                                     "min": [0, 0, 0], "max": [1, 1, 0]}], (data, [(0, 48)]),
                         {"attributes": {"POSITION": 0}, "mode": 6}, "fan.glb")
    assert len(fan.mesh.faces) == 2
    # KHR_mesh_quantization: normalised int16 positions; a sparse accessor moving one vertex
    q = np.array([[0, 0, 0, 0], [32767, 0, 0, 0], [0, 32767, 0, 0]], np.int16).tobytes()
    sparse_idx = np.array([2], np.uint8).tobytes() + b"\0\0\0"
    sparse_val = np.array([[0, -32767, 0, 0]], np.int16).tobytes()
    views = (q + sparse_idx + sparse_val, [(0, 24, 8), (24, 1), (28, 8)])   # int16 VEC3 padded to 8 bytes
    acc = [{"bufferView": 0, "componentType": 5122, "normalized": True, "count": 3, "type": "VEC3",
            "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5121}, "values": {"bufferView": 2}}}]
    asset = _one_primitive(tmp_path, acc, views, {"attributes": {"POSITION": 0}}, "quantised.glb")
    np.testing.assert_allclose(asset.mesh.vertices[:3], [[0, 0, 0], [1, 0, 0], [0, -1, 0]], atol=1e-12)


def test_a_textured_primitive_without_uv_is_refused_even_when_another_has_uv(tmp_path):
    b = GltfBuilder()
    mat = b.material({"pbrMetallicRoughness": {"baseColorTexture": {"index": b.texture(b.image(
        np.full((4, 4, 4), 200, np.uint8)))}}})
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    b.node(b.mesh([Primitive(tri, np.array([[0, 1, 2]]), uv=tri[:, :2], material=mat),
                   Primitive(tri + 2.0, np.array([[0, 1, 2]]), material=mat)]))
    path = b.write(tmp_path / "half.glb")
    with pytest.raises(GltfError, match=r"half.glb: meshes\[0\].primitives\[1\]: material 0 \(material 0\).base_color reads "
                                        r"TEXCOORD_0, but the primitive has none"):
        load_gltf(path)


def test_copy_gltf_brings_the_files_a_gltf_names(tmp_path):
    from inshade.geometry.gltf import copy_gltf

    src = gltf_scenes.tiles_torus().write(tmp_path / "src" / "torus.gltf")
    out = tmp_path / "out"
    assert copy_gltf(src, out) == "source.gltf"
    assert (out / "source.gltf").read_bytes() == src.read_bytes()
    assert (out / "torus.bin").read_bytes() == (src.parent / "torus.bin").read_bytes()
    assert len(load_gltf(out / "source.gltf").mesh.faces) == 4096
    glb = gltf_scenes.tiles_torus().write(tmp_path / "src" / "torus.glb")
    assert copy_gltf(glb, out, "mine") == "mine.glb" and (out / "mine.glb").read_bytes() == glb.read_bytes()
    doc = json.loads(src.read_text())
    doc["buffers"][0]["uri"] = "../elsewhere.bin"
    (tmp_path / "src" / "outside.gltf").write_text(json.dumps(doc))
    with pytest.raises(GltfError, match=r"outside.gltf: buffers\[0\].uri: '../elsewhere.bin' lies outside"):
        copy_gltf(tmp_path / "src" / "outside.gltf", out)
