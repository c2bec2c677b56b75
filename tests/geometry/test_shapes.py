"""Built-in shapes (geometry/shapes.py, geometry/teapot.py): the Newell teapot table's structure, its
tessellation (stitched patches, outward winding, uv atlas, tangents), sphere and plane, scenes that
name a shape, and the sidecar's record of it.

The teapot's expected values are geometric facts of Newell's data, not outputs of the tessellator:
rotational patches are quarter turns of one profile with the 0.56 tangent factor, handle and spout
are mirror-symmetric in Newell's y, and stitched patch edges leave exactly the known openings.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from inshade.geometry import shapes, teapot
from inshade.geometry.mesh import check_tangents, edge_defects, load_mesh, mesh_uv, obj_text, shading_normals, vertex_tangents

REPO = Path(__file__).resolve().parents[2]
PBR_ASSET = REPO / "trained" / "di_pbr_set_bricks"     # a mesh program that needs uv and tangents
ROTATIONAL = [*teapot.GROUPS["rim"], *teapot.GROUPS["body"], *teapot.GROUPS["lid"], *teapot.GROUPS["bottom"]]


# --- Newell's table --------------------------------------------------------------------------------
def test_table_sizes_and_unused_points():
    assert teapot.VERTICES.shape == (306, 3) and teapot.PATCHES.shape == (32, 16)
    assert teapot.PATCHES.min() == 1 and teapot.PATCHES.max() == 306
    unused = sorted(set(range(1, 307)) - set(teapot.PATCHES.reshape(-1).tolist()))
    # the table's four near-duplicates of the lid's top point
    assert unused == [205, 206, 216, 223]
    assert np.abs(teapot.VERTICES[np.array(unused) - 1] - [0.0, 0.0, 3.15]).max() <= 0.002


def test_rotational_patches_are_quarter_turns_of_one_profile():
    p = teapot.control_points("z_up")
    for k in ROTATIONAL:
        for row in p[k]:
            assert np.ptp(row[:, 2]) == 0.0, f"patch {k}: a row is not at one height"
            r = np.hypot(row[0, 0], row[0, 1])
            a0, a3 = row[0, :2] / max(r, 1e-12), row[3, :2] / max(r, 1e-12)
            if r == 0.0:   # a pole: all four points on the axis
                assert np.abs(row[:, :2]).max() == 0.0
                continue
            assert abs(np.hypot(*row[3, :2]) - r) < 1e-12, f"patch {k}: row ends at different radii"
            assert abs(np.dot(a0, a3)) < 1e-12, f"patch {k}: a row is not a quarter turn"
            # the inner points sit on the end points' tangent lines
            assert abs(np.dot(row[1, :2] - row[0, :2], a0)) < 1e-12 and abs(np.dot(row[2, :2] - row[3, :2], a3)) < 1e-12
            # the inner points: the end points plus 0.56 r along the circle's tangents (0.45 / 0.8 for
            # the knob's 0.8 ring, as Newell rounded it)
            k1 = np.dot(row[1, :2] - row[0, :2], a3) / r
            k2 = np.dot(row[2, :2] - row[3, :2], a0) / r
            assert abs(k1 - 0.56) < 0.003 and abs(k2 - 0.56) < 0.003, (k, k1, k2)
    # neighbouring quarters turn the same way (+x -> -y, the bottom +x -> +y)
    first_dirs = [p[k][-1, 0, :2] / np.hypot(*p[k][-1, 0, :2]) for k in teapot.GROUPS["body"][:4]]
    assert np.allclose(first_dirs, [[1, 0], [0, -1], [-1, 0], [0, 1]])


def test_handle_and_spout_are_mirror_symmetric():
    p = teapot.control_points("z_up")
    for group in ("handle", "spout"):
        a, b = teapot.GROUPS[group][0], teapot.GROUPS[group][-1]
        pts = p[a:b + 1].reshape(-1, 3)
        mirrored = pts * [1.0, -1.0, 1.0]
        as_set = {tuple(np.round(q, 9)) for q in pts}
        assert {tuple(np.round(q, 9)) for q in mirrored} == as_set, group
    # the handle's lower end lands on the body (Newell's point 69)
    assert tuple(teapot.VERTICES[68]) == (-2.0, 0.0, 0.9)


# --- the tessellated teapot ------------------------------------------------------------------------
def _welded(mesh):
    """The mesh with vertices merged by position only (uv seams and poles joined)."""
    _, first, inverse = np.unique(np.asarray(mesh.vertices), axis=0, return_index=True, return_inverse=True)
    return trimesh.Trimesh(np.asarray(mesh.vertices)[first], inverse.reshape(-1)[mesh.faces], process=False)


@settings(max_examples=4, deadline=None)
@given(segments=st.integers(3, 12))   # 1-2: too coarse to hold the knob's shape
def test_teapot_patches_are_stitched_and_wound_outward(segments):
    m = shapes.teapot(segments)
    w = _welded(m)
    open_edges, nonmanifold = edge_defects(w)
    # the openings Newell's teapot has, each `segments` edges per patch side: the lid's edge and the
    # rim's inner edge (4 + 4 patches), the spout's tip and base, the handle's two ends (2 each)
    assert (open_edges, nonmanifold) == (16 * segments, 0)
    assert w.is_winding_consistent
    assert len(w.split(only_watertight=False)) == 4          # body + bottom + rim, lid, handle, spout
    assert np.all(m.area_faces > 0.0)
    # one known-outward face per piece: the top of the knob, the body's widest point, the handle's
    # outermost point, the spout's tip's highest point
    c, n = w.triangles_center, w.face_normals
    top = np.argmax(c[:, 1])
    assert n[top, 1] > 0.5
    body = np.argmax(c[:, 2])    # handle and spout lie along x: the farthest +z is the body's side
    assert n[body, 2] > 0.5
    handle = np.argmin(c[:, 0])
    assert n[handle, 0] < -0.5
    bottom = np.argmin(c[:, 1])
    assert n[bottom, 1] < -0.9


def test_teapot_normals_point_out_everywhere():
    """Each face against a point inside its part: the axis at the face's height for the knob, the
    middle of the lip's arch for the rim, the pot's centre for lid, body and bottom, the tube's
    centre line for handle and spout."""
    m = shapes.teapot(6)
    uv, c, n = mesh_uv(m)[m.faces].mean(1), m.triangles_center, m.face_normals
    rotational = uv[:, 1] >= 0.25
    r = np.hypot(c[:, 0], c[:, 2])
    knob = rotational & (c[:, 1] > 2.6 + 1e-9) & (r < 0.85)
    rim = rotational & (c[:, 1] > 2.4 - 1e-9) & (r > 1.3 + 1e-9)
    inside = np.where(knob[:, None], c * [0.0, 1.0, 0.0], [0.0, 1.5, 0.0])
    inside[rim] = c[rim] / r[rim, None] * 1.45 * [1.0, 0.0, 1.0] + [0.0, 2.4, 0.0]
    assert knob.sum() > 20 and rim.sum() > 20
    out = np.einsum("ij,ij->i", n, c - inside)
    assert (out[rotational] > 0).all(), f"{int((out[rotational] <= 0).sum())} rotational faces point in"
    # handle and spout: against the centre of the tube's cross-section at the face's place along
    # the part (u), the midpoint of the tube's top and bottom curves (Newell's y = 0 columns)
    p = teapot.control_points("y_up")
    for group, ((u0, u1), (v0, v1)) in (("handle", teapot.HANDLE_UV), ("spout", teapot.SPOUT_UV)):
        first = teapot.GROUPS[group][0]
        faces = (uv[:, 1] <= v1) & (uv[:, 0] >= u0) & (uv[:, 0] <= u1)
        along = (uv[faces, 0] - u0) / (u1 - u0) * 2.0          # two patches along the part
        half = np.minimum(along.astype(int), 1)
        centre = np.empty((faces.sum(), 3))
        for h in (0, 1):
            sel = half == h
            ends = [teapot.evaluate(p[first + 2 * h], np.array([s]), np.array([0.0, 1.0]))[0].mean(0)
                    for s in along[sel] - h]
            centre[sel] = ends
        out = np.einsum("ij,ij->i", n[faces], c[faces] - centre)
        if group == "spout":   # the last quarter is the lip rolling over the tip: no simple inside point
            out = out[along <= 1.5]   # (its winding agrees with the rest: the stitched test's consistency)
        assert faces.sum() > 50 and (out > 0).all(), f"{group}: {int((out <= 0).sum())} faces point in"


def test_teapot_uv_atlas():
    m = shapes.teapot(8)
    uv, v = mesh_uv(m), np.asarray(m.vertices)
    assert uv is not None and uv.shape == (len(v), 2)
    assert uv.min() >= 0.0 and uv.max() <= 1.0
    rot = uv[:, 1] >= 0.25
    handle = (uv[:, 1] <= 0.24) & (uv[:, 0] <= 0.49)
    spout = (uv[:, 1] <= 0.24) & (uv[:, 0] >= 0.51)
    assert (rot | handle | spout).all() and not (handle & spout).any()
    assert (v[handle, 0] < -1.4).all() and (v[spout, 0] > 1.6).all()
    # rotational parts: u = angle / 2 pi counter-clockwise about +y from +x, off the axis
    r = np.hypot(v[:, 0], v[:, 2])
    angle = np.arctan2(-v[:, 2], v[:, 0]) / (2 * np.pi)
    off_axis = rot & (r > 0.05)
    du = (uv[off_axis, 0] - angle[off_axis] + 0.5) % 1.0 - 0.5
    assert np.abs(du).max() < 0.002
    # v goes up the profile: 0.25 at the bottom's centre, 1 at the knob's top, the body monotone
    assert uv[np.argmin(np.where(rot, v[:, 1] + r, np.inf)), 1] == 0.25
    assert uv[np.argmax(np.where(rot, v[:, 1], -np.inf)), 1] == 1.0
    body = rot & (r > 1.45) & (v[:, 1] < 2.4) & (v[:, 1] > 0.15)
    order = np.argsort(v[body, 1])
    assert np.all(np.diff(uv[body, 1][order]) >= -1e-12)
    # continuity: no face straddles a seam (every face's uv span is one grid step or so)
    span = np.ptp(uv[m.faces], axis=1)
    assert span.max() < 0.1
    # the seam u = 0 | 1: every vertex there has its twin at the same place with the other u
    seam0 = rot & (uv[:, 0] == 0.0) & (r > 0.05)
    twins = {(tuple(p), q) for p, q in zip(np.round(v[rot & (uv[:, 0] == 1.0)], 9), uv[rot & (uv[:, 0] == 1.0), 1])}
    assert seam0.sum() > 10 and all((tuple(p), q) in twins for p, q in zip(np.round(v[seam0], 9), uv[seam0, 1]))


def test_teapot_tangents_finite_and_along_u():
    m = shapes.teapot(8)
    check_tangents(m)
    n = shading_normals(m)
    t = vertex_tangents(m, n)
    assert np.isfinite(t).all() and np.isfinite(n).all()
    assert np.allclose(np.linalg.norm(t[:, :3], axis=1), 1.0) and np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert np.abs(np.einsum("ij,ij->i", t[:, :3], n)).max() < 1e-9
    assert (t[:, 3] == 1.0).all(), "the atlas is never mirrored"
    uv, v = mesh_uv(m), np.asarray(m.vertices)
    r = np.hypot(v[:, 0], v[:, 2])
    # on the rotational parts, away from the poles, +u is the counter-clockwise circle direction
    rot = (uv[:, 1] >= 0.25) & (r > 0.1)
    a = np.arctan2(-v[:, 2], v[:, 0])
    circle = np.stack([-np.sin(a), np.zeros_like(a), -np.cos(a)], 1)
    assert np.einsum("ij,ij->i", t[rot, :3], circle[rot]).min() > 0.99
    # handle and spout: +u runs along the part (handle: away from the body at its top, spout: out to the tip)
    handle = (uv[:, 1] <= 0.24) & (uv[:, 0] <= 0.49)
    top = handle & (v[:, 1] > 2.0) & (v[:, 0] > -2.2)
    assert top.sum() > 5 and (t[top, 0] < 0).all()
    spout = (uv[:, 1] <= 0.24) & (uv[:, 0] >= 0.51) & (v[:, 0] < 2.6)   # before the lip curls over
    assert spout.sum() > 5 and (t[spout, 0] > 0).all()


def test_teapot_deterministic_and_obj_round_trip(tmp_path):
    a, b = shapes.teapot(5), shapes.teapot(5)
    assert np.asarray(a.vertices).tobytes() == np.asarray(b.vertices).tobytes()
    assert np.asarray(a.faces).tobytes() == np.asarray(b.faces).tobytes()
    assert mesh_uv(a).tobytes() == mesh_uv(b).tobytes()
    out = tmp_path / "teapot.obj"
    assert shapes.main(["teapot", str(out), "5"]) == 0
    assert out.read_text() == obj_text(a)
    assert [p.name for p in tmp_path.iterdir()] == ["teapot.obj"]
    loaded = load_mesh(out)
    assert len(loaded.faces) == len(a.faces) and mesh_uv(loaded) is not None


@pytest.mark.parametrize("bad", [0, 65, 2.5, True, "8", None])
def test_teapot_bad_segments(bad):
    with pytest.raises(shapes.ShapeError, match="segments"):
        shapes.teapot(bad)


# --- sphere and plane ----------------------------------------------------------------------------------
@settings(max_examples=4, deadline=None)
@given(radius=st.floats(0.01, 100.0), segments=st.integers(3, 24))
def test_sphere(radius, segments):
    m = shapes.sphere(radius, segments)
    v, uv = np.asarray(m.vertices), mesh_uv(m)
    assert np.allclose(np.linalg.norm(v, axis=1), radius, rtol=1e-12)
    w = _welded(m)
    assert w.is_watertight and w.is_winding_consistent and w.volume > 0
    c, n = m.triangles_center, m.face_normals
    assert (np.einsum("ij,ij->i", n, c) > 0).all()
    # v = latitude, u = longitude counter-clockwise about +y (off the poles)
    assert np.allclose(uv[:, 1], np.arcsin(np.clip(v[:, 1] / radius, -1, 1)) / np.pi + 0.5, atol=1e-9)
    off = np.abs(v[:, 1]) < radius * (1 - 1e-9)
    du = (uv[off, 0] - np.arctan2(-v[off, 2], v[off, 0]) / (2 * np.pi) + 0.5) % 1.0 - 0.5
    assert np.abs(du).max() < 1e-9
    t = vertex_tangents(m)
    assert np.isfinite(t).all() and (t[:, 3] == 1.0).all()
    assert len(v) == (2 * segments + 1) * (segments - 1) + 2 * 2 * segments
    assert len(m.faces) == 2 * segments * 2 * (segments - 1)


def test_plane():
    m = shapes.plane(3.0, 2)
    v, uv = np.asarray(m.vertices), mesh_uv(m)
    assert len(v) == 9 and len(m.faces) == 8
    assert np.allclose(m.face_normals, [0, 1, 0])
    assert np.allclose(v[:, 0], (uv[:, 0] - 0.5) * 3.0) and np.allclose(v[:, 2], (0.5 - uv[:, 1]) * 3.0)
    t = vertex_tangents(m)
    assert np.allclose(t, [1, 0, 0, 1])
    assert np.isclose(m.area, 9.0)


# --- scenes ------------------------------------------------------------------------------------------
def _pbr_scene(mesh) -> dict:
    data = json.loads((PBR_ASSET / "scene.json").read_text())
    data["mesh"] = mesh
    return data


def test_scene_names_a_shape():
    from inshade.scene.description import parse_scene

    scene = parse_scene(_pbr_scene({"shape": "teapot", "segments": 3}), root=PBR_ASSET)
    assert scene.mesh.path is None and scene.mesh.name == "teapot"
    assert scene.mesh.shape == "teapot" and scene.mesh.params == {"segments": 3}
    assert len(scene.mesh.data.faces) == len(shapes.teapot(3).faces)
    sphere = parse_scene(_pbr_scene({"shape": "sphere", "radius": 2}), root=PBR_ASSET).mesh
    assert sphere.params == {"radius": 2.0, "segments": 32}
    assert parse_scene(_pbr_scene({"shape": "plane"}), root=PBR_ASSET).mesh.params == {"size": 2.0, "segments": 1}


@pytest.mark.parametrize("mesh, field", [
    ({"shape": "cube"}, "mesh.shape"),
    ({"segments": 4}, "mesh.shape"),
    ({"shape": ["teapot"]}, "mesh.shape"),
    ({"shape": "teapot", "segments": 0}, "mesh.segments"),
    ({"shape": "teapot", "segments": 1.5}, "mesh.segments"),
    ({"shape": "teapot", "segments": "8"}, "mesh.segments"),
    ({"shape": "teapot", "segments": True}, "mesh.segments"),
    ({"shape": "teapot", "segments": 10 ** 9}, "mesh.segments"),
    ({"shape": "teapot", "radius": 1}, "mesh.radius"),
    ({"shape": "sphere", "radius": -1}, "mesh.radius"),
    ({"shape": "sphere", "radius": 0}, "mesh.radius"),
    ({"shape": "sphere", "segments": 2}, "mesh.segments"),
    ({"shape": "plane", "size": None}, "mesh.size"),
    (["teapot"], "mesh"),
    (5, "mesh"),
])
def test_scene_shape_errors(mesh, field):
    from inshade.scene.description import SceneError, parse_scene

    with pytest.raises(SceneError) as info:
        parse_scene(_pbr_scene(mesh), root=PBR_ASSET)
    message = str(info.value)
    assert message.startswith(f"{field}:") and "\n" not in message, message


def test_mesh_without_uv_or_with_degenerate_uv(tmp_path):
    from inshade.scene.description import SceneError, parse_scene

    plain = shapes.sphere(1.0, 6)
    (tmp_path / "plain.obj").write_text(obj_text(trimesh.Trimesh(plain.vertices, plain.faces, process=False)))
    with pytest.raises(SceneError, match=r"^mesh: plain.obj has no texture coordinates, and "
                                         r"passes/mesh_pbr_set.frag needs the mesh attributes uv, tangent"):
        parse_scene(_pbr_scene("plain.obj"), root=tmp_path)
    flat = trimesh.Trimesh(plain.vertices, plain.faces, process=False,
                           visual=trimesh.visual.TextureVisuals(uv=np.full((len(plain.vertices), 2), 0.5)))
    (tmp_path / "flat.obj").write_text(obj_text(flat))
    with pytest.raises(SceneError, match=r"^mesh: flat.obj: texture coordinates are degenerate: all \d+ faces "
                                         r"have zero uv area .*needs the mesh attribute tangent"):
        parse_scene(_pbr_scene("flat.obj"), root=tmp_path)
    # one face with an area is enough: the rest get a tangent from their neighbours or the fallback
    uv = np.full((len(plain.vertices), 2), 0.5)
    uv[plain.faces[0]] = [[0, 0], [1, 0], [0, 1]]
    check_tangents(trimesh.Trimesh(plain.vertices, plain.faces, process=False,
                                   visual=trimesh.visual.TextureVisuals(uv=uv)))


def test_render_teapot_scene_records_the_shape(gl, tmp_path):
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import parse_scene

    data = _pbr_scene({"shape": "teapot", "segments": 4})
    data["camera"] = {"type": "orbit", "fov_y": 40.0, "target": [0.2, 1.4, 0.0], "distance": 9.0,
                      "yaw": 25.0, "pitch": -25.0}
    scene = parse_scene(data, root=PBR_ASSET)
    image, info = render_scene(scene, width=32, height=24, settings={"view": "uncompressed"})
    assert info["mesh"] == {"path": None, "shape": "teapot", "segments": 4, "name": "teapot",
                            "vertices": len(shapes.teapot(4).vertices), "faces": len(shapes.teapot(4).faces)}
    rgb = np.asarray(image)[..., :3]
    assert np.isfinite(rgb).all()
    # the teapot covers the middle of the frame and not the corners (background differs)
    assert np.abs(rgb[12, 16] - rgb[0, 0]).max() > 1e-3
    json.dumps(info)   # the sidecar is plain JSON
