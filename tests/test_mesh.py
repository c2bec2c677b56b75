"""Triangle meshes (inshade/mesh.py): loading OBJ/PLY/GLB, one clear MeshError per bad input, the
procedural rabbit, and the G-buffer pass (viewer/geometry.py + passes/mesh_gbuffer.frag) checked
against the mesh itself: covered pixels lie on the surface (exact signed distance), they are the
first hit of the pixel-centre ray (embree), normals are unit and equal the interpolated vertex
normals there, the background has w = 0.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from inshade.mesh import MeshError, bounding_sphere, bunny, edge_defects, load_mesh


@pytest.fixture(scope="module")
def small_bunny():
    return bunny(voxel=0.06, smooth_iterations=2)   # ~4k faces: same generator, fewer cells


# loading -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("ext", ["obj", "ply", "glb"])
def test_load_formats_roundtrip(tmp_path, ext):
    src = trimesh.creation.icosphere(2)
    path = tmp_path / f"sphere.{ext}"
    src.export(path)
    m = load_mesh(path, require_watertight=True)
    assert len(m.faces) == len(src.faces) and m.is_watertight
    assert np.allclose(np.sort(m.vertices, 0), np.sort(src.vertices, 0), atol=1e-6)


def test_glb_scene_is_flattened(tmp_path):
    scene = trimesh.Scene([trimesh.creation.box(), trimesh.creation.icosphere(1)])
    path = tmp_path / "two.glb"
    path.write_bytes(scene.export(file_type="glb"))
    m = load_mesh(path)
    assert len(m.faces) == 12 + 80


def test_bad_meshes_one_clear_error(tmp_path):
    def raises(path, pattern, **kw):
        with pytest.raises(MeshError) as e:
            load_mesh(path, **kw)
        assert str(e.value).startswith(str(path)), e.value
        assert pattern in str(e.value), e.value

    raises(tmp_path / "missing.obj", "no such file")
    (tmp_path / "garbage.ply").write_bytes(b"\x00\x01garbage" * 10)
    raises(tmp_path / "garbage.ply", "cannot read as a mesh")
    (tmp_path / "garbage.obj").write_text("hello\nnot a mesh\n")
    raises(tmp_path / "garbage.obj", "empty mesh")
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    raises(tmp_path / "nan.obj", "NaN or infinite")
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    raises(tmp_path / "flat.obj", "degenerate: all 1 faces have zero area")
    (tmp_path / "range.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n")
    with pytest.raises(MeshError):
        load_mesh(tmp_path / "range.obj")   # trimesh rejects or we do; either way one MeshError
    (tmp_path / "x.unknownext").write_text("abc")
    raises(tmp_path / "x.unknownext", "cannot read as a mesh")
    # an open sphere: 3 faces removed -> their boundary edges are counted
    s = trimesh.creation.icosphere(1)
    s.update_faces(np.arange(3, len(s.faces)))
    open_edges, nonmanifold = edge_defects(s)
    s.export(tmp_path / "open.ply")
    raises(tmp_path / "open.ply", f"not watertight: {open_edges} open (boundary) edges", require_watertight=True)
    assert open_edges > 0 and nonmanifold == 0
    assert len(load_mesh(tmp_path / "open.ply").faces) == len(s.faces)   # fine when not required


# the procedural asset ------------------------------------------------------------------------------
def test_bunny_watertight_deterministic_and_bounded(small_bunny):
    again = bunny(voxel=0.06, smooth_iterations=2)
    np.testing.assert_array_equal(small_bunny.vertices, again.vertices)
    np.testing.assert_array_equal(small_bunny.faces, again.faces)
    assert small_bunny.is_watertight and small_bunny.is_winding_consistent and small_bunny.volume > 0
    c, r = bounding_sphere(small_bunny)
    assert np.linalg.norm(small_bunny.vertices - c, axis=1).max() <= r + 1e-12


def test_bunny_default_size():
    m = bunny()
    assert 10_000 <= len(m.faces) <= 30_000 and m.is_watertight


# G-buffer ------------------------------------------------------------------------------------------
def _model_matrix():
    """Row-vector (pyrr) model matrix: scale 0.8, rotate 30 deg about y, translate."""
    a = math.radians(30.0)
    rot = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    m = np.eye(4)
    m[:3, :3] = 0.8 * rot.T          # v @ M: the column-vector rotation transposed
    m[3, :3] = (0.1, -0.05, 0.2)
    return m


def test_gbuffer_on_surface_first_hit_and_normals(gl, small_bunny):
    from inshade.models.neural_sdf import signed_distance
    from inshade.models.sdf import camera_rays
    from inshade.viewer.camera import OrbitCamera
    from inshade.viewer.geometry import MeshGBuffer

    size = 48
    model = _model_matrix()
    world = small_bunny.copy()
    world.apply_transform(model.T)      # trimesh takes column-vector matrices
    c, r = bounding_sphere(world)
    cam = OrbitCamera(target=tuple(c), distance=2.6 * r, yaw=35.0, pitch=15.0)
    gb = MeshGBuffer(gl, small_bunny)
    try:
        pos_tex, nrm_tex = gb.draw(cam.view_matrix(), cam.projection(size, size), model, size, size)
        assert pos_tex.size == (size, size) and nrm_tex.dtype == "f4"
        pos, nrm = gb.read()
    finally:
        gb.release()
    pos, nrm = pos[::-1].reshape(-1, 4), nrm[::-1].reshape(-1, 4)     # image orientation, as camera_rays
    covered = pos[:, 3] == 1.0
    assert 0.1 < covered.mean() < 0.8
    assert (pos[~covered] == 0).all() and (nrm[~covered] == 0).all(), "background must be all zero (w = 0)"
    assert (nrm[covered, 3] == 1.0).all()
    p, n = pos[covered, :3].astype(np.float64), nrm[covered, :3].astype(np.float64)
    # on the surface
    d = signed_distance(world, p)
    assert np.abs(d).max() < 1e-4 * r, f"max |distance to surface| {np.abs(d).max():.3g}"
    # unit normals equal to the normalised barycentric mix of vertex normals at that point
    assert np.abs(np.linalg.norm(n, axis=1) - 1.0).max() < 1e-5
    closest, _, tri = _closest(world, p)
    bary = trimesh.triangles.points_to_barycentric(world.triangles[tri], closest)
    vn = np.einsum("nk,nkj->nj", bary, world.vertex_normals[world.faces[tri]])
    vn /= np.linalg.norm(vn, axis=1, keepdims=True)
    cos = np.einsum("ij,ij->i", n, vn)
    assert np.percentile(cos, 99) > 1 - 1e-4 and cos.min() > 0.9
    assert (np.einsum("ij,ij->i", n, world.face_normals[tri]) > 0).mean() > 0.99
    # depth test: the stored point is the first hit of the pixel-centre ray (silhouettes aside)
    ro, rd = camera_rays(cam.uniforms(size, size), size, size)
    ro, rd = ro.numpy().astype(np.float64), rd.numpy().astype(np.float64)
    loc, ray_idx, _ = world.ray.intersects_location(ro, rd, multiple_hits=False)
    hit = np.zeros(size * size, bool)
    hit[ray_idx] = True
    first = np.zeros((size * size, 3))
    first[ray_idx] = loc
    both = hit & covered
    assert (hit != covered).mean() < 0.03
    err = np.linalg.norm(pos[both, :3] - first[both], axis=1)
    assert np.percentile(err, 98) < 1e-3 * r, f"98th percentile |gbuffer - first hit| {np.percentile(err, 98):.3g}"



def _closest(mesh, points):
    """Closest points and faces, exact: point-cloud-utils if present, else trimesh (rtree)."""
    try:
        import point_cloud_utils as pcu
    except ImportError:
        return trimesh.proximity.closest_point(mesh, points)
    d, fi, bc = pcu.closest_points_on_mesh(np.ascontiguousarray(points), np.ascontiguousarray(mesh.vertices),
                                           np.ascontiguousarray(mesh.faces))
    pts = pcu.interpolate_barycentric_coords(np.ascontiguousarray(mesh.faces), fi, bc,
                                             np.ascontiguousarray(mesh.vertices))
    return pts, d, fi


def test_gbuffer_resize_and_reuse(gl, small_bunny):
    from inshade.viewer.camera import OrbitCamera
    from inshade.viewer.geometry import MeshGBuffer

    cam = OrbitCamera(distance=3.0)
    gb = MeshGBuffer(gl, small_bunny)
    try:
        a = gb.draw_camera(cam, 16, 16)
        b = gb.draw_camera(cam, 16, 16)
        assert a[0] is b[0]                          # same target reused
        c = gb.draw_camera(cam, 24, 20)
        assert c[0].size == (24, 20) and gb.size == (24, 20)
        with pytest.raises(ValueError, match="4x4"):
            gb.draw(np.eye(3), np.eye(4), None, 8, 8)
    finally:
        gb.release()
