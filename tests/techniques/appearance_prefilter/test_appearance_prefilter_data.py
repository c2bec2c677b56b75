"""Appearance prefiltering's data side: the procedural scenes, the sparse multi-scale
voxelisation, the per-voxel data bake (embree, through the bake executor) and the ray-traced
reference (techniques/appearance_prefilter/{scene,frame,voxels,data,reference,brdf_np}.py).

Independent checks: the voxel set against a brute-force exact overlap (vertex-in-box, triangle
edge vs box, box edge vs triangle), spheres against points sampled on the triangles, coverage
against the projected triangle's analytic inside/outside texels, phase against the BRDF at the
recorded light directions, the reference against closed-form pixel values and an explicit
pinhole camera.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from inshade.models.bake import Executor
from inshade.techniques.appearance_prefilter import frame
from inshade.techniques.appearance_prefilter.brdf_np import brdf
from inshade.techniques.appearance_prefilter.data import DataError, bake_voxel_data, phase_slice
from inshade.techniques.appearance_prefilter.reference import ReferenceError, camera_rays, render_reference
from inshade.techniques.appearance_prefilter import scene as scene_module
from inshade.techniques.appearance_prefilter.scene import (SceneError, build_scene, scene_from_mesh)
from inshade.techniques.appearance_prefilter.voxels import VoxelError, clip_to_boxes, count_voxels, voxelise

FAST = settings(max_examples=12, deadline=None, derandomize=True)


# --- scenes ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["grove", "slabs", "forest"])
def test_quick_scenes_are_deterministic_and_in_the_unit_box(name):
    a, b = build_scene(name, "quick"), build_scene(name, "quick")
    assert np.array_equal(a.mesh.vertices, b.mesh.vertices) and np.array_equal(a.base_colour, b.base_colour)
    assert 0 < a.faces < 3000
    assert a.mesh.vertices.min() >= 0.0 and a.mesh.vertices.max() <= 1.0
    n = a.faces
    assert a.base_colour.shape == (n, 3) and a.roughness.shape == a.metallic.shape == a.two_sided.shape == (n,)
    assert a.parts[0][1] == 0 and a.parts[-1][2] == n
    for (_, _, stop), (_, start, _) in zip(a.parts, a.parts[1:]):
        assert stop == start


def test_grove_ship_has_every_ingredient():
    s = build_scene("grove", "ship")
    assert 20_000 <= s.faces <= 60_000
    names = [p[0] for p in s.parts]
    assert any("leaves" in p for p in names) and any("glossy" in p for p in names) and any("slab" in p for p in names)
    leaves = np.concatenate([np.arange(a, b) for n, a, b in s.parts if "leaves" in n])
    assert s.two_sided[leaves].all() and s.two_sided.sum() == len(leaves)
    glossy = np.concatenate([np.arange(a, b) for n, a, b in s.parts if "glossy" in n])
    assert s.roughness[glossy].min() >= 0.2 and s.roughness[glossy].max() <= 0.5
    assert 0 < s.metallic[glossy].mean() < 1


def test_forest_ship_is_in_the_papers_size_class():
    """Over a million triangles: closed displaced-bark trunks and branches, two-sided leaf cards."""
    s = build_scene("forest", "ship")
    assert s.faces >= 1_000_000
    names = [p[0] for p in s.parts]
    leaves = np.concatenate([np.arange(a, b) for n, a, b in s.parts if n.endswith("leaves")])
    assert s.two_sided[leaves].all() and s.two_sided.sum() == len(leaves)
    trunk = next((a, b) for n, a, b in s.parts if n.endswith("trunk"))
    piece = trimesh.Trimesh(s.mesh.vertices, s.mesh.faces[trunk[0]:trunk[1]], process=False)
    piece.merge_vertices()
    assert piece.is_watertight and piece.volume > 0
    # displaced bark: the radius varies around a ring
    bark = scene_module._bark(np.random.default_rng(0), 0.05, 1.0, 32, 8)
    ring = np.linalg.norm(bark.vertices[:32, [0, 2]], axis=1)
    assert bark.is_watertight and ring.std() > 0.02 * ring.mean()
    assert len({n.split("_")[0] for n in names}) >= 10                   # trees


def test_bad_scene_input_gets_one_clear_error():
    box = trimesh.creation.box()
    with pytest.raises(SceneError, match="mesh: empty geometry"):
        scene_from_mesh(trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), int)), 0.5, 0.5, 0.0, False)
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-1])
    with pytest.raises(SceneError, match="parts.mesh: a solid .* watertight"):
        scene_from_mesh(open_box, 0.5, 0.5, 0.0, False)
    scene_from_mesh(open_box, 0.5, 0.5, 0.0, True)     # two-sided cards need not be closed
    bad = box.copy()
    bad.vertices[0, 1] = np.nan
    with pytest.raises(SceneError, match="vertices contain NaN or inf"):
        scene_from_mesh(bad, 0.5, 0.5, 0.0, False)
    with pytest.raises(SceneError, match="base_colour: expected one value or one per face"):
        scene_from_mesh(box, np.ones((3, 3)), 0.5, 0.0, False)
    with pytest.raises(SceneError, match="roughness: values must be finite and in"):
        scene_from_mesh(box, 0.5, 1.5, 0.0, False)
    with pytest.raises(SceneError, match="scene: unknown 'jungle'"):
        build_scene("jungle")
    with pytest.raises(SceneError, match="detail: must be one of"):
        build_scene("grove", "huge")


# --- the frame and the bins -----------------------------------------------------------------------

def test_view_frame_matches_the_contract():
    t, b, w = frame.view_frame(np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]]))
    assert np.allclose(t[0], [1, 0, 0]) and np.allclose(b[0], [0, 1, 0])
    # |w.y| > 0.999: up = +x, t = cross(x, w)
    assert np.allclose(t[1], [0, 0, 1]) and np.allclose(b[1], [1, 0, 0])
    assert np.allclose(t[2], [0, 0, -1]) and np.allclose(b[2], [1, 0, 0])


@FAST
@given(st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 0.1))
def test_view_frame_is_a_right_handed_orthonormal_basis(v):
    w = np.asarray(v) / np.linalg.norm(v)
    t, b, w2 = frame.view_frame(w)
    m = np.stack([t, b, w2])
    assert np.allclose(m @ m.T, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(m), 1.0)
    d = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    assert np.allclose(frame.to_world(frame.to_local(d, w), w), d)


@pytest.mark.parametrize("bt, bp", [(4, 8), (2, 4), (3, 5)])
def test_jittered_bin_directions_stay_in_their_bin(bt, bp):
    u = np.random.default_rng(0).random((100, bt * bp, 2))
    d = frame.jittered_bins(bt, bp, u)
    assert np.allclose(np.linalg.norm(d, axis=-1), 1.0)
    assert np.array_equal(frame.bin_index(d, bt, bp), np.broadcast_to(np.arange(bt * bp), (100, bt * bp)))
    assert np.array_equal(frame.bin_index(frame.bin_centres(bt, bp), bt, bp), np.arange(bt * bp))


def test_stratified_views_put_one_sample_in_each_equal_area_stratum():
    d = frame.stratified_sphere(16, np.random.default_rng(1).random((16, 2)))
    rows = np.floor((1.0 - d[:, 1]) * 0.5 * 4).astype(int)       # 4 bands of world y
    assert np.array_equal(np.bincount(rows, minlength=4), [4, 4, 4, 4])
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0)


# --- the BRDF -------------------------------------------------------------------------------------

def test_brdf_known_value_at_normal_incidence():
    n = np.array([0.0, 0.0, 1.0])
    for rough, metal in ((0.5, 0.0), (0.8, 0.0), (0.4, 1.0)):
        base = np.array([0.2, 0.5, 0.9])
        alpha2 = (rough * rough) ** 2
        f0 = 0.04 * (1 - metal) + base * metal
        # l = v = n: F_D = 1, D = 1 / (pi alpha^2), G = 1, F = F0
        expect = (1 - metal) * base / math.pi + f0 / (4 * math.pi * alpha2)
        assert np.allclose(brdf(n, n, n, base, rough, metal), expect, rtol=1e-12)
    assert np.all(brdf(n, n, np.array([0.0, 0.6, -0.8]), np.ones(3), 0.5, 0.0) == 0.0)


@FAST
@given(st.floats(0, 1), st.floats(0, 1), st.integers(0, 2**31 - 1))
def test_brdf_is_reciprocal(rough, metal, seed):
    rng = np.random.default_rng(seed)
    v, l = rng.normal(size=(2, 64, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    l /= np.linalg.norm(l, axis=1, keepdims=True)
    n = np.array([0.0, 0.0, 1.0])
    base = rng.random((64, 3))
    assert np.allclose(brdf(n, v, l, base, rough, metal), brdf(n, l, v, base, rough, metal), rtol=1e-10, atol=1e-12)


def hemisphere(k: int) -> np.ndarray:
    """Midpoint quadrature directions over the +z hemisphere: k cos-theta rows x 2k phi columns,
    each of solid angle (1 / k) (2 pi / 2k)."""
    cos_t = (np.arange(k) + 0.5) / k
    phi = (np.arange(2 * k) + 0.5) / (2 * k) * 2 * math.pi
    c, p = np.meshgrid(cos_t, phi, indexing="ij")
    s = np.sqrt(1 - c * c)
    return np.stack([s * np.cos(p), s * np.sin(p), c], -1).reshape(-1, 3)


def test_white_metal_directional_albedo_is_at_most_one():
    # midpoint quadrature over the hemisphere of f cos: a GGX-Smith metal loses energy, never gains it
    k = 400
    l = hemisphere(k)
    n = np.array([0.0, 0.0, 1.0])
    # (roughness, lower bound): alpha = 1 is analytic, 2 (1 - ln 2) / 2 ~ 0.307 (half the
    # reflections leave below the horizon); smooth metal keeps almost everything
    for rough, low in ((0.3, 0.9), (0.6, 0.6), (1.0, 0.30)):
        f = brdf(n, n, l, np.ones(1), rough, 1.0)[:, 0]
        albedo = (f * l[:, 2]).sum() * (1.0 / k) * (2 * math.pi / (2 * k))
        assert low < albedo <= 1.0, (rough, albedo)
    assert abs(albedo - (1 - math.log(2))) < 1e-3


# --- voxelisation ---------------------------------------------------------------------------------

def _point_in_box(p, lo, hi):
    return np.all((p >= lo) & (p <= hi))


def _segment_box(a, b, lo, hi):
    d = b - a
    t0, t1 = 0.0, 1.0
    for i in range(3):
        if d[i] == 0.0:
            if a[i] < lo[i] or a[i] > hi[i]:
                return False
            continue
        u, v = (lo[i] - a[i]) / d[i], (hi[i] - a[i]) / d[i]
        t0, t1 = max(t0, min(u, v)), min(t1, max(u, v))
    return t0 <= t1


def _segment_triangle(a, b, tri):
    e1, e2 = tri[1] - tri[0], tri[2] - tri[0]
    n = np.cross(e1, e2)
    da, db = np.dot(a - tri[0], n), np.dot(b - tri[0], n)
    if da * db > 0 or da == db:
        return False
    p = a + (b - a) * (da / (da - db))
    w = p - tri[0]
    d00, d01, d11 = e1 @ e1, e1 @ e2, e2 @ e2
    d20, d21 = w @ e1, w @ e2
    den = d00 * d11 - d01 * d01
    v = (d11 * d20 - d01 * d21) / den
    u = (d00 * d21 - d01 * d20) / den
    return v >= 0 and u >= 0 and u + v <= 1


def _brute_overlap(tri, lo, hi):
    """Exact closed overlap, a different algorithm from the SAT: a vertex in the box, a triangle
    edge through the box, or a box edge through the triangle."""
    if any(_point_in_box(v, lo, hi) for v in tri):
        return True
    if any(_segment_box(tri[i], tri[(i + 1) % 3], lo, hi) for i in range(3)):
        return True
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    for i in range(8):
        for j in range(i + 1, 8):
            if np.sum(corners[i] != corners[j]) == 1 and _segment_triangle(corners[i], corners[j], tri):
                return True
    return False


triangles = st.integers(0, 2**31 - 1).map(lambda s: np.random.default_rng(s))


def _random_mesh(rng, n=3):
    centres = 0.15 + 0.7 * rng.random((n, 1, 3))
    tri = centres + rng.normal(scale=0.12, size=(n, 3, 3))
    return trimesh.Trimesh(np.clip(tri, 0.0, 1.0).reshape(-1, 3), np.arange(3 * n).reshape(n, 3), process=False)


def _random_voxels(rng, min_scale, max_scale):
    """A random triangle set, its voxels and spheres over the scales, and its triangles' corners [n, 3, 3]."""
    mesh = _random_mesh(rng)
    cells, spheres = voxelise(mesh, min_scale, max_scale)
    return mesh, cells, spheres, mesh.vertices[mesh.faces]


@settings(max_examples=6, deadline=None, derandomize=True)
@given(triangles)
def test_voxels_match_a_brute_force_overlap(rng):
    mesh, cells, spheres, tri = _random_voxels(rng, 0, 3)
    expect = []
    for s in range(4):
        n = 1 << s
        for k in range(n):
            for j in range(n):
                for i in range(n):
                    lo = np.array([i, j, k]) / n
                    # (a cell apart from a triangle's AABB cannot overlap it: skip the slow test there)
                    near = [t for t in tri if np.all(t.min(0) <= lo + 1.0 / n) and np.all(t.max(0) >= lo)]
                    if any(_brute_overlap(t, lo, lo + 1.0 / n) for t in near):
                        expect.append((s, i, j, k))
    assert cells.dtype == np.uint32 and spheres.dtype == np.float32
    assert [tuple(c) for c in cells.tolist()] == expect      # same set, contract order (scale, k, j, i)
    assert count_voxels(mesh, 0, 3) == {s: sum(e[0] == s for e in expect) for s in range(4)}


@settings(max_examples=6, deadline=None, derandomize=True)
@given(triangles)
def test_spheres_contain_the_clipped_geometry(rng):
    _, cells, spheres, tri = _random_voxels(rng, 1, 4)
    # points sampled on every triangle; those inside a cell must lie in its sphere
    u = rng.random((4000, 2))
    u = np.where(u.sum(1, keepdims=True) > 1, 1 - u, u)
    pts = (tri[:, 0, None] + u[None, :, :1] * (tri[:, 1] - tri[:, 0])[:, None] +
           u[None, :, 1:] * (tri[:, 2] - tri[:, 0])[:, None]).reshape(-1, 3)
    size = 1.0 / (1 << cells[:, 0].astype(int))
    lo = cells[:, 1:] * size[:, None]
    covered = np.zeros(len(cells), bool)
    for c in range(len(cells)):
        inside = np.all((pts >= lo[c]) & (pts <= lo[c] + size[c]), 1)
        if inside.any():
            covered[c] = True
            dist = np.linalg.norm(pts[inside] - spheres[c, :3], axis=1)
            assert dist.max() <= spheres[c, 3] * (1 + 1e-5) + 1e-6
        # the sphere's centre is the clipped AABB's centre: inside the cell
        assert np.all(spheres[c, :3] >= lo[c] - 1e-6) and np.all(spheres[c, :3] <= lo[c] + size[c] + 1e-6)
    assert covered.mean() > 0.5
    assert spheres[:, 3].min() >= 1e-6


def test_clipping_a_triangle_to_a_box():
    tri = np.array([[[-1.0, 0.5, 0.5], [2.0, 0.5, 0.5], [0.5, 2.0, 0.5]]])
    pts, valid = clip_to_boxes(tri, np.zeros((1, 3)), np.ones((1, 3)))
    p = pts[0][valid[0]]
    assert np.all(p >= -1e-12) and np.all(p <= 1 + 1e-12)
    assert np.isclose(p[:, 0].min(), 0.0) and np.isclose(p[:, 0].max(), 1.0) and np.isclose(p[:, 1].max(), 1.0)


def test_voxel_input_errors_and_the_memory_budget():
    mesh = build_scene("slabs", "quick")
    with pytest.raises(VoxelError, match="scales: need 0 <= s_min <= s_max <= 9"):
        voxelise(mesh, 3, 2)
    with pytest.raises(VoxelError, match="scales: need"):
        voxelise(mesh, 0, 10)
    with pytest.raises(VoxelError, match="s_min: must be an int"):
        voxelise(mesh, 1.5, 2)
    counts = count_voxels(mesh, 1, 2)
    need = sum(counts.values()) * 100
    with pytest.raises(VoxelError, match=f"memory_budget_bytes: scales 1..2 need {need} bytes"):
        voxelise(mesh, 1, 2, memory_budget_bytes=need - 1, bytes_per_voxel=100)
    cells, _ = voxelise(mesh, 1, 2, memory_budget_bytes=need, bytes_per_voxel=100)
    assert len(cells) == sum(counts.values())


# --- per-voxel data -------------------------------------------------------------------------------

def _quad_scene(corners, two_sided=True, base=(0.6, 0.4, 0.2), roughness=0.5, metallic=0.0):
    mesh = trimesh.Trimesh(np.asarray(corners, float), [[0, 1, 2], [0, 2, 3]], process=False)
    return scene_from_mesh(mesh, base, roughness, metallic, two_sided, normalise=False)


def _voxel(scene, scale, ijk):
    cells, spheres = voxelise(scene, scale, scale)
    row = [tuple(c[1:]) for c in cells.tolist()].index(tuple(ijk))
    return cells[row:row + 1], spheres[row:row + 1]


# a quad filling cell (1, 1, 1) of scale 2 in its mid plane z = 0.375
QUAD = [[0.25, 0.25, 0.375], [0.5, 0.25, 0.375], [0.5, 0.5, 0.375], [0.25, 0.5, 0.375]]


def test_a_quad_filling_a_voxel_covers_it_from_the_front_and_not_edge_on():
    scene = _quad_scene(QUAD)
    cells, spheres = _voxel(scene, 2, (1, 1, 1))
    assert np.allclose(spheres[0], [0.375, 0.375, 0.375, 0.125 * math.sqrt(2)], atol=1e-6)
    views = np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0], [0, 1.0, 0]])
    d = bake_voxel_data(scene, cells, spheres, views=4, mask=8, bins=(2, 4), rays_per_texel=4, seed=0,
                        progress=False, fixed_views=views)
    cov = d["coverage"][0]
    # the quad spans |x|, |y| <= 1/sqrt(2) of the sphere's square: texels 2..5 lie inside it, the rim outside
    for v in (0, 1):
        assert np.all(cov[v, 2:6, 2:6] == 1.0) and cov[v, 0].max() == 0.0 and cov[v, :, 7].max() == 0.0
        assert np.allclose(d["albedo"][0, v], [0.6, 0.4, 0.2])
    assert cov[2:].max() < 0.05                      # edge-on: the rays run parallel to the quad
    assert np.all(d["albedo"][0, 2:][cov[2:].reshape(2, -1).max(1) == 0] == 0.0)


def _cross2(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


@settings(max_examples=5, deadline=None, derandomize=True)
@given(st.integers(0, 2**31 - 1))
def test_coverage_matches_the_projected_triangle(seed):
    rng = np.random.default_rng(seed)
    tri = 0.5 + 0.45 * rng.random((3, 3))           # inside cell (1, 1, 1) of scale 1
    mesh = trimesh.Trimesh(tri, [[0, 1, 2]], process=False)
    scene = scene_from_mesh(mesh, 0.5, 0.5, 0.0, True, normalise=False)
    cells, spheres = _voxel(scene, 1, (1, 1, 1))
    w = rng.normal(size=(2, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    M = 8
    d = bake_voxel_data(scene, cells, spheres, views=2, mask=M, bins=(1, 2), rays_per_texel=4, seed=seed,
                        progress=False, fixed_views=w)
    c, r = spheres[0, :3].astype(float), float(spheres[0, 3])
    for v in range(2):
        t, b, _ = frame.view_frame(w[v])
        q = np.stack([(tri - c) @ t, (tri - c) @ b], 1) / r          # the triangle in mask coordinates
        edges = [(q[i], q[(i + 1) % 3]) for i in range(3)]
        orient = np.sign(_cross2(q[1] - q[0], q[2] - q[0]))
        grid = -1 + 2 * np.arange(M + 1) / M
        for iv in range(M):
            for iu in range(M):
                corners = np.array([[grid[iu + a], grid[iv + e]] for a in (0, 1) for e in (0, 1)])
                side = np.stack([orient * _cross2(b2 - a2, corners - a2) for a2, b2 in edges])   # [3, 4]
                if np.all(side > 1e-9):
                    assert d["coverage"][0, v, iv, iu] == 1.0, (v, iv, iu)
                elif np.any(np.all(side < -1e-9, axis=1)):
                    assert d["coverage"][0, v, iv, iu] == 0.0, (v, iv, iu)


def test_phase_of_a_single_quad_is_the_brdf_times_cosine():
    # one planar face: every hit has the same normal and nothing shadows it, so
    # phase[b] = f_white(w, l_b, n) max(0, n.l_b) exactly (mean over identical values)
    scene = _quad_scene(QUAD, two_sided=True, roughness=0.7)
    cells, spheres = _voxel(scene, 2, (1, 1, 1))
    w = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, -0.6, -0.8]])
    d = bake_voxel_data(scene, cells, spheres, views=3, mask=4, bins=(4, 8), rays_per_texel=1, seed=5,
                        progress=False, fixed_views=w)
    for v in range(3):
        n = np.array([0.0, 0.0, 1.0 if w[v, 2] > 0 else -1.0])      # two-sided: the normal faces the viewer
        l = frame.to_world(d["light_local"][0, v].astype(float), w[v])
        expect = brdf(n, w[v], l, np.ones(1), 0.7, 0.0)[:, 0] * np.clip(l @ n, 0, None)
        assert np.allclose(d["phase"][0, v], expect, rtol=1e-5, atol=1e-7)
        assert (expect > 0).sum() >= 8 and (expect == 0).sum() >= 8      # lit and unlit bins
    # the straight-on view of a white diffuse-ish quad: bin 0 (light near w) is close to 1/pi
    assert abs(d["phase"][0, 0, :8].mean() - 1 / math.pi) < 0.12
    assert np.allclose(phase_slice(d["phase"], (4, 8)), d["phase"] * 4 * math.pi / 32)


def test_a_ray_starting_inside_a_cut_solid_hits_a_back_face_that_reflects_nothing():
    box = trimesh.creation.box(bounds=[[0.3, 0.3, 0.3], [0.8, 0.8, 0.8]])
    scene = scene_from_mesh(box, 0.5, 0.5, 0.0, False, normalise=False)
    cells, spheres = _voxel(scene, 2, (1, 1, 1))             # [0.25, 0.5]^3 holds the box's corner
    w = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])        # rays toward +z: front face z = 0.3; toward -z: from inside
    d = bake_voxel_data(scene, cells, spheres, views=2, mask=4, bins=(2, 4), rays_per_texel=1, seed=0,
                        progress=False, fixed_views=w)
    assert d["coverage"][0, 0].max() == 1.0 and d["phase"][0, 0].max() > 0.0
    assert d["coverage"][0, 1].max() == 1.0 and np.all(d["phase"][0, 1] == 0.0)


def test_phase_sees_intra_voxel_shadows_only():
    # seen from +z: a strip (z = 0.45, x < 0.375) in front of a back quad (z = 0.30) that fills the
    # cell's xy square; both face the viewer with the same diffuse material, so every hit has the
    # same f cos = g(l) and phase(l) = g(l) (1 - 0.5 B(l)), B(l) = the fraction of the back quad's
    # visible half (x > 0.375) whose shadow ray toward l meets the strip. A quad right above the
    # cell (z = 0.6, outside it) must shadow nothing.
    back = [[0.25, 0.25, 0.30], [0.5, 0.25, 0.30], [0.5, 0.5, 0.30], [0.25, 0.5, 0.30]]
    strip = [[0.25, 0.25, 0.45], [0.375, 0.25, 0.45], [0.375, 0.5, 0.45], [0.25, 0.5, 0.45]]
    outside = [[0.2, 0.2, 0.6], [0.55, 0.2, 0.6], [0.55, 0.55, 0.6], [0.2, 0.55, 0.6]]
    v = np.array(back + strip + outside)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    mesh = trimesh.Trimesh(v, np.concatenate([faces, faces + 4, faces + 8]), process=False)
    scene = scene_from_mesh(mesh, 0.5, 1.0, 0.0, True, normalise=False)
    cells, spheres = _voxel(scene, 2, (1, 1, 1))
    w = np.array([[0.0, 0.0, 1.0]])
    d = bake_voxel_data(scene, cells, spheres, views=1, mask=8, bins=(4, 8), rays_per_texel=16, seed=1,
                        progress=False, fixed_views=w)
    lights = frame.to_world(d["light_local"][0, 0].astype(float), w[0])
    n = np.array([0.0, 0.0, 1.0])
    g = brdf(n, w[0], lights, np.ones(1), 1.0, 0.0)[:, 0] * np.clip(lights @ n, 0, None)
    gx, gy = np.meshgrid(0.375 + (np.arange(100) + 0.5) / 100 * 0.125, 0.25 + (np.arange(100) + 0.5) / 100 * 0.25)
    blocked = []
    for l in lights:
        if l[2] <= 0:
            blocked.append(0.0)
            continue
        x2, y2 = gx + 0.15 * l[0] / l[2], gy + 0.15 * l[1] / l[2]
        blocked.append(np.mean((x2 >= 0.25) & (x2 <= 0.375) & (y2 >= 0.25) & (y2 <= 0.5)))
    expect = g * (1 - 0.5 * np.array(blocked))
    assert np.max(blocked) > 0.3                                   # some lights are well shadowed
    assert np.allclose(d["phase"][0, 0], expect, atol=0.03 * g.max())


def test_bake_is_identical_in_process_through_a_pool_and_from_the_cache(tmp_path):
    scene = build_scene("grove", "quick")
    cells, spheres = voxelise(scene, 1, 2)
    args = dict(views=4, mask=4, bins=(2, 4), rays_per_texel=2, seed=7, progress=False)
    a = bake_voxel_data(scene, cells, spheres, chunk=16, **args)
    b = bake_voxel_data(scene, cells, spheres, chunk=5, executor=Executor(workers=2), cache_dir=tmp_path, **args)
    c = bake_voxel_data(scene, cells, spheres, chunk=5, cache_dir=tmp_path, **args)    # all from the cache
    assert len(list(tmp_path.glob("dap-*/voxels-*.safetensors"))) == math.ceil(len(cells) / 5)
    for k in ("views", "coverage", "albedo", "light_local", "phase", "cells", "spheres", "ray_counts"):
        assert np.array_equal(a[k], b[k]) and np.array_equal(a[k], c[k]), k
    assert a["coverage"].shape == (len(cells), 4, 4, 4) and a["light_local"].shape == (len(cells), 4, 8, 3)
    assert a["coverage"].max() == 1.0 and a["phase"].max() > 0.0
    # the views are the contract's: unit, stratified, one set per slot
    assert np.allclose(np.linalg.norm(a["views"], axis=-1), 1.0, atol=1e-6)
    assert not np.array_equal(a["views"][0], a["views"][1])
    d = bake_voxel_data(scene, cells, spheres, chunk=16, **{**args, "seed": 8})
    assert not np.array_equal(a["views"], d["views"])


def test_bake_input_errors():
    scene = build_scene("slabs", "quick")
    cells, spheres = voxelise(scene, 1, 1)
    with pytest.raises(DataError, match="cells: expected uint32"):
        bake_voxel_data(scene, cells.astype(np.int64), spheres, progress=False)
    with pytest.raises(DataError, match="spheres: expected float32"):
        bake_voxel_data(scene, cells, spheres[:-1], progress=False)
    bad = cells.copy()
    bad[0, 1] = 2
    with pytest.raises(DataError, match="cells: an .* index lies outside"):
        bake_voxel_data(scene, bad, spheres, progress=False)
    with pytest.raises(DataError, match="mask: must be an int >= 1"):
        bake_voxel_data(scene, cells, spheres, mask=0, progress=False)
    with pytest.raises(DataError, match="bins: must be"):
        bake_voxel_data(scene, cells, spheres, bins=(4,), progress=False)
    with pytest.raises(DataError, match="fixed_views: expected"):
        bake_voxel_data(scene, cells, spheres, views=2, fixed_views=np.ones((2, 3)), progress=False)


# --- the reference renderer -----------------------------------------------------------------------

def test_reference_rays_match_an_explicit_pinhole_camera():
    from inshade.scene.camera import OrbitCamera

    cam = OrbitCamera(fov_y=50.0, target=(0.4, 0.5, 0.45), distance=2.0, yaw=30.0, pitch=-20.0)
    width, height = 12, 8
    eye, dirs = camera_rays(cam.to_dict(), width, height)
    assert np.allclose(eye, cam.eye(), atol=1e-6)
    fwd = cam.forward()
    right = np.cross(fwd, [0, 1, 0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    tan = math.tan(math.radians(50.0) / 2)
    for row, col in ((0, 0), (3, 7), (7, 11)):
        ndc_x = (col + 0.5) * 2 / width - 1
        ndc_y = (height - 1 - row + 0.5) * 2 / height - 1            # row 0 is the top
        d = fwd + ndc_x * tan * width / height * right + ndc_y * tan * up
        assert np.allclose(dirs[row, col], d / np.linalg.norm(d), atol=1e-5)
    # (origin, target, fov): the centre of an odd image looks straight at the target
    eye, dirs = camera_rays(((0.1, 0.9, 2.0), (0.5, 0.4, 0.5), 40.0), 9, 9)
    aim = np.array([0.4, -0.5, -1.5]) / np.linalg.norm([0.4, -0.5, -1.5])
    assert np.allclose(eye, [0.1, 0.9, 2.0], atol=1e-5) and np.allclose(dirs[4, 4], aim, atol=1e-5)


def test_reference_one_quad_matches_closed_form_values():
    quad = [[0.2, 0.2, 0.5], [0.8, 0.2, 0.5], [0.8, 0.8, 0.5], [0.2, 0.8, 0.5]]
    base, rough = np.array([0.7, 0.5, 0.3]), 0.6
    scene = _quad_scene(quad, two_sided=True, base=base, roughness=rough)
    sh = np.zeros((4, 3))
    sh[0] = [0.5, 1.0, 2.0]
    cam = ((0.5, 0.5, 2.0), (0.5, 0.5, 0.5), 30.0)
    img = render_reference(scene, cam, 9, spp=1, sun_dir=(0, 0, 1), sun_radiance=2.0, env_sh=np.zeros((1, 3)))
    alpha2 = (rough * rough) ** 2
    expect = 2.0 * (base / math.pi + 0.04 / (4 * math.pi * alpha2))   # l = v = n at the centre pixel
    assert np.allclose(img[4, 4], expect, rtol=1e-5)
    img = render_reference(scene, cam, 33, spp=1, sun_dir=(0, 0, 1), sun_radiance=0.0, env_sh=sh)
    assert np.allclose(img[0, 0], sh[0] * 0.28209479177387814, rtol=1e-6)     # a miss shows the sky
    # a constant sky: the centre pixel is sky * the directional albedo (quadrature), within MC noise
    img = render_reference(scene, cam, 5, spp=1, sun_dir=(0, 0, 1), sun_radiance=0.0, env_sh=sh[:1],
                           env_samples=20000, seed=3)
    k = 200
    l = hemisphere(k)
    n = np.array([0.0, 0.0, 1.0])
    albedo = (brdf(n, n, l, base, rough, 0.0) * l[:, 2:]).sum(0) / k * (2 * math.pi / (2 * k))
    assert np.allclose(img[2, 2], sh[0] * 0.28209479177387814 * albedo, rtol=0.03)


def test_reference_shadows_and_input_errors():
    quad = [[0.2, 0.2, 0.5], [0.8, 0.2, 0.5], [0.8, 0.8, 0.5], [0.2, 0.8, 0.5]]
    blocker = [[0.0, 0.0, 0.7], [1.0, 0.0, 0.7], [1.0, 1.0, 0.7], [0.0, 1.0, 0.7]]
    v = np.array(quad + blocker)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    mesh = trimesh.Trimesh(v, np.concatenate([faces, faces + 4]), process=False)
    scene = scene_from_mesh(mesh, 0.5, 0.5, 0.0, True, normalise=False)
    cam = ((0.5, 0.5, 0.6), (0.5, 0.5, 0.0), 60.0)                      # between the quad and the blocker
    lit = render_reference(scene, cam, 5, spp=1, sun_dir=(0, 0, 1), sun_radiance=1.0, shadows=False)
    dark = render_reference(scene, cam, 5, spp=1, sun_dir=(0, 0, 1), sun_radiance=1.0)
    assert lit[2, 2].min() > 0.1 and np.all(dark[2, 2] == 0.0)
    with pytest.raises(ReferenceError, match="spp: must be an int >= 1"):
        render_reference(scene, cam, 5, spp=0)
    with pytest.raises(ReferenceError, match="env_sh: expected"):
        render_reference(scene, cam, 5, spp=1, env_sh=np.zeros((5, 3)))
    with pytest.raises(ReferenceError, match="camera: origin and target must differ"):
        render_reference(scene, ((0, 0, 0), (0, 0, 0), 40.0), 5, spp=1)
    with pytest.raises(ReferenceError, match="camera.type: a 3D camera"):
        render_reference(scene, {"type": "plane2d"}, 5, spp=1)


def test_reference_supersampling_converges_to_the_pixel_mean():
    # an edge through a pixel: 64 spp lands between the 1-spp extremes of the pixel's two sides
    quad = [[0.0, 0.0, 0.5], [0.5, 0.0, 0.5], [0.5, 1.0, 0.5], [0.0, 1.0, 0.5]]
    scene = _quad_scene(quad, two_sided=True, base=(1, 1, 1), roughness=1.0)
    cam = ((0.5, 0.5, 2.0), (0.5, 0.5, 0.5), 20.0)
    one = render_reference(scene, cam, 9, spp=1, sun_dir=(0, 0, 1), sun_radiance=1.0)
    many = render_reference(scene, cam, 9, spp=64, sun_dir=(0, 0, 1), sun_radiance=1.0, seed=2)
    # the quad's edge x = 0.5 runs through the centre column: left of it lit, right of it the (black) sky
    assert one[4, 0, 0] > 0.25 and one[4, 8, 0] == 0.0
    assert 0.3 * one[4, 0, 0] < many[4, 4, 0] < 0.7 * one[4, 0, 0]
    assert np.allclose(many[:, :3], one[:, :3], rtol=1e-3) and np.all(many[:, 5:] == 0.0)


def test_frame_twins_agree_with_the_march():
    # the contract's one frame in numpy (the data) and torch (the march's reference)
    import torch

    from inshade.techniques.appearance_prefilter import march

    rng = np.random.default_rng(4)
    w = rng.normal(size=(200, 3))
    w[:3] = [[0.0, 1.0, 0.0], [0.001, -1.0, 0.0], [0.0, 0.0, 1.0]]
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    t, b, _ = frame.view_frame(w)
    tt, bt = march.view_frame(torch.tensor(w, dtype=torch.float32))
    assert np.allclose(tt.numpy(), t, atol=1e-6) and np.allclose(bt.numpy(), b, atol=1e-6)
    assert np.allclose(march.bin_centres(4, 8).numpy(), frame.bin_centres(4, 8), atol=1e-6)


def test_decimated_lod_reaches_a_coarse_budget_and_can_vanish():
    """A mesh a thousand times over a budget is decimated in several passes to fit it (one pass
    stops at 1 % of the faces); a budget below one face leaves an empty mesh with empty materials."""
    from inshade.techniques.appearance_prefilter.baseline import decimate, lod_bytes

    sphere = trimesh.creation.icosphere(subdivisions=6, radius=0.3)
    sphere.apply_translation([0.5, 0.5, 0.5])
    scene = scene_from_mesh(sphere, [0.5, 0.4, 0.3], 0.5, 0.0, False, normalise=False)
    budget = lod_bytes(40, 60)
    assert budget < lod_bytes(len(sphere.vertices) // 100, len(sphere.faces) // 100)
    lod, used = decimate(scene, budget)
    assert 0 < used <= budget and used == lod_bytes(len(lod.mesh.vertices), len(lod.mesh.faces))
    assert lod.base_colour.shape == (len(lod.mesh.faces), 3)
    np.testing.assert_allclose(lod.base_colour, np.broadcast_to([0.5, 0.4, 0.3], lod.base_colour.shape), atol=1e-6)
    empty, used = decimate(scene, 10)
    assert used == 0 and len(empty.mesh.faces) == 0
    assert empty.base_colour.shape == (0, 3) and empty.roughness.shape == empty.two_sided.shape == (0,)


def test_a_miss_shows_the_background_the_gl_passes_draw():
    """The reference's escaped rays show the windowed series (lib/spherical_harmonics sh_background,
    torch twin sh_background_t), not the raw one the lighting uses."""
    import torch

    from inshade.codegen.sdf import environment_sh
    from inshade.models.sdf import sh_background_t
    from inshade.techniques.appearance_prefilter import reference

    sh = environment_sh("overcast", 30.0, 4).astype(np.float64)
    d = np.random.default_rng(3).normal(size=(256, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    want = sh_background_t(torch.as_tensor(sh, dtype=torch.float32), torch.as_tensor(d, dtype=torch.float32)).numpy()
    np.testing.assert_allclose(reference._background(sh, d), want, atol=1e-5)
    assert np.abs(reference._env(sh, d) - want).max() > 1e-3      # the lighting's series differs
