"""geometry/mesh_topology.py: welding, corner and edge owner tables (hand-made meshes with the
owners worked out by hand, random meshes against a loop-by-loop reference), the errors, the
digest and the table validator."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from inshade.geometry.mesh_topology import MeshTopologyError, check_tables, mesh_topology, topology_digest, weld

QUAD = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)


def corner(owner, slot):
    return (owner << 2) | slot


def edge(owner, a, b):
    return (owner << 4) | (a << 2) | b


def reference(vertices, faces):
    """The rules of the module docstring, one face and one vertex at a time."""
    welded, _ = weld(vertices, faces)
    faces_of = {}
    for k, f in enumerate(welded.tolist()):
        for v in f:
            faces_of.setdefault(v, []).append(k)
    corners = np.zeros(welded.shape, np.uint32)
    edges = np.zeros(welded.shape, np.uint32)
    for k, f in enumerate(welded.tolist()):
        for i in range(3):
            owner = min(faces_of[f[i]])
            corners[k, i] = corner(owner, welded[owner].tolist().index(f[i]))
            vj, vm = f[(i + 1) % 3], f[(i + 2) % 3]
            owner = min(set(faces_of[vj]) & set(faces_of[vm]))
            of = welded[owner].tolist()
            edges[k, i] = edge(owner, of.index(vj), of.index(vm))
    return corners, edges


def test_two_triangles_sharing_an_edge():
    t = mesh_topology(QUAD, [[0, 1, 2], [1, 3, 2]])
    assert t.corners.dtype == np.uint32 and t.edges.dtype == np.uint32
    assert t.corners.tolist() == [[corner(0, 0), corner(0, 1), corner(0, 2)],
                                  [corner(0, 1), corner(1, 1), corner(0, 2)]]
    # face 0: edge 0 (v1 -> v2) is shared and owned by face 0; edges 1, 2 are boundaries
    # face 1: edge 1 runs v2 -> v1, i.e. slots (2, 1) of the owner face 0
    assert t.edges.tolist() == [[edge(0, 1, 2), edge(0, 2, 0), edge(0, 0, 1)],
                                [edge(1, 1, 2), edge(0, 2, 1), edge(1, 0, 1)]]


def test_fan_around_a_vertex_owned_by_its_lowest_face():
    ring = [[np.cos(a), np.sin(a), 0.0] for a in np.linspace(0, 2 * np.pi, 6)[:-1]]
    v = np.array([[0, 0, 0], *ring], np.float32)
    faces = [[1, 2, 3], [2, 0, 1], [0, 2, 3], [3, 4, 0], [0, 4, 5], [5, 1, 0]]
    t = mesh_topology(v, faces)
    centre = [t.corners[k, f.index(0)] for k, f in enumerate(faces) if 0 in f]
    assert centre == [corner(1, 1)] * 5      # face 0 does not touch the centre; face 1 has it at slot 1
    assert t.corners[3, 1] == corner(3, 1)   # vertex 4 first appears in face 3
    np.testing.assert_array_equal(t.edges, reference(v, faces)[1])


def test_non_manifold_edge_has_one_owner():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], np.float32)
    faces = [[0, 1, 2], [1, 0, 3], [0, 1, 4]]     # edge {0, 1} shared by three faces
    t = mesh_topology(v, faces)
    assert t.edges[0, 2] == edge(0, 0, 1)
    assert t.edges[1, 2] == edge(0, 1, 0)         # face 1 runs it v1 -> v0
    assert t.edges[2, 2] == edge(0, 0, 1)
    assert t.edges[2, 0] == edge(2, 1, 2)         # its other edges are boundaries: owned by itself
    assert t.edges[2, 1] == edge(2, 2, 0)


def test_uv_seam_vertices_are_welded_by_position():
    split = np.concatenate([QUAD, QUAD[[1, 2]]])  # vertices 4, 5 repeat 1, 2 (a uv seam)
    a = mesh_topology(QUAD, [[0, 1, 2], [1, 3, 2]])
    b = mesh_topology(split, [[0, 1, 2], [4, 3, 5]])
    np.testing.assert_array_equal(a.corners, b.corners)
    np.testing.assert_array_equal(a.edges, b.edges)
    assert a.digest == b.digest
    assert a.digest != mesh_topology(QUAD, [[1, 3, 2], [0, 1, 2]]).digest   # face order matters


def test_negative_zero_welds_with_zero():
    v = np.concatenate([QUAD, [[-0.0, 1.0, 0.0]]]).astype(np.float32)
    t = mesh_topology(v, [[0, 1, 2], [1, 3, 4]])
    assert t.corners[1, 2] == corner(0, 2)


def test_degenerate_face_after_welding_is_an_error():
    v = np.concatenate([QUAD, QUAD[[1]]])
    with pytest.raises(MeshTopologyError, match=r"^faces: face 1 is degenerate after welding vertices by "
                                                r"position \(vertex 4 twice\)$"):
        mesh_topology(v, [[0, 1, 2], [4, 3, 1]])
    with pytest.raises(MeshTopologyError, match=r"face 0 is degenerate .*\(vertex 2 twice\)"):
        mesh_topology(QUAD, [[2, 1, 2]])


def test_zero_area_face_with_distinct_vertices_is_fine():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]], np.float32)
    t = mesh_topology(v, [[0, 1, 2], [0, 2, 3]])
    assert t.corners[1].tolist() == [corner(0, 0), corner(0, 2), corner(1, 2)]


@pytest.mark.parametrize("vertices, faces, what", [
    (QUAD, [[0, 1, 4]], r"faces: face 0 names vertex 4, outside 0\.\.3"),
    (QUAD, [[0, -1, 2]], "faces: face 0 names vertex -1"),
    (QUAD, [[0, 1]], r"faces: must be a \[N, 3\] integer array"),
    (QUAD, [[0.0, 1.0, 2.0]], "faces: must be a .* integer array"),
    (QUAD, np.zeros((0, 3), int), "faces: must hold 1.."),
    (QUAD[:, :2], [[0, 1, 2]], r"vertices: must be a \[V, 3\]"),
    (np.where(np.arange(12).reshape(4, 3) == 4, np.nan, QUAD), [[0, 1, 2]], "vertices: vertex 1 is not finite"),
])
def test_bad_arrays(vertices, faces, what):
    with pytest.raises(MeshTopologyError, match=what):
        mesh_topology(vertices, np.asarray(faces))


@st.composite
def random_meshes(draw):
    """Faces over a small pool of grid positions, some vertices duplicated (seams), repeated
    and non-manifold edges likely; faces degenerate after welding are dropped."""
    n_pos = draw(st.integers(3, 8))
    pos = np.array([[i % 3, i // 3, (i * 7) % 5] for i in range(n_pos)], np.float32)
    dup = draw(st.lists(st.integers(0, n_pos - 1), max_size=4))
    v = np.concatenate([pos, pos[dup]]) if dup else pos
    where = np.arange(len(v)) % n_pos if not dup else np.concatenate([np.arange(n_pos), dup])
    raw = draw(st.lists(st.tuples(*[st.integers(0, len(v) - 1)] * 3), min_size=1, max_size=24))
    faces = [f for f in raw if len({int(where[i]) for i in f}) == 3]
    if not faces:
        faces = [(0, 1, 2)]
    return v, np.array(faces)


@settings(max_examples=150, deadline=None)
@given(random_meshes())
def test_tables_match_the_loop_reference(mesh):
    v, faces = mesh
    t = mesh_topology(v, faces)
    c, e = reference(v, faces)
    np.testing.assert_array_equal(t.corners, c)
    np.testing.assert_array_equal(t.edges, e)
    check_tables(t.corners, t.edges, len(faces))


def test_large_grid_tables_are_consistent():
    """A 2 x 64 x 64 grid (8192 faces, randomly ordered): every corner and edge owner is the
    lowest face holding that vertex / both edge vertices at the slots the tables name."""
    n = 64
    ij = np.stack(np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij"), -1).reshape(-1, 2)
    v = np.concatenate([ij, np.zeros((len(ij), 1))], 1).astype(np.float32)
    q = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).reshape(-1)
    faces = np.concatenate([np.stack([q, q + n + 1, q + 1], 1), np.stack([q + 1, q + n + 1, q + n + 2], 1)])
    faces = faces[np.random.default_rng(0).permutation(len(faces))]
    t = mesh_topology(v, faces)
    w = t.welded_faces
    k = np.arange(len(faces))[:, None]
    owner, slot = t.corners >> 2, t.corners & 3
    assert (owner <= k).all() and (w[owner, slot] == w).all()
    first = {}
    for f, verts in enumerate(w.tolist()):
        for x in verts:
            first.setdefault(x, f)
    assert (owner == np.vectorize(first.get)(w)).all()
    eo, a, b = t.edges >> 4, (t.edges >> 2) & 3, t.edges & 3
    assert (eo <= k).all()
    assert (w[eo, a] == w[:, [1, 2, 0]]).all() and (w[eo, b] == w[:, [2, 0, 1]]).all()
    shared = (eo < k).sum()           # each of the grid's interior edges is named by its second face
    assert shared == 3 * n * n - 2 * n


def test_digest_is_of_the_welded_faces():
    f = np.array([[0, 1, 2], [1, 3, 2]])
    assert topology_digest(f) == topology_digest(f.astype(np.uint32))
    assert len(topology_digest(f)) == 16 and topology_digest(f) != topology_digest(f[::-1])


def test_check_tables_refuses_out_of_range_entries():
    t = mesh_topology(QUAD, [[0, 1, 2], [1, 3, 2]])
    check_tables(t.corners, t.edges, 2)
    for name, bad in (("corners", (t.corners.copy(), 1, 1, corner(2, 0))),
                      ("corners", (t.corners.copy(), 0, 0, corner(0, 3))),
                      ("edges", (t.edges.copy(), 1, 2, edge(5, 0, 1))),
                      ("edges", (t.edges.copy(), 0, 0, edge(0, 1, 1)))):
        arr, k, i, value = bad
        arr[k, i] = value
        tables = (arr, t.edges) if name == "corners" else (t.corners, arr)
        with pytest.raises(MeshTopologyError, match=rf"{name}: entry \[{k}, {i}\]"):
            check_tables(*tables, 2)
    with pytest.raises(MeshTopologyError, match=r"corners: must be uint32 \[3, 3\]"):
        check_tables(t.corners, t.edges, 3)
