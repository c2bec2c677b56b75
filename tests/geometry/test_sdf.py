"""Analytic SDF scenes (geometry/sdf.py): torch (models/sdf.py) vs generated GLSL (codegen/sdf.py,
shaders/lib/sdf.glsl), primitives vs closed forms, the sdf_diffuse pass vs the torch reference
renderer, bad scene files, deterministic chunks.

Tolerances: SDF values |glsl - torch| <= 1e-5 * max(1, |d|) (both are float32 with the same
operation order; drivers may contract to FMA and use their own atan/sin/cos). Renders: PSNR >= 50 dB
over all pixels at 64x64 in linear float (peak 1). Hit masks: a pixel may differ only on a
silhouette, i.e. if some 8-neighbour of it has the other hit status in the torch mask, and at most
1% of pixels may differ (a ray grazing an edge can cross hit_eps in one executor and not the other).
Inside the mask, colours may differ more than rounding at creases (hard booleans, polar sector
seams) where the central-difference normal straddles the crease; PSNR bounds those.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from inshade.codegen.sdf import SDF_CHUNK, environment_sh, sdf_chunk, sdf_chunks
from inshade.models.sdf import SdfModule, camera_rays, gradient, normals, render, sh_background_t
from inshade.geometry.sdf import SdfError, SdfScene, load_sdf, parse_sdf
from network_view import network_view
from parity import run_sample_pass

ROOT = Path(__file__).resolve().parents[2]
SCENES = ["creature", "mechanical", "occlusion"]


def _glsl_eval(gl, scene, points):
    out = run_sample_pass(gl, "passes/sdf_eval_test.frag", points, sampler="u_points", attachments=3, width=32,
                          chunks=sdf_chunks(scene))
    return out[0][:, 0], out[1][:, :3], out[2][:, :3]


def _check_values(gl, scene, points):
    d_gl, a_gl, n_gl = _glsl_eval(gl, scene, points)
    m = SdfModule(scene)
    p = torch.from_numpy(points)
    with torch.no_grad():
        d, a = m.evaluate(p)
    d = d.numpy()
    tol = 1e-5 * np.maximum(1.0, np.abs(d))
    bad = np.abs(d_gl - d) > tol
    assert not bad.any(), f"sdf mismatch at {points[bad][:3]}: glsl {d_gl[bad][:3]} torch {d[bad][:3]}"
    np.testing.assert_allclose(a_gl, a.numpy(), atol=1e-5)
    return n_gl, m


@pytest.mark.parametrize("name", SCENES)
def test_scene_values_glsl_vs_torch(gl, name):
    scene = load_sdf(ROOT / f"trained/sdf_{name}/sdf.json")
    rng = np.random.default_rng(1)
    c, r = np.asarray(scene.center, np.float32), scene.radius
    points = (c + rng.uniform(-r, r, (2048, 3))).astype(np.float32)
    n_gl, m = _check_values(gl, scene, points)
    # normals: central differences in both; differences of float32 distances over 2 * eps
    n_t = normals(m, torch.from_numpy(points)).numpy()
    assert np.percentile(np.abs(n_gl - n_t).max(-1), 99) < 1e-3


# colour ties: hard union/intersect children at equal distance ------------------------------------
def _children(scene, points):
    """Each child of the root boolean alone, in torch: distances [C, N], albedos [C, N, 3]."""
    d, a = [], []
    for child in scene.root.children:
        sub = SdfScene(root=child, center=scene.center, radius=scene.radius, trace=scene.trace)
        with torch.no_grad():
            dc, ac = SdfModule(sub).evaluate(torch.from_numpy(points))
        d.append(dc.numpy())
        a.append(ac.numpy())
    return np.stack(d), np.stack(a)


def test_mechanical_gear_tooth_ties_glsl_vs_torch(gl):
    """The gears' meshing teeth share their side faces (z = +-0.055) and tops (y = +-0.09): there
    the two gears' distances are equal up to rounding, which differs between torch and the driver
    (polar folding, rotations). Both executors must colour those faces alike: the first child.
    Points lie on and within ~1e-5 of the shared faces, between the teeth's fillets (x in
    [0.395, 0.455], where the two distances agree to 1e-7)."""
    scene = load_sdf(ROOT / "trained/sdf_mechanical/sdf.json")
    rng = np.random.default_rng(3)
    n = 2048
    x, y, z = rng.uniform(0.395, 0.455, n), rng.uniform(-0.085, 0.085, n), rng.uniform(-0.03, 0.03, n)
    side = rng.choice([-1.0, 1.0], n)
    on = np.concatenate([np.stack([x, y, side * 0.055], -1), np.stack([x, side * 0.09, z], -1)])
    near = on + rng.normal(0.0, 1e-5, on.shape)          # within a few 1e-5 of the shared faces
    points = np.concatenate([on, near]).astype(np.float32)
    _check_values(gl, scene, points)
    with torch.no_grad():
        alb = SdfModule(scene).albedo(torch.from_numpy(points)).numpy()
    d, a = _children(scene, points)
    assert (np.abs(d[0] - d[1]) <= 1e-6).all()
    np.testing.assert_array_equal(alb, a[0])


@pytest.mark.parametrize("op", ["union", "intersect"])
def test_hard_boolean_ties_pick_the_first_child(gl, op):
    """Two boxes sharing a face, one reached through a rotation by a full turn (same surface,
    different rounding): on and within rounding of the shared face both executors take the first
    child's colour; away from it, the nearer (union) or farther (intersect) child's."""
    box = {"type": "box", "size": [0.3, 0.3, 0.3]}
    root = {"type": op, "k": 0.0, "children": [
        {"type": "transform", "translate": [0.1, 0.0, 0.0], "child": box, "albedo": [1.0, 0.0, 0.0]},
        {"type": "transform", "translate": [-0.1, 0.0, 0.0], "rotate": {"axis": [0.3, 1.0, 0.2], "angle": 360.0},
         "child": box, "albedo": [0.0, 0.0, 1.0]}]}
    scene = parse_sdf({"format": "inshade.geometry.sdf", "version": 1, "bound": {"center": [0, 0, 0], "radius": 2},
                       "root": root})
    rng = np.random.default_rng(4)
    n = 4096
    # the shared faces y = +-0.3 and z = +-0.3 over the overlap x in [-0.2, 0.2], outside the boxes
    u, v = rng.uniform(-0.2, 0.2, n), rng.uniform(-0.25, 0.25, n)
    s = rng.choice([-1.0, 1.0], n)
    off = rng.choice([0.0, 1e-3, 0.05], n)                # on the faces, and above them (equal distances)
    pts = np.where((rng.uniform(size=n) < 0.5)[:, None],
                   np.stack([u, s * (0.3 + off), v], -1), np.stack([u, v, s * (0.3 + off)], -1))
    far = rng.uniform(-0.8, 0.8, (1024, 3))               # decided points (|d0 - d1| well above rounding)
    points = np.concatenate([pts, far]).astype(np.float32)
    _check_values(gl, scene, points)
    d, _ = _children(scene, points)
    with torch.no_grad():
        alb = SdfModule(scene).albedo(torch.from_numpy(points)).numpy()
    tied = np.abs(d[0] - d[1]) <= 1e-6
    assert tied.sum() > 1000
    assert (alb[tied] == [1.0, 0.0, 0.0]).all()
    decided = np.abs(d[0] - d[1]) > 1e-3
    first = d[0] < d[1] if op == "union" else d[0] > d[1]
    want = np.where(first[:, None], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(alb[decided], want[decided])


# hypothesis-random small scenes -------------------------------------------------------------------
_num = st.floats(0.125, 0.75, allow_nan=False, width=32)
_vec = st.lists(st.floats(-0.625, 0.625, width=32), min_size=3, max_size=3)
_colour = st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3)
_leaf = st.one_of(
    st.builds(lambda r: {"type": "sphere", "radius": r}, _num),
    st.builds(lambda s: {"type": "box", "size": s}, st.lists(_num, min_size=3, max_size=3)),
    st.builds(lambda s, f: {"type": "round_box", "size": [x + 0.1 for x in s], "radius": 0.1 * f},
              st.lists(_num, min_size=3, max_size=3), st.floats(0.0, 0.9)),
    st.builds(lambda a, b, r: {"type": "capsule", "a": a, "b": [x + 0.05 for x in b], "radius": r}, _vec, _vec, _num),
    st.builds(lambda R, r: {"type": "torus", "major": R, "minor": r * 0.5}, _num, _num),
    st.builds(lambda r, h: {"type": "cylinder", "radius": r, "height": h}, _num, _num),
    st.builds(lambda n, o: {"type": "plane", "normal": [n[0], n[1] + 1.0, n[2]], "offset": o}, _vec, _vec.map(lambda v: v[0])),
)


def _extend(children):
    op = st.sampled_from(["union", "subtract", "intersect"])
    k = st.sampled_from([0.0, 0.05, 0.2])
    boolean = st.builds(lambda o, kk, cs, col: {"type": o, "k": kk, "children": cs, "albedo": col},
                        op, k, st.lists(children, min_size=2, max_size=3), _colour)
    transform = st.builds(lambda c, t, ax, ang, s: {"type": "transform", "child": c, "translate": t,
                                                    "rotate": {"axis": [ax[0], ax[1], ax[2] + 1.0], "angle": ang},
                                                    "scale": s},
                          children, _vec, _vec, st.floats(-180, 180), st.floats(0.5, 1.5))
    repeat = st.builds(lambda c, s, n: {"type": "repeat", "child": c, "spacing": s, "count": n},
                       children, st.lists(st.sampled_from([0.0, 0.7, 1.1]), min_size=3, max_size=3)
                       .filter(lambda s: any(s)), st.lists(st.integers(0, 2), min_size=3, max_size=3))
    polar = st.builds(lambda c, n: {"type": "repeat_polar", "child": c, "count": n}, children, st.integers(1, 9))
    return st.one_of(boolean, transform, repeat, polar)


_tree = st.recursive(_leaf, _extend, max_leaves=5)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(root=_tree, seed=st.integers(0, 2**16))
def test_random_scenes_glsl_vs_torch(gl, root, seed):
    scene = parse_sdf({"format": "inshade.geometry.sdf", "version": 1, "bound": {"center": [0, 0, 0], "radius": 2},
                       "root": root})
    points = np.random.default_rng(seed).uniform(-1.5, 1.5, (256, 3)).astype(np.float32)
    _check_values(gl, scene, points)


# primitives vs closed forms -----------------------------------------------------------------------
def _prim(node):
    return SdfModule(parse_sdf({"format": "inshade.geometry.sdf", "version": 1, "bound": {"center": [0, 0, 0], "radius": 3},
                                "root": node}))


def test_primitives_closed_forms():
    rng = np.random.default_rng(2)
    p64 = rng.uniform(-2, 2, (4000, 3))
    p = torch.from_numpy(p64.astype(np.float32))
    q = p.double().numpy()
    ev = lambda node: _prim(node)(p).detach().double().numpy()  # noqa: E731
    np.testing.assert_allclose(ev({"type": "sphere", "radius": 0.7}), np.linalg.norm(q, axis=1) - 0.7, atol=1e-6)
    b = np.array([0.5, 0.3, 0.8])
    outside = np.linalg.norm(q - np.clip(q, -b, b), axis=1)
    inside = -np.min(b - np.abs(q), axis=1)
    exact_box = np.where(np.all(np.abs(q) <= b, axis=1), inside, outside)
    np.testing.assert_allclose(ev({"type": "box", "size": b.tolist()}), exact_box, atol=1e-6)
    # round box = box of the inner extents minus the radius: exact outside the inner box's offset
    rb = ev({"type": "round_box", "size": b.tolist(), "radius": 0.2})
    inner = b - 0.2
    out_inner = np.linalg.norm(q - np.clip(q, -inner, inner), axis=1)
    sel = np.any(np.abs(q) > inner, axis=1)
    np.testing.assert_allclose(rb[sel], out_inner[sel] - 0.2, atol=1e-6)
    # capsule: distance to a densely sampled segment
    a, bb = np.array([-0.4, 0.1, 0.2]), np.array([0.5, -0.3, 0.0])
    seg = a + np.linspace(0, 1, 4001)[:, None] * (bb - a)
    seg_d = np.min(np.linalg.norm(q[:, None, :] - seg[None], axis=2), axis=1) - 0.25
    np.testing.assert_allclose(ev({"type": "capsule", "a": a.tolist(), "b": bb.tolist(), "radius": 0.25}), seg_d,
                               atol=1e-4)
    # torus: distance to the circle of radius R in the xz plane, minus r
    t = np.linspace(0, 2 * np.pi, 20001)
    circle = np.stack([0.8 * np.cos(t), 0 * t, 0.8 * np.sin(t)], 1)
    tor = np.array([np.min(np.linalg.norm(circle - x, axis=1)) for x in q[:300]]) - 0.2
    np.testing.assert_allclose(ev({"type": "torus", "major": 0.8, "minor": 0.2})[:300], tor, atol=1e-4)
    # capped cylinder: 2D box in (radial, y)
    rad = np.hypot(q[:, 0], q[:, 2])
    w = np.stack([rad - 0.6, np.abs(q[:, 1]) - 0.4], 1)
    cyl = np.where(np.all(w <= 0, axis=1), w.max(1), np.linalg.norm(np.maximum(w, 0), axis=1))
    np.testing.assert_allclose(ev({"type": "cylinder", "radius": 0.6, "height": 0.4}), cyl, atol=1e-6)
    n = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    np.testing.assert_allclose(ev({"type": "plane", "normal": [1.0, 2.0, -0.5], "offset": 0.3}), q @ n - 0.3,
                               atol=1e-6)
    # transforms keep distances exact: a translated, rotated, scaled sphere
    tr = {"type": "transform", "translate": [0.2, -0.1, 0.3], "rotate": {"axis": [1, 1, 0], "angle": 33},
          "scale": 1.7, "child": {"type": "sphere", "radius": 0.4}}
    np.testing.assert_allclose(ev(tr), np.linalg.norm(q - [0.2, -0.1, 0.3], axis=1) - 0.68, atol=2e-6)
    # autograd gradient of an exact SDF is unit length away from the medial axis
    g = gradient(_prim({"type": "sphere", "radius": 0.7}), p).numpy()
    np.testing.assert_allclose(np.linalg.norm(g, axis=1), 1.0, atol=1e-5)


# rendering -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", SCENES)
def test_render_glsl_vs_torch(gl, name):
    from inshade.scene.description import load_scene

    scene = load_scene(ROOT / f"trained/sdf_{name}")
    size = 64
    cam = scene.make_camera()
    image, sh = network_view(gl, scene, size)
    ref = render(scene.sdf, cam.uniforms(size, size), size, size, sh)
    diff = image[..., :3] - ref["rgba"][..., :3]
    mse = float(np.mean(diff ** 2))
    psnr = math.inf if mse == 0 else 10 * math.log10(1.0 / mse)
    assert psnr >= 50.0, f"{name}: PSNR {psnr:.1f} dB"
    # hit masks: the GLSL pass writes alpha 1 everywhere, so its misses are the pixels showing the
    # environment colour the torch reference computes for that ray
    _, rd = camera_rays(cam.uniforms(size, size), size, size)
    env = sh_background_t(torch.from_numpy(sh), rd).numpy().reshape(size, size, 3)
    gl_hit = np.abs(image[..., :3] - env).max(-1) > 1e-5
    hit = ref["hit"]
    pad = np.pad(hit, 1, mode="edge")
    neigh = np.stack([pad[1 + dy:1 + dy + size, 1 + dx:1 + dx + size] for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    silhouette = (neigh != hit[None]).any(0)
    differ = gl_hit != hit
    assert differ.mean() <= 0.01
    assert not (differ & ~silhouette).any(), f"{name}: off-silhouette mask disagreement at {np.argwhere(differ & ~silhouette)[:5]}"


def test_environment_rotation_setting_changes_lighting():
    a = environment_sh("sunset", 0.0)
    b = environment_sh("sunset", 90.0)
    assert a.shape == (16, 3) and a.dtype == np.float32
    np.testing.assert_array_equal(a[0], b[0])   # band 0 is rotation invariant
    assert np.abs(a[1:] - b[1:]).max() > 1e-3


# errors and determinism ------------------------------------------------------------------------------
def test_bad_sdf_file_one_clear_error(tmp_path):
    data = json.loads((ROOT / "trained/sdf_creature/sdf.json").read_text())
    data["root"]["children"][1]["child"]["radius"] = -1
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    with pytest.raises(SdfError) as e:
        load_sdf(bad)
    assert str(bad) in str(e.value) and "root.children[1].child.radius" in str(e.value)
    data["root"]["children"][1]["child"] = {"type": "cone", "radius": 1}
    bad.write_text(json.dumps(data))
    with pytest.raises(SdfError, match=r"root\.children\[1\]\.child\.type: unknown node type 'cone'"):
        load_sdf(bad)


def test_bad_scene_file_names_scene_and_sdf(tmp_path):
    from inshade.scene.description import SceneError, load_scene

    scene = json.loads((ROOT / "trained/sdf_occlusion/scene.json").read_text())
    sdf = json.loads((ROOT / "trained/sdf_occlusion/sdf.json").read_text())
    sdf["bound"]["radius"] = "big"
    (tmp_path / "sdf.json").write_text(json.dumps(sdf))
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    with pytest.raises(SceneError) as e:
        load_scene(tmp_path)
    msg = str(e.value)
    assert str(tmp_path / "scene.json") in msg and "sdf:" in msg and "bound.radius" in msg
    sdf["bound"]["radius"] = 2.0
    (tmp_path / "sdf.json").write_text(json.dumps(sdf))
    scene["environment"]["sky"] = "mars"
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    with pytest.raises(SceneError, match="environment.sky: unknown sky 'mars'"):
        load_scene(tmp_path)


def test_chunk_is_deterministic():
    for name in SCENES:
        path = ROOT / f"trained/sdf_{name}/sdf.json"
        a, b = sdf_chunk(load_sdf(path)), sdf_chunk(load_sdf(path))
        assert a == b and sdf_chunks(load_sdf(path)) == {SDF_CHUNK: a}
        assert "float scene_sdf(vec3 p)" in a and "vec3 scene_albedo(vec3 p)" in a
