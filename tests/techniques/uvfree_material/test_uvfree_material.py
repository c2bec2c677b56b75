"""uvfree_material end to end: the quick preset trains an asset; its material network agrees with
torch under the parity rule at (triangle, barycentric) points, including points on shared edges
and vertices named from every adjacent face; the pass decodes the visibility buffer's points as
torch does; every view, channel and overlay draws; the scene refuses a mesh other than the
bundle's; the trainer's bad inputs are one error line and exit status 2."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from inshade.metrics import srgb_eotf

from parity import assert_parity, glsl_eval
from uvfree_assets import train_quick

W, H = 64, 64


@pytest.fixture(scope="module")
def asset(tmp_path_factory):
    return train_quick(tmp_path_factory.mktemp("uvf") / "uvfree_material_test", object_name="stump_low",
                       config="balanced", steps=40)


@pytest.fixture(scope="module")
def graph(asset):
    from inshade.bundle import load
    from inshade.models import GraphModule

    return GraphModule.from_bundle(load(asset / "material"))


def test_asset_folder_holds_the_bundle_mesh_and_reference(asset):
    from inshade.bundle import load
    from inshade.components.mesh_features.emit import TOPOLOGY_LAYOUTS, topology_layout
    from inshade.geometry.mesh import load_mesh
    from inshade.techniques.uvfree_material.model import CHANNELS, KIND

    bundle = load(asset / "material")
    assert bundle.kind == KIND and bundle.out_dim == len(CHANNELS)
    assert [p.dtype for p in bundle.inputs] == ["uint", "float"]
    node = next(n for n in bundle.nodes if n.type == "mesh_features")
    assert node.params["faces"] == len(load_mesh(asset / "mesh.obj").faces)
    table = bundle.tensors["features.table"]
    assert np.array_equal(table, table.astype(np.float16).astype(np.float32)), "fp16 features, as the texture holds"
    metrics = json.loads((asset / "metrics.json").read_text())
    mem = metrics["memory"]
    # as the textures hold them: fp16 rows, and the owner tables in their packed layout (12, 16 or 24 B
    # per face) plus the rows' padding
    corners, edges = bundle.tensor(node, "corners"), bundle.tensor(node, "edges")
    packed = TOPOLOGY_LAYOUTS[topology_layout(corners, edges)][2](corners, edges)
    assert mem["features_bytes"] == table.size * 2 and mem["topology_bytes"] >= packed.nbytes
    for name in ("albedo.png", "normal.png", "rma.png", "scene.json"):
        assert (asset / name).is_file()


def _shared_points(asset, rng, n_random=96):
    """Random interior points, plus every mesh vertex and edge midpoint named from each face that has
    it (so both sides of an edge and all faces around a vertex), plus sub-triangle boundaries."""
    from inshade.geometry.mesh import load_mesh
    from inshade.geometry.mesh_topology import weld

    mesh = load_mesh(asset / "mesh.obj")
    welded, _ = weld(mesh.vertices, mesh.faces)
    faces = rng.choice(len(welded), 24, replace=False)
    # the faces sharing welded vertex / edge with the chosen ones
    rows, groups = [], []
    for f in faces:
        for slot in range(3):
            v = welded[f, slot]
            around = np.argwhere(welded == v)
            groups.append([len(rows) + i for i in range(len(around))])
            rows += [[k, *np.eye(3)[s][:2]] for k, s in around]
            a, b = welded[f, slot], welded[f, (slot + 1) % 3]
            sharing = [k for k in np.argwhere((welded == a).any(1) & (welded == b).any(1))[:, 0]]
            group = []
            for k in sharing:
                t = np.zeros(3)
                t[list(welded[k]).index(a)] = 0.5
                t[list(welded[k]).index(b)] = 0.5
                group.append(len(rows))
                rows.append([k, t[0], t[1]])
            groups.append(group)
    r = rng.random((n_random, 2))
    s = np.sqrt(r[:, 0])
    rand = np.c_[rng.integers(0, len(welded), n_random), 1 - s, s * (1 - r[:, 1])]
    grid = np.c_[rng.integers(0, len(welded), 8), np.array([0.25, 0.5, 0.75, 0.125, 0.375, 0.0, 0.5, 0.25]),
                 np.array([0.25, 0.25, 0.0, 0.5, 0.125, 0.5, 0.5, 0.75])]
    return np.r_[np.array(rows), rand, grid].astype(np.float32), groups


def test_material_network_matches_torch_and_is_continuous_across_faces(gl, asset, graph):
    from inshade.bundle import load

    x, groups = _shared_points(asset, np.random.default_rng(3))
    with torch.no_grad():
        want = graph(torch.from_numpy(x)).numpy()
    for g in groups:   # one surface point, named from every face that has it: one value (seamless)
        np.testing.assert_allclose(want[g], np.broadcast_to(want[g[0]], want[g].shape), rtol=0, atol=1e-6)
    assert_parity(glsl_eval(gl, load(asset / "material"), x), want, what="uvfree material network")


def _renderer(asset, **settings):
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    return SceneRenderer(load_scene(asset), settings=settings)


def test_pass_decodes_the_visibility_buffer_points_like_torch(asset, graph):
    """The channel views of the decoded material show srgb_eotf(clamp(stored value)); at every covered
    pixel torch, fed the visibility buffer's (face, t0, t1), gives the same (the parity rule, on top
    of the GLSL pow's few ulp)."""
    r = _renderer(asset, view="decoded")
    try:
        scene = r.scene
        camera = scene.make_camera()
        shown = {}
        for channel in ("albedo", "normal", "roughness", "metallic", "ao"):
            r.set_setting("channel", channel)
            r.render_network(camera, W, H)
            shown[channel] = r.read("network")[::-1]   # image orientation -> data orientation (the G-buffer's)
        position, *_, primitive, bary = r.gbuffer.read()
    finally:
        r.release()
    covered = position[..., 3] == 1.0
    assert covered.mean() > 0.2
    x = np.c_[primitive[covered].astype(np.float32), bary[covered]]
    with torch.no_grad():
        stored = np.clip(graph(torch.from_numpy(x)).numpy(), 0, 1)
    expect = {"albedo": stored[:, 0:3], "normal": stored[:, 3:6], "roughness": stored[:, 6:7].repeat(3, 1),
              "metallic": stored[:, 7:8].repeat(3, 1), "ao": stored[:, 8:9].repeat(3, 1)}
    for channel, values in expect.items():
        got = shown[channel][covered][:, :3]
        np.testing.assert_allclose(got, srgb_eotf(values.astype(np.float64)), rtol=2e-5, atol=2e-5,
                                   err_msg=f"channel {channel}")


@pytest.mark.parametrize("settings", [{"view": v} for v in ("decoded", "reference", "split", "error")]
                         + [{"view": "split", "channel": c} for c in ("shaded", "albedo", "normal", "ao")]
                         + [{"view": "decoded", "wireframe": w} for w in ("triangles", "level")])
def test_every_view_channel_and_overlay_draws(asset, settings):
    r = _renderer(asset, **settings)
    size = 4 * W if settings.get("wireframe") else W   # the overlay draws cells three pixels or more across
    try:
        r.render_network(r.scene.make_camera(), size, size)
        image = r.read("network")
    finally:
        r.release()
    rgb, covered = image[..., :3], image[..., 3] > 0
    assert np.isfinite(rgb).all() and covered.mean() > 0.2
    if settings.get("wireframe"):
        orange = (np.abs(rgb - np.array([0.8, 0.44, 0.08]) - 0.2 * rgb).max(-1) < 0.25) & covered
        assert orange.mean() > 0.005, "the overlay draws edges"


def test_wireframe_level_refines_the_triangle_overlay(asset):
    """A level's sub-triangles draw more edges than the faces while the screen resolves them; a level
    finer than the pixels fades out instead of covering the surface (cells under three pixels draw
    no lines)."""
    def edges(**s):
        r = _renderer(asset, view="decoded", channel="albedo", **s)
        try:
            r.render_network(r.scene.make_camera(), 4 * W, 4 * H)
            plain = r.read("network")[..., :3].copy()
        finally:
            r.release()
        return plain

    base = edges(wireframe="off")
    covered = (np.abs(base).max(-1) > 0).sum()
    tri = (np.abs(edges(wireframe="triangles") - base).max(-1) > 1e-4).sum()
    fine = (np.abs(edges(wireframe="level", wire_level=1) - base).max(-1) > 1e-4).sum()
    finest = (np.abs(edges(wireframe="level", wire_level=7) - base).max(-1) > 1e-4).sum()
    assert 0 < tri < fine, (tri, fine)
    assert finest < fine and finest < 0.2 * covered, (finest, fine, covered)


def test_scene_refuses_a_mesh_other_than_the_bundles(asset, tmp_path):
    from inshade.scene.description import SceneError, load_scene

    other = tmp_path / "other"
    shutil.copytree(asset, other)
    scene = json.loads((other / "scene.json").read_text())
    scene["mesh"] = {"shape": "sphere", "segments": 8}
    (other / "scene.json").write_text(json.dumps(scene))
    with pytest.raises(SceneError, match="faces; the material bundle was trained on"):
        load_scene(other)
    # same face count, faces in another order: the welded topology digest differs
    from inshade.geometry.mesh import load_mesh, obj_text

    mesh = load_mesh(asset / "mesh.obj")
    flipped = trimesh.Trimesh(mesh.vertices, np.asarray(mesh.faces)[::-1], visual=mesh.visual, process=False)
    (other / "mesh.obj").write_text(obj_text(flipped))
    scene["mesh"] = "mesh.obj"
    (other / "scene.json").write_text(json.dumps(scene))
    with pytest.raises(SceneError, match="not the mesh the material bundle was trained on"):
        load_scene(other)


def _train_cli(*args):
    return subprocess.run([sys.executable, "-m", "inshade.cli", "train", "uvfree_material", *args],
                          capture_output=True, text=True, timeout=300, env={**os.environ, "OMP_NUM_THREADS": "1"})


def _quad_mesh(path: Path, uv: bool, faces=((0, 1, 2), (0, 2, 3))):
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1, 0, 0]], float)
    visual = trimesh.visual.TextureVisuals(uv=v[:, :2]) if uv else None
    m = trimesh.Trimesh(v, np.array(faces), visual=visual, process=False)
    from inshade.geometry.mesh import obj_text

    path.write_text(obj_text(m) if uv else m.export(file_type="obj"))
    return path


def test_training_bad_inputs_are_one_error_line(tmp_path, asset):
    textures = asset   # albedo/normal/rma PNGs
    cases = [
        (["--mesh", str(_quad_mesh(tmp_path / "nouv.obj", uv=False)), "--textures", str(textures)],
         "has no texture coordinates"),
        (["--table-size", "1000"], "table_size: must be a power of two, got 1000"),
        (["--textures", str(textures)], "--textures: goes with --mesh"),
    ]
    for i, (args, message) in enumerate(cases):   # a fresh folder each: a refused one would be the one error
        res = _train_cli("--preset", "quick", "--steps", "2", "--no-preview", "--out", str(tmp_path / f"o{i}"), *args)
        assert res.returncode == 2, (args, res.stderr[-2000:])
        lines = [ln for ln in res.stderr.splitlines() if ln.startswith("inshade: error:")]
        assert len(lines) == 1 and message in lines[0], (args, res.stderr[-2000:])


def test_degenerate_faces_are_dropped_by_the_loader_before_ids_are_given(tmp_path, asset):
    """A face whose corners weld to two positions has zero area: geometry/mesh.py load_mesh drops it
    when the trainer writes and reads the mesh, exactly as the renderer's loader does, so face ids agree."""
    from inshade.bundle import load

    path = _quad_mesh(tmp_path / "weld.obj", uv=True, faces=((0, 1, 2), (1, 4, 3)))
    out = train_quick(tmp_path / "weld", mesh_path=path, textures_dir=asset, steps=2)
    assert next(n for n in load(out / "material").nodes if n.type == "mesh_features").params["faces"] == 1


def test_non_manifold_edges_train_and_render_by_the_documented_rule(tmp_path, asset):
    """Three faces on one edge: the lowest face owns it (geometry/mesh_topology.py), training runs."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1]], float)
    mesh = trimesh.Trimesh(v, [[0, 1, 2], [1, 0, 3], [0, 1, 4]], process=False,
                           visual=trimesh.visual.TextureVisuals(uv=v[:, :2] * 0.4 + 0.5))
    from inshade.geometry.mesh import obj_text

    (tmp_path / "fin.obj").write_text(obj_text(mesh))
    out = train_quick(tmp_path / "fin", mesh_path=tmp_path / "fin.obj", textures_dir=asset, steps=3)
    from inshade.bundle import load

    edges = load(out / "material").tensors["features.edges"]
    assert (edges[:, 2] >> 4 == 0).all(), "the shared edge (opposite slot 2 in every face) is owned by face 0"


def test_cli_render_opens_the_asset(asset, tmp_path):
    res = subprocess.run([sys.executable, "-m", "inshade.cli", "render", str(asset), "-o", str(tmp_path / "r.png"),
                          "--width", "48", "--height", "48", "--set", "view=split"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    assert (tmp_path / "r.png").is_file() and (tmp_path / "r.png.json").is_file()


def test_u8_quantised_asset_matches_torch_and_keeps_its_quality(gl, asset, tmp_path):
    """quantize.py: post-training u8 tables (half the feature bytes), the whole material network
    GLSL vs torch on the bundle's dequantised values; a short quantisation-aware fine-tune exports
    what it trained on; bad inputs are one error line."""
    from inshade.bundle import load
    from inshade.models import GraphModule
    from inshade.techniques.uvfree_material.quantize import main, quantize_asset

    m = quantize_asset(asset, tmp_path / "u8")
    bundle = load(tmp_path / "u8" / "material")
    node = next(n for n in bundle.nodes if n.type == "mesh_features")
    assert node.params["precision"] == "u8" and bundle.tensor(node, "table").dtype == np.uint8
    src = m["memory_source"]
    assert m["memory"]["features_bytes"] == src["features_bytes"] // 2 + 2 * 4 * node.params["features"]
    assert m["memory"]["mlp_bytes"] == src["mlp_bytes"] and m["memory"]["features_precision"] == "u8"
    assert m["torch_quality"]["psnr_albedo"] > m["torch_quality_source"]["psnr_albedo"] - 1.0
    x, _ = _shared_points(asset, np.random.default_rng(5))
    g8 = GraphModule.from_bundle(bundle)
    with torch.no_grad():
        want = g8(torch.from_numpy(x)).numpy()
    assert_parity(glsl_eval(gl, bundle, x), want, what="u8 uvfree material network")
    qat = quantize_asset(asset, tmp_path / "qat", steps=3, batch=256)
    assert len(qat["history"]) == 2 and qat["memory"]["features_bytes"] == m["memory"]["features_bytes"]
    b2 = load(tmp_path / "qat" / "material")
    again = GraphModule.from_bundle(b2).export("t").tensors
    n2 = next(n for n in b2.nodes if n.type == "mesh_features")
    np.testing.assert_array_equal(again[n2.tensor_name("table")], b2.tensor(n2, "table"))
    assert main([str(asset), "--out", str(asset)]) == 2
    assert main([str(tmp_path / "nothing"), "--out", str(tmp_path / "x")]) == 2
    assert main([str(asset), "--out", str(tmp_path / "u8")]) == 2            # not empty, no --force
