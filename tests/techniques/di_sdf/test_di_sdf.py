"""DI-SDF (techniques/di_sdf/: data.py, model.py, train.py): signed distances from a mesh vs closed
forms, sizing, a tiny fit, the generated ``scene_sdf`` (exact LUT path) vs torch under the parity
rule, the hardware-filtered path within its documented bound, the sdf_diffuse render of the asset vs
the torch reference renderer, and bad input.

Tolerances: exact path, tests/parity.py's rule (1e-5 * max(1, |d|), world units). Fast path:
model.py ``fast_path_bound`` (the lookup-array bound of tests/components/test_lookup_array.py carried through
the cascade, times the bound radius). Renders at 48x48: PSNR >= 50 dB (linear, peak 1) over the
pixels where both executors hit or both miss; hit masks may differ only on a silhouette (as
tests/geometry/test_sdf.py).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.codegen.network_sdf import network_sdf_chunks
from inshade.techniques.di_sdf import data as di_data
from inshade.techniques.di_sdf import model as di_model
from inshade.techniques.di_sdf import train as di_sdf

from network_view import network_view
from parity import assert_parity, parity_settings, run_sample_pass

TINY = dict(rho=2.0, steps=80, batch=4096, samples=30000, lr=1e-2, seed=0)
TINY_BUDGET = 3 * 16 ** 3 + 8 ** 3          # N_p = 16, N_c = 8: 12,800 bytes


def _box_sdf(p, half):
    q = np.abs(p) - half
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(1), 0.0)


@pytest.fixture(scope="module")
def capsule():
    import trimesh

    return trimesh.creation.capsule(height=0.9, radius=0.35, count=[24, 24])


@pytest.fixture(scope="module")
def tiny(capsule, tmp_path_factory):
    """One tiny DI-SDF of a capsule, written as an asset folder (trained once per module)."""
    result = di_sdf.fit(capsule, TINY_BUDGET, progress=False, name="tiny_di_sdf", **TINY)
    out = di_sdf.write_asset(result, tmp_path_factory.mktemp("di") / "tiny_di_sdf", "tiny", preview_size=32)
    return result, out


# --- data --------------------------------------------------------------------------------------

def test_signed_distance_matches_box_closed_form():
    import trimesh

    half = np.array([0.5, 0.3, 0.4])
    box = trimesh.creation.box(extents=2 * half)
    band = 0.15
    query = di_data.DistanceQuery(box, band, seed=0, surface_samples=20000)
    p = np.random.default_rng(0).uniform(-0.8, 0.8, (4000, 3))
    exact = _box_sdf(p, half)
    got = query(p)
    inside_band = np.abs(exact) < band - 1e-9
    np.testing.assert_allclose(got[inside_band], exact[inside_band], atol=1e-6)
    np.testing.assert_allclose(got[~inside_band], np.sign(exact[~inside_band]) * band, atol=1e-6)


def test_samples_are_truncated_and_in_the_cube(capsule):
    frame = di_data.mesh_frame(capsule)
    s = di_data.make_samples(capsule, frame, 5000, 0.1, seed=3)
    assert s.q.dtype == np.float32 and np.abs(s.q).max() <= 1.0
    assert np.abs(s.d).max() <= 0.1 + 1e-7
    assert 0.0 < (np.abs(s.d[s.near]) < 0.1).mean() and (s.d[~s.near] == 0.1).mean() > 0.5
    assert np.isclose(s.near.mean(), 1 - di_sdf.DEFAULTS["uniform_fraction"], atol=1e-3)
    # the vertices lie strictly inside the bound sphere (margin), so the band fits in the cube
    assert np.linalg.norm(capsule.vertices - frame.center, axis=1).max() < frame.radius


def test_sizing_and_budget_errors():
    for kb in (13, 48, 200):
        s = di_model.plan(kb * 1024)
        assert s.n_primary % 8 == 0 and s.n_cascaded % 4 == 0
        assert s.bytes == 3 * s.n_primary ** 3 + s.n_cascaded ** 3 <= kb * 1024
    with pytest.raises(di_data.DiSdfError, match="budget"):
        di_model.plan(1000)


# --- the fit -----------------------------------------------------------------------------------

def test_tiny_fit(tiny):
    result, out = tiny
    m = result.metrics
    assert (m["n_primary"], m["n_cascaded"], m["bytes"]) == (16, 8, TINY_BUDGET)
    assert m["iou"] > 0.9 and m["surface_mae_per_radius"] < 0.03, m
    assert result.history.records[-1]["loss"] < result.history.records[1]["loss"]
    b = result.bundle
    assert b.meta["render"]["sdf"]["radius"] == pytest.approx(result.frame.radius)
    assert {b.node(k).params["bits"] for k in ("primary", "cascaded")} == {8}
    # the truncation band is a property of the array: every cell (so every distance) is in it
    cells = di_model.sdf_module(b).graph.nodes["cascaded"].table()
    assert float(cells.detach().abs().max()) <= m["truncation"] + 1e-6
    scene = json.loads((out / "scene.json").read_text())
    assert scene["sdf"] == {"network": "."} and (out / "preview.png").is_file()


def test_training_is_deterministic(capsule):
    kw = dict(TINY, steps=5, samples=8192, batch=4096)
    a = di_sdf.fit(capsule, TINY_BUDGET, progress=False, evaluate=False, **kw).bundle
    b = di_sdf.fit(capsule, TINY_BUDGET, progress=False, evaluate=False, **kw).bundle
    for k in a.tensors:
        np.testing.assert_array_equal(a.tensors[k], b.tensors[k])


# --- GLSL --------------------------------------------------------------------------------------

def _glsl_sdf(gl, bundle, points, lut_filter):
    """scene_sdf at points [N, 3] through passes/sdf_eval_test.frag."""
    chunks, generated = network_sdf_chunks(bundle, lut_filter=lut_filter)
    return run_sample_pass(gl, "passes/sdf_eval_test.frag", points, sampler="u_points", attachments=3, width=32,
                           chunks=chunks, generated=generated)[0][:, 0]


@parity_settings(max_examples=4)
@given(seed=st.integers(0, 2**16))
def test_scene_sdf_exact_path_parity(gl, tiny, capsule, seed):
    result, _ = tiny
    frame = result.frame
    rng = np.random.default_rng(seed)
    # the whole bound cube, plus points near the surface where the field is not flat
    near = di_data.make_samples(capsule, frame, 256, 0.1, uniform_fraction=0.0, seed=seed).q
    q = np.concatenate([rng.uniform(-1.0, 1.0, (256, 3)), near])
    p = frame.world(q).astype(np.float32)
    module = di_model.sdf_module(result.bundle)
    with torch.no_grad():
        ref = module(torch.from_numpy(p)).numpy()
    assert_parity(_glsl_sdf(gl, result.bundle, p, "exact"), ref, what="DI-SDF scene_sdf, exact path")


def test_scene_sdf_fast_path_within_bound(gl, tiny):
    result, _ = tiny
    p = result.frame.world(np.random.default_rng(5).uniform(-1.0, 1.0, (1024, 3))).astype(np.float32)
    exact = _glsl_sdf(gl, result.bundle, p, "exact").astype(np.float64)
    fast = _glsl_sdf(gl, result.bundle, p, "fast").astype(np.float64)
    bound = di_model.fast_path_bound(result.bundle) + 1e-5 * np.maximum(1.0, np.abs(exact))
    err = np.abs(fast - exact)
    assert np.isfinite(fast).all() and (err <= bound).all(), f"max err {err.max():.3g} > bound {bound.max():.3g}"


def test_asset_renders_like_torch(gl, tiny):
    """The asset's scene (SceneRenderer, sdf_diffuse + the DI-SDF's textures) vs models/sdf.py."""
    from inshade.scene.description import load_scene

    result, out = tiny
    scene = load_scene(out)
    size = 48
    cam = scene.make_camera()
    image, sh = network_view(gl, scene, size)
    ref = di_sdf.render_module(di_model.sdf_module(result.bundle), cam.uniforms(size, size), size, sh)
    from inshade.models.sdf import camera_rays, sh_background_t

    _, rd = camera_rays(cam.uniforms(size, size), size, size)
    env = sh_background_t(torch.from_numpy(sh), rd).numpy().reshape(size, size, 3)
    gl_hit = np.abs(image[..., :3] - env).max(-1) > 1e-5
    hit = ref["hit"]
    assert hit.mean() > 0.1, "the camera should see the shape"
    pad = np.pad(hit, 1, mode="edge")
    neigh = np.stack([pad[1 + dy:1 + dy + size, 1 + dx:1 + dx + size] for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    silhouette = (neigh != hit[None]).any(0)
    differ = gl_hit != hit
    assert differ.mean() <= 0.01 and not (differ & ~silhouette).any()
    agree = ~differ
    mse = float(np.mean((image[..., :3] - ref["rgba"][..., :3])[agree] ** 2))
    psnr = math.inf if mse == 0 else 10 * math.log10(1.0 / mse)
    assert psnr >= 50.0, f"PSNR {psnr:.1f} dB"


# --- bad input ---------------------------------------------------------------------------------

def test_bad_meshes_one_clear_error(tmp_path, capsule):
    import trimesh

    with pytest.raises(di_data.DiSdfError, match="no such file"):
        di_data.load_mesh(tmp_path / "nope.ply")
    junk = tmp_path / "junk.ply"
    junk.write_bytes(b"ply\nthis is not a mesh\n")
    with pytest.raises(di_data.DiSdfError, match=str(junk).replace("\\", "\\\\")):
        di_data.load_mesh(junk)
    open_mesh = capsule.copy()
    open_mesh.update_faces(np.arange(len(open_mesh.faces)) > 10)
    path = tmp_path / "open.ply"
    open_mesh.export(path)
    with pytest.raises(di_data.DiSdfError, match="not watertight"):
        di_data.load_mesh(path)
    with pytest.raises(di_data.DiSdfError, match="truncation"):
        di_sdf.fit(trimesh.creation.icosphere(1), TINY_BUDGET, truncation=0.0, progress=False)


def test_cli_reports_bad_input(tmp_path, capsys):
    assert di_sdf.main(["--mesh", str(tmp_path / "missing.obj"), "--out", str(tmp_path / "x")]) == 2
    assert "no such file" in capsys.readouterr().err


# --- the benchmark's pieces (the run itself is `inshade bench di_sdf`, minutes) ---------------------

def test_bench_equal_bytes_width():
    from inshade.techniques.di_sdf.bench import mlp_params, mlp_width_for_bytes
    from inshade.models.mlp_sdf import build

    for width, layers in ((7, 2), (38, 3), (71, 3)):
        g = build(width, layers)
        assert mlp_params(width, layers) == sum(p.numel() for p in g.parameters())
    w = mlp_width_for_bytes(TINY_BUDGET, 3)
    assert 4 * mlp_params(w, 3) <= TINY_BUDGET < 4 * mlp_params(w + 1, 3)


def test_bench_ground_truth_is_the_mesh():
    """The mesh ground truth of a sphere mesh: hits where the analytic sphere is hit (off the
    silhouette), normals close to the sphere's, shaded like the sdf pass."""
    import trimesh

    from inshade.techniques.di_sdf.bench import mesh_ground_truth
    from inshade.codegen.sdf import environment_sh
    from inshade.models.sdf import camera_rays
    from inshade.scene.camera import camera_from_dict

    size = 32
    mesh = trimesh.creation.icosphere(4, radius=0.6)
    cam = camera_from_dict(di_sdf.orbit_camera(di_data.Frame((0.0, 0.0, 0.0), 1.0)))
    u = cam.uniforms(size, size)
    gt = mesh_ground_truth(mesh, u, size, environment_sh("noon"))
    ro, rd = camera_rays(u, size, size)
    b = (ro * rd).sum(1)
    disc = (b * b - ((ro * ro).sum(1) - 0.36)).numpy().reshape(size, size)
    clear = np.abs(disc) > 0.02
    assert (gt["hit"][clear] == (disc[clear] > 0)).all()
    assert gt["hit"].mean() > 0.1 and np.isfinite(gt["rgba"]).all()
