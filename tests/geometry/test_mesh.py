"""Triangle meshes (geometry/mesh.py): loading OBJ/PLY/GLB, one clear MeshError per bad input, the
procedural rabbit, and the G-buffer pass (runtime/geometry.py + passes/mesh_gbuffer.frag) checked
against the mesh itself: covered pixels lie on the surface (exact signed distance), they are the
first hit of the pixel-centre ray (embree), normals are unit and equal the interpolated vertex
normals there, the background has w = 0.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from inshade.geometry.mesh import MeshError, bounding_sphere, bunny, edge_defects, load_mesh


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
    from inshade.models.mlp_sdf_fit import signed_distance
    from inshade.models.sdf import camera_rays
    from inshade.scene.camera import OrbitCamera
    from inshade.runtime.geometry import MeshGBuffer

    size = 48
    model = _model_matrix()
    world = small_bunny.copy()
    world.apply_transform(model.T)      # trimesh takes column-vector matrices
    c, r = bounding_sphere(world)
    cam = OrbitCamera(target=tuple(c), distance=2.6 * r, yaw=35.0, pitch=15.0)
    gb = MeshGBuffer(gl, small_bunny)
    try:
        pos_tex, nrm_tex, *_ = gb.draw(cam.view_matrix(), cam.projection(size, size), model, size, size)
        assert pos_tex.size == (size, size) and nrm_tex.dtype == "f4"
        pos, nrm, *_ = gb.read()
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
    from inshade.scene.camera import OrbitCamera
    from inshade.runtime.geometry import MeshGBuffer

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


# --- uv-mapped meshes: loading keeps uv, tangents, the torus, G-buffer uv/tangent ---------------

def _torus_angles(p, major=1.0):
    """Ring angle a and tube angle b of points on the torus (inshade.geometry.mesh.torus parametrisation)."""
    a = np.arctan2(-p[:, 2], p[:, 0]) % (2 * np.pi)
    ring = np.hypot(p[:, 0], p[:, 2]) - major
    b = np.arctan2(p[:, 1], ring) % (2 * np.pi)
    return a, b


def test_torus_obj_roundtrip_keeps_uv_seams_and_tangents(tmp_path):
    from inshade.geometry.mesh import mesh_uv, obj_text, shading_normals, torus, vertex_tangents, write_torus

    path = write_torus(tmp_path / "t.obj", segments=(24, 12))
    assert path.read_text() == obj_text(torus(segments=(24, 12))), "not deterministic"
    m = load_mesh(path)
    uv = mesh_uv(m)
    assert uv is not None and uv.shape == (25 * 13, 2), "seam vertices must stay split by their uv"
    a, b = _torus_angles(m.vertices)
    # uv follow the parametrisation (4 and 2 tiles); the seam's duplicates sit at 0 and the full tile count
    ua = (uv[:, 0] / 4.0 * 2 * np.pi) % (2 * np.pi)
    assert np.abs(np.angle(np.exp(1j * (ua - a)))).max() < 1e-6
    n = shading_normals(m)
    radial = m.vertices.copy()
    radial[:, 1] = 0
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    outward = m.vertices - radial
    outward /= np.linalg.norm(outward, axis=1, keepdims=True)
    # smooth across the seam: per-vertex normals on it match the analytic ones as well as elsewhere
    assert np.einsum("ij,ij->i", n, outward).min() > 0.99
    t = vertex_tangents(m, n)
    along_u = np.stack([-np.sin(a), np.zeros_like(a), -np.cos(a)], 1)
    assert np.einsum("ij,ij->i", t[:, :3], along_u).min() > 0.99
    assert np.abs(np.einsum("ij,ij->i", t[:, :3], n)).max() < 1e-9
    assert (t[:, 3] == 1.0).all()   # +v runs along cross(n, t) everywhere on this torus
    # mirrored uv (v -> -v) flips the handedness
    mirrored = trimesh.Trimesh(m.vertices, m.faces, process=False,
                               visual=trimesh.visual.TextureVisuals(uv=uv * [1.0, -1.0]))
    assert (vertex_tangents(mirrored)[:, 3] == -1.0).all()


def test_uv_errors(tmp_path):
    from inshade.geometry.mesh import vertex_tangents

    with pytest.raises(MeshError, match="no texture coordinates"):
        vertex_tangents(trimesh.creation.icosphere(subdivisions=1))
    bad = tmp_path / "nan_uv.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt nan 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    with pytest.raises(MeshError, match="texture coordinates"):
        load_mesh(bad)


def test_gbuffer_uv_and_tangent_on_torus(gl, tmp_path):
    from inshade.geometry.mesh import write_torus
    from inshade.scene.camera import OrbitCamera
    from inshade.runtime.geometry import MeshGBuffer

    size = 48
    m = load_mesh(write_torus(tmp_path / "t.obj", segments=(64, 32)))
    cam = OrbitCamera(target=(0.0, 0.0, 0.0), distance=3.6, yaw=20.0, pitch=-35.0)
    gb = MeshGBuffer(gl, m)
    try:
        gb.draw_camera(cam, size, size)
        pos, nrm, uv, tan = (x.reshape(-1, 4).astype(np.float64) for x in gb.read()[:4])
    finally:
        gb.release()
    covered = pos[:, 3] == 1.0
    assert 0.1 < covered.mean() < 0.9
    assert (uv[~covered] == 0).all() and (tan[~covered] == 0).all()
    a, b = _torus_angles(pos[covered, :3])
    # interpolated uv agrees with the point's own parameters up to the faceting of the 64x32 grid
    du = np.angle(np.exp(1j * (uv[covered, 0] / 4.0 * 2 * np.pi - a)))
    dv = np.angle(np.exp(1j * (uv[covered, 1] / 2.0 * 2 * np.pi - b)))
    assert np.abs(du).max() < 2 * np.pi / 64 and np.abs(dv).max() < 2 * np.pi / 32
    t = tan[covered, :3] / np.linalg.norm(tan[covered, :3], axis=1, keepdims=True)
    along_u = np.stack([-np.sin(a), np.zeros_like(a), -np.cos(a)], 1)
    assert np.einsum("ij,ij->i", t, along_u).min() > 0.99
    assert np.abs(tan[covered, 3] - 1.0).max() < 1e-5   # a constant, up to interpolation rounding
