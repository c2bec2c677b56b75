"""The mesh_features component (models/mesh_features.py, components/mesh_features/emit.py,
shaders/lib/mesh_features.glsl): canonical names and hashes bit-exact between torch and GLSL for
every sub-vertex of small meshes, canonical names independent of the naming face, continuity
across edges and vertices, decode parity through generate() (tests/parity.py rule, exact
fp32 path; f16 tables are fp16 in both executors; u8 tables are the same uint8 codes and per-lane
scale/offset in both), the component spec, bundles, training.
"""
from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.bundle import Bundle, BundleError, load
from inshade.codegen import generate
from inshade.codegen.limits import LimitError
from inshade.components import ComponentError, check_node, resolve_params
from inshade.components.mesh_features.torch_twin import MeshFeatures
from inshade.geometry.mesh_topology import MeshTopologyError, mesh_topology
from inshade.models import GraphModule
from inshade.models.mesh_features import canonical, hash_index, hash_value, subvertices

from fitting import fit_losses
from parity import assert_parity, glsl_eval, parity_settings, run_sample_pass, torch_reference


# --- meshes ------------------------------------------------------------------------------------

def octahedron():
    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float32)
    f = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return v, np.array(f)


def grid(n: int, seed: int = 0):
    """An n x n grid of quads split in two triangles each, faces shuffled and their corners
    rotated, two vertices duplicated (a seam: welding must join them)."""
    rng = np.random.default_rng(seed)
    ij = np.stack(np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij"), -1).reshape(-1, 2)
    v = np.concatenate([ij / n, np.zeros((len(ij), 1))], 1).astype(np.float32)
    q = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).reshape(-1)
    f = np.concatenate([np.stack([q, q + n + 1, q + 1], 1), np.stack([q + 1, q + n + 1, q + n + 2], 1)])
    f = f[rng.permutation(len(f))]
    f = np.stack([np.roll(row, r) for row, r in zip(f, rng.integers(0, 3, len(f)))])
    dup = np.array([n + 2, (n + 1) * (n + 1) // 2])
    v = np.concatenate([v, v[dup]])
    for d, src in enumerate(dup):     # the first face using each duplicated vertex takes the copy
        k = int(np.argwhere(f == src)[0, 0])
        f[k][f[k] == src] = len(v) - 2 + d
    return v, f


MESHES = {"octahedron": octahedron(), "grid2": grid(2)}


def tables(mesh):
    t = mesh_topology(*mesh)
    return t, torch.from_numpy(t.corners.astype(np.int64)), torch.from_numpy(t.edges.astype(np.int64))


def all_subvertices(faces: int, level: int):
    """Every (k, W0, W1) of every face at `level` as int64 columns."""
    r = 1 << level
    w = [(a, b) for a in range(r + 1) for b in range(r + 1 - a)]
    k = np.repeat(np.arange(faces), len(w))
    w0, w1 = np.tile(np.array(w).T, faces)
    return [torch.from_numpy(np.asarray(a, np.int64)) for a in (k, w0, w1)]


# --- the test pass -----------------------------------------------------------------------------

def glsl_lib(gl, topo, k, w0, w1, level, t, table_size):
    """Runs tests/shaders/passes/mesh_features_test.frag: returns a dict of int64 / float arrays."""
    c, e = topo.corners.astype(np.float32), topo.edges.astype(np.float32)
    k = np.asarray(k)
    rows = np.zeros((len(k), 12), np.float32)
    rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3] = k, w0, w1, level
    rows[:, 4:7], rows[:, 7], rows[:, 8:10] = c[k], e[k, 0], e[k, 1:]
    rows[:, 10:12] = t
    assert (c < 2 ** 24).all() and (e < 2 ** 24).all()   # exact as floats
    o = run_sample_pass(gl, "passes/mesh_features_test.frag", rows, 3, attachments=5,
                        uniforms={"u_table_size": int(table_size)})
    i = lambda a: a.astype(np.int64)  # noqa: E731
    return dict(canon=i(o[0][:, :3]), h=i(o[0][:, 3]) | (i(o[1][:, 0]) << 16), index=i(o[1][:, 1]),
                w=i(np.concatenate([o[2], o[3][:, :2]], 1)),
                weight=np.concatenate([o[3][:, 2:], o[4][:, :1]], 1), taps=i(o[4][:, 1:]))


def torch_taps(k, t, level, corners, edges, table_size):
    w0, w1, weight = subvertices(torch.from_numpy(t[:, 0]), torch.from_numpy(t[:, 1]), level)
    w = torch.stack([w0, w1, (1 << level) - w0 - w1], -1)
    kk, c0, c1 = canonical(torch.as_tensor(k)[:, None].expand_as(w0), w, corners, edges, level)
    return w0, w1, weight, hash_index(kk, c0, c1, level, table_size)


def probe_points(w0: np.ndarray, w1: np.ndarray, level: np.ndarray) -> np.ndarray:
    """Four points per sub-vertex, on the edge cases of the sub-triangle rule: the sub-vertex
    itself; the midpoint of the diagonal of the upright sub-triangle at (W0, W1) (f0 + f1 == 1);
    a point on the outer diagonal pushed one ulp outside the face (t0 + t1 > 1, i + j == R - 1);
    a point inside the rotated sub-triangle at (W0, W1).
    Where a kind does not exist for a sub-vertex it falls back to the sub-vertex."""
    r = (1 << level).astype(np.float32)
    grid_t = np.stack([w0 / r, w1 / r], 1).astype(np.float32)
    diag = np.stack([(w0 + 0.5) / r, (w1 + 0.5) / r], 1).astype(np.float32)
    diag = np.where((w0 + w1 <= r - 1)[:, None], diag, grid_t)
    t0 = ((w0 + 0.25) / r).astype(np.float32)
    out = np.stack([t0, np.nextafter((1 - t0).astype(np.float32), np.float32(2))], 1)
    out = np.where((w0 < r)[:, None], out, grid_t)
    inside = np.stack([(w0 + 0.75) / r, (w1 + 0.75) / r], 1).astype(np.float32)
    inside = np.where((w0 + w1 <= r - 2)[:, None], inside, grid_t)
    return np.concatenate([grid_t, diag, out, inside])


@pytest.mark.parametrize("mesh", list(MESHES))
def test_every_subvertex_bit_exact(gl, mesh):
    """Levels 0..4, every sub-vertex of every face: (k', W'0, W'1), the full 32-bit h and the
    row index equal in torch and GLSL; the sub-triangle, weights and taps at probe_points."""
    topo, corners, edges = tables(MESHES[mesh])
    n, size = len(topo.corners), 1 << 10
    cols = [all_subvertices(n, level) + [level] for level in range(5)]
    k = torch.cat([c[0] for c in cols]).repeat(4)
    w0, w1 = torch.cat([c[1] for c in cols]).repeat(4), torch.cat([c[2] for c in cols]).repeat(4)
    level = np.tile(np.concatenate([np.full(len(c[0]), c[3]) for c in cols]), 4)
    m = len(k) // 4
    t = probe_points(w0.numpy()[:m], w1.numpy()[:m], level[:m])
    out = glsl_lib(gl, topo, k.numpy(), w0.numpy(), w1.numpy(), level, t, size)
    rotated = 0
    for lv in range(5):
        sel = torch.from_numpy(level == lv)
        w = torch.stack([w0[sel], w1[sel], (1 << lv) - w0[sel] - w1[sel]], -1)
        kk, c0, c1 = canonical(k[sel], w, corners, edges, lv)
        np.testing.assert_array_equal(out["canon"][sel.numpy()], torch.stack([kk, c0, c1], 1).numpy(),
                                      err_msg=f"{mesh} level {lv}: canonical")
        np.testing.assert_array_equal(out["h"][sel.numpy()], hash_value(kk, c0, c1, lv).numpy())
        np.testing.assert_array_equal(out["index"][sel.numpy()], hash_index(kk, c0, c1, lv, size).numpy())
        sw0, sw1, weight, taps = torch_taps(k[sel].numpy(), t[sel.numpy()], lv, corners, edges, size)
        np.testing.assert_array_equal(out["w"][sel.numpy()], torch.stack([sw0, sw1], -1).reshape(-1, 6).numpy(),
                                      err_msg=f"{mesh} level {lv}: sub-triangle")
        np.testing.assert_array_equal(out["weight"][sel.numpy()], weight.numpy())
        np.testing.assert_array_equal(out["taps"][sel.numpy()], taps.numpy())
        rotated += int((sw0[:, 0] > sw0[:, 1]).sum())
    assert out["h"].max() >= 1 << 24   # the high half was exercised
    assert rotated > 0                 # and both kinds of sub-triangle


@pytest.mark.parametrize("version", ["330", "450", "es300"])
def test_lib_passes_glslang(tmp_path, version):
    """The chunk (through its test pass) with the reference compiler, every target."""
    import shutil
    import subprocess

    from inshade.shaders import assemble

    assert shutil.which("glslangValidator"), "glslangValidator not found on PATH: install glslang-tools"
    path = assemble("passes/mesh_features_test.frag", version=version).write(tmp_path, "frag")
    result = subprocess.run(["glslangValidator", str(path)], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout


def test_hash_uses_32_bit_wraparound():
    k, w0, w1 = (torch.tensor([v]) for v in (5, 3, 7))
    want = ((2654435761 * 5) % 2 ** 32) ^ 3 ^ ((805459861 * 7) % 2 ** 32) ^ ((5389456063 * 2) % 2 ** 32)
    assert int(hash_value(k, w0, w1, 2)) == want
    assert int(hash_index(k, w0, w1, 2, 1 << 8)) == 2 * 256 + (want & 255)


@pytest.mark.parametrize("mesh", list(MESHES))
def test_canonical_names_each_surface_point_once(mesh):
    """A sub-vertex is the point sum_s W_s / R * vertex_s; every face naming the same point gives
    the same (k', W'), different points different ones, and a canonical name names itself."""
    topo, corners, edges = tables(MESHES[mesh])
    welded = topo.welded_faces
    for level in range(5):
        r = 1 << level
        k, w0, w1 = all_subvertices(len(welded), level)
        w = torch.stack([w0, w1, r - w0 - w1], -1)
        kk, c0, c1 = canonical(k, w, corners, edges, level)
        names = {}
        for ki, wi, name in zip(k.tolist(), w.tolist(), zip(kk.tolist(), c0.tolist(), c1.tolist())):
            point = frozenset((int(welded[ki][s]), wi[s]) for s in range(3) if wi[s])
            assert names.setdefault(point, name) == name, f"level {level}: {point} named {name} and {names[point]}"
        assert len(set(names.values())) == len(names)
        k2, d0, d1 = canonical(kk, torch.stack([c0, c1, r - c0 - c1], -1), corners, edges, level)
        assert torch.equal(k2, kk) and torch.equal(d0, c0) and torch.equal(d1, c1)


def test_subtriangle_rule_reconstructs_the_point():
    """The weighted sub-vertices give back R * t; weights sum to 1 and lie in [0, 1] (up to
    R * 2^-23: a float32 t0 + t1 may exceed 1 by an ulp, putting the point just outside)."""
    rng = np.random.default_rng(3)
    t = rng.dirichlet([1, 1, 1], 4000)[:, :2].astype(np.float32)
    t[:500] = (np.floor(t[:500] * 8) / 8).astype(np.float32)   # sub-triangle boundaries
    t[500:600, 1] = (1 - t[500:600, 0]).astype(np.float32)      # the outer edge t0 + t1 = 1
    for level in range(7):
        w0, w1, weight = subvertices(torch.from_numpy(t[:, 0]), torch.from_numpy(t[:, 1]), level)
        r = 1 << level
        assert (w0 >= 0).all() and (w1 >= 0).all() and (w0 + w1 <= r).all()
        back = torch.stack([(weight * w0).sum(-1), (weight * w1).sum(-1)], -1).double()
        np.testing.assert_allclose(back.numpy(), r * t.astype(np.float64), atol=4e-7 * r)
        slack = r * 2.0 ** -23
        assert (weight >= -slack).all() and (weight <= 1 + slack).all()
        np.testing.assert_allclose(weight.sum(-1).numpy(), 1.0, atol=1e-6)


# --- continuity ----------------------------------------------------------------------------------

def edge_point_pairs(mesh, s):
    """For every edge shared by two faces, the same point (1 - s) P_j + s P_m named from both:
    rows (k, t0, t1) for the first face and the second."""
    v, f = mesh
    topo = mesh_topology(v, f)
    w = topo.welded_faces
    first, second = [], []
    seen = {}
    for k in range(len(w)):
        for i in range(3):
            key = frozenset((w[k, (i + 1) % 3], w[k, (i + 2) % 3]))
            seen.setdefault(key, []).append((k, (i + 1) % 3, (i + 2) % 3))
    for key, users in seen.items():
        for (ka, ja, ma), (kb, jb, mb) in zip(users, users[1:]):
            for sv in s:
                ta, tb = np.zeros(3, np.float32), np.zeros(3, np.float32)
                ta[ja], ta[ma] = 1 - sv, sv
                vb = {w[ka, ja]: 1 - sv, w[ka, ma]: sv}
                tb[jb], tb[mb] = vb[w[kb, jb]], vb[w[kb, mb]]
                first.append([ka, *ta[:2]])
                second.append([kb, *tb[:2]])
    return np.array(first, np.float32), np.array(second, np.float32)


def vertex_point_sets(mesh):
    """Every welded vertex named from every face around it: rows (k, t0, t1), vertex ids."""
    v, f = mesh
    w = mesh_topology(v, f).welded_faces
    rows, ids = [], []
    for k in range(len(w)):
        for s in range(3):
            t = np.zeros(3, np.float32)
            t[s] = 1
            rows.append([k, *t[:2]])
            ids.append(w[k, s])
    return np.array(rows, np.float32), np.array(ids)


def feature_graph(mesh, levels, feats, size, precision="f32", uint=True, seed=0, scale=1.0):
    g = GraphModule([("triangle", 1, "generic", "uint"), ("bary", 2)] if uint else [("x", 3)])
    g.add("mf", MeshFeatures.for_mesh(*mesh, levels, feats, size, precision=precision, init_scale=scale,
                                      seed=seed), ["triangle", "bary"] if uint else "x")
    g.output("y", "mf")
    return g


@pytest.mark.parametrize("mesh", list(MESHES))
def test_continuous_across_edges_and_vertices(gl, mesh):
    g = feature_graph(MESHES[mesh], 5, 2, 64)
    dyadic = [0.0, 0.25, 0.5, 0.125, 0.8125]
    a, b = edge_point_pairs(MESHES[mesh], dyadic)
    with torch.no_grad():
        fa, fb = g(torch.from_numpy(a)), g(torch.from_numpy(b))
    assert torch.equal(fa, fb)                      # dyadic points: every float step is exact
    a, b = edge_point_pairs(MESHES[mesh], np.random.default_rng(1).uniform(0, 1, 6).astype(np.float32))
    with torch.no_grad():
        fa, fb = g(torch.from_numpy(a)), g(torch.from_numpy(b))
    np.testing.assert_allclose(fa.numpy(), fb.numpy(), atol=2e-6)
    rows, ids = vertex_point_sets(MESHES[mesh])
    with torch.no_grad():
        fv = g(torch.from_numpy(rows)).numpy()
    for vid in np.unique(ids):
        same = fv[ids == vid]
        assert (same == same[0]).all(), f"vertex {vid} has different features from different faces"
    x = np.concatenate([a, b, rows])
    bundle = g.export("mesh_features_test")
    assert_parity(glsl_eval(gl, bundle, x), torch_reference(bundle, x), what=f"{mesh} edges and vertices")


# --- decode parity -------------------------------------------------------------------------------

@st.composite
def feature_cases(draw):
    mesh = draw(st.sampled_from(["octahedron", "grid2", "grid3", "grid1"]))
    levels = draw(st.integers(1, 5))
    small = draw(st.booleans())     # GL_MAX_TEXTURE_SIZE 16: tables wrap into several rows
    size = 1 << draw(st.integers(1, 4 if small else 10))
    feats = draw(st.sampled_from([f for f in (1, 2, 4, 8) if levels * f <= 32]))   # <= 8 draw buffers
    return dict(mesh=mesh, levels=levels, feats=feats, size=size,
                precision=draw(st.sampled_from(["f16", "f32", "u8"])), uint=draw(st.booleans()),
                seed=draw(st.integers(0, 2 ** 31 - 1)), small=small)


def surface_points(faces: int, levels: int, seed: int, n: int = 96) -> np.ndarray:
    """Uniform points, points on edges (t0 = 0, t1 = 0, t0 + t1 = 1), at vertices and on the
    sub-triangle boundaries of the finest level."""
    rng = np.random.default_rng(seed)
    t = rng.dirichlet([1, 1, 1], n)[:, :2]
    q = n // 6
    t[:q, 0] = 0
    t[q:2 * q, 1] = 0
    t[2 * q:3 * q, 1] = 1 - t[2 * q:3 * q, 0]
    t[3 * q:4 * q] = np.eye(3)[rng.integers(0, 3, q), :2]
    r = 1 << (levels - 1)
    grid_t = np.floor(t[4 * q:5 * q] * r) / r
    t[4 * q:5 * q] = np.where(grid_t.sum(1, keepdims=True) <= 1, grid_t, t[4 * q:5 * q])
    t[5 * q:6 * q, 0] = np.floor(t[5 * q:6 * q, 0] * r) / r
    t = t.astype(np.float32)
    k = rng.integers(0, faces, n)
    return np.concatenate([k[:, None], t], 1).astype(np.float32)


@parity_settings(20)
@given(feature_cases())
def test_decode_parity(gl, case):
    mesh = MESHES.get(case["mesh"]) or grid(int(case["mesh"][-1]), case["seed"] % 97)
    g = feature_graph(mesh, case["levels"], case["feats"], case["size"], case["precision"], case["uint"],
                      case["seed"])
    bundle = g.export("mesh_features_test")
    x = surface_points(len(mesh[1]), case["levels"], case["seed"])
    limits = {"GL_MAX_TEXTURE_SIZE": 16} if case["small"] else None
    generated = generate(bundle, limits=limits)
    if case["small"]:
        assert all(max(r.data.shape[:2]) <= 16 for r in generated.resources)
    assert_parity(glsl_eval(gl, generated, x), torch_reference(bundle, x), what=str(case))


def test_plan_resources_and_limits():
    g = feature_graph(MESHES["grid2"], 4, 8, 1 << 10, "f16")
    gen = generate(g.export("mesh_features_test"))
    topo, t0, t1 = gen.resources
    assert topo.dtype == "u4" and topo.data.dtype == np.uint32 and topo.data.shape == (1, 8, 3)   # 1 texel per face
    assert t0.dtype == t1.dtype == "f2" and t0.data.shape == (4, 1024, 4)
    row = next(r for r in gen.plan.rows if r.type == "mesh_features")
    assert row.fetches == 1 + 3 * 4 * 2 and row.params == 4 * 1024 * 8
    assert row.texture_bytes == topo.nbytes + t0.nbytes + t1.nbytes
    assert "uniform usampler2D net_mf_topology;" in gen.chunk
    one = feature_graph(MESHES["grid2"], 2, 1, 8).export("mesh_features_test")
    assert generate(one).resources[1].data.shape == (1, 16, 1)            # F = 1: an R texture
    with pytest.raises(LimitError, match=r"node mf: the feature table needs 8192 texels.*GL_MAX_TEXTURE_SIZE is 64"):
        generate(feature_graph(MESHES["grid2"], 4, 2, 2048).export("t"), limits={"GL_MAX_TEXTURE_SIZE": 64})


def owner_tables(seed: int, faces: int, corner_owners: int, edge_owners: int):
    """Valid owner tables of ``faces`` faces that name no real mesh (parity needs none): corner
    owners < corner_owners, edge owners < edge_owners, random slots, the last face holding the
    largest of each."""
    rng = np.random.default_rng(seed)
    corners = (rng.integers(0, corner_owners, (faces, 3)) << 2) | rng.integers(0, 3, (faces, 3))
    slots = np.array([(a, b) for a in range(3) for b in range(3) if a != b])[rng.integers(0, 6, (faces, 3))]
    edges = (rng.integers(0, edge_owners, (faces, 3)) << 4) | (slots[..., 0] << 2) | slots[..., 1]
    corners[-1, 1], edges[-1, 2] = ((corner_owners - 1) << 2) | 2, ((edge_owners - 1) << 4) | 9
    return corners.astype(np.uint32), edges.astype(np.uint32)


# layout -> (bytes per face, the limits that force it, owner tables for parity: every lane's top bits)
LAYOUT_CASES = {
    "pack16": (12, {}, lambda: owner_tables(4, 1 << 14, 1 << 14, 1 << 12)),          # ids up to 0xFFFE / 0xFFF9
    "owners16": (16, {"PACK16_LIMIT": 0}, lambda: owner_tables(5, 1 << 16, 1 << 16, 1 << 16)),  # owners up to 0xFFFF
    "pack32": (24, {"PACK16_LIMIT": 0, "OWNERS16_LIMIT": 0}, lambda: owner_tables(6, 1 << 14, 1 << 14, 1 << 14)),
}


@pytest.mark.parametrize("layout", list(LAYOUT_CASES))
def test_topology_layouts(gl, monkeypatch, layout):
    """The owner tables' texture: two 16-bit ids to a channel (12 bytes per face) where every id
    fits, the owner faces two to a channel + slot bits (16 bytes) up to 2^16 faces, else 2 texels
    (24 bytes); the others forced by lowering the limits. Decode parity for each, with ids using
    the top bits of every lane, in wide rows and wrapped."""
    from inshade.components.mesh_features import emit as codegen

    per_face, limits, tables = LAYOUT_CASES[layout]
    for name, value in limits.items():
        monkeypatch.setattr(codegen, name, value)
    texels, function, _ = codegen.TOPOLOGY_LAYOUTS[layout]
    small = feature_graph(MESHES["grid2"], 2, 2, 16).export("t")      # 8 faces: rows without padding
    gen = generate(small)
    assert gen.resources[0].name == "net_mf_topology" and gen.resources[0].nbytes == per_face * 8
    assert next(r for r in gen.plan.rows if r.type == "mesh_features").fetches == texels + 3 * 2

    corners, edges = tables()
    faces = len(corners)
    g = GraphModule([("triangle", 1, "generic", "uint"), ("bary", 2)])
    # T = 2^14: the row index keeps hash bits up to 13, where an owner's bit 13 (corner id bit 15) lands
    g.add("mf", MeshFeatures(3, 2, 1 << 14, corners, edges, "f32", init_scale=1.0, seed=4), ["triangle", "bary"])
    g.output("y", "mf")
    bundle = g.export("mesh_features_test")
    x = surface_points(faces, 3, 5, 384)
    x[-1, 0] = faces - 1                     # the face holding the largest ids
    for cap in (1 << 14, 256):               # 256: the topology wraps into many rows
        gen = generate(bundle, limits={"GL_MAX_TEXTURE_SIZE": cap})
        width = min(cap, faces * texels)
        assert gen.resources[0].data.shape[:2] == (faces * texels // width, width)
        assert f"{function}(net_mf_topology" in gen.chunk
        assert_parity(glsl_eval(gl, gen, x), torch_reference(bundle, x), what=f"{layout} cap={cap}")


@pytest.mark.parametrize("feats,levels", [(4, 3), (2, 4), (8, 2), (1, 5)])
def test_u8_decode_parity(gl, feats, levels):
    """u8 tables: GLSL (unorm8 texels, affine decode after the blend) against torch on the bundle's
    dequantised values, one lane range far from [0, 1] (offset -3, scale 7)."""
    mesh = grid(3, 5)
    g = feature_graph(mesh, levels, feats, 64, "u8", seed=feats, scale=1.0)
    mf = g.nodes["mf"]
    with torch.no_grad():
        mf.table[:, 0].mul_(3.5).sub_(0.5)
    mf.calibrate()
    bundle = g.export("mesh_features_test")
    table = bundle.tensor(bundle.node("mf"), "table")
    assert table.dtype == np.uint8 and table.min() == 0 and table.max() == 255
    x = surface_points(len(mesh[1]), levels, feats + 11)
    for limits in (None, {"GL_MAX_TEXTURE_SIZE": 32}):      # 32: the tables wrap into rows
        assert_parity(glsl_eval(gl, generate(bundle, limits=limits), x), torch_reference(bundle, x),
                      what=f"u8 F={feats} L={levels} limits={limits}")


def test_u8_quantises_round_trips_and_trains_straight_through(tmp_path):
    m32 = MeshFeatures.for_mesh(*MESHES["grid2"], 3, 4, 64, precision="f32", init_scale=0.4, seed=3)
    m8 = MeshFeatures(3, 4, 64, m32.corners, m32.edges, "u8", table=m32.table.detach())
    scale, offset = m8.scale.numpy(), m8.offset.numpy()
    np.testing.assert_allclose(offset, m32.table.detach().min(0).values.numpy())
    np.testing.assert_allclose(scale + offset, m32.table.detach().max(0).values.numpy(), rtol=1e-6)
    x = torch.from_numpy(surface_points(8, 3, 9))
    with torch.no_grad():
        err = (m8(x) - m32(x)).abs().reshape(len(x), 3, 4)
    assert (err <= torch.from_numpy(scale) / 510 * 1.0001).all()     # half a code step at most
    g = GraphModule([("x", 3)])
    g.add("mf", m8, "x")
    g.output("y", "mf")
    bundle = load(g.export("mesh_features_test").save(tmp_path / "b"))
    q = bundle.tensor(bundle.node("mf"), "table")
    assert q.dtype == np.uint8 and q.shape == (3 * 64, 4)
    with torch.no_grad():
        np.testing.assert_array_equal(torch_reference(bundle, x.numpy()), m8(x).numpy())
    again = GraphModule.from_bundle(bundle)
    for slot in ("table", "scale", "offset"):     # loaded and re-exported: bit for bit
        np.testing.assert_array_equal(again.export("t").tensors[f"mf.{slot}"], bundle.tensors[f"mf.{slot}"])
    fresh = MeshFeatures(3, 4, 64, m8.corners, m8.edges, "u8", table=again.nodes["mf"].table.detach())
    fresh.calibrate(bundle.tensors["mf.scale"], bundle.tensors["mf.offset"])
    np.testing.assert_array_equal(fresh.export_tensors()["table"], q)          # requantising is exact
    m8(x).square().sum().backward()                                            # straight-through
    assert m8.table.grad.abs().sum() > 0


def test_u8_plan_bytes_and_bad_input():
    g16 = feature_graph(MESHES["grid2"], 4, 8, 1 << 10, "f16")
    g8 = feature_graph(MESHES["grid2"], 4, 8, 1 << 10, "u8")
    gen16, gen8 = generate(g16.export("t")), generate(g8.export("t"))
    _, t0, t1 = gen8.resources
    assert t0.dtype == t1.dtype == "f1" and t0.data.dtype == np.uint8 and t0.data.shape == (4, 1024, 4)
    assert 2 * t0.nbytes == gen16.resources[1].nbytes
    row = next(r for r in gen8.plan.rows if r.type == "mesh_features")
    assert "RGBA8 + RGBA8" in row.storage + row.why and "(u8)" in row.shape
    p = resolve_params("mesh_features", {"levels": 2, "table_size": 16, "faces": 8, "precision": "u8"})
    assert check_node("mesh_features", p, 3) == 4
    with pytest.raises(ComponentError, match="precision"):
        resolve_params("mesh_features", {**p, "precision": "u4"})
    m = MeshFeatures.for_mesh(*MESHES["octahedron"], 2, 2, 16, precision="u8")
    for scale, offset, match in (([1.0, 0.0], [0.0, 0.0], "scale: must be finite and > 0"),
                                 ([1.0, np.nan], [0.0, 0.0], "scale: must be finite"),
                                 ([1.0, 1.0], [0.0, np.inf], "offset finite"),
                                 ([1.0], [0.0], r"scale, offset: shape \[2\] each")):
        with pytest.raises(ComponentError, match=match):
            m.calibrate(scale, offset)
    b = feature_graph(MESHES["octahedron"], 2, 2, 16, "u8").export("t")
    bad = {k: v for k, v in b.tensors.items() if k != "mf.scale"}
    with pytest.raises(BundleError, match="mf.scale.*missing tensor"):
        Bundle(b.meta, bad)
    with pytest.raises(BundleError, match="mf.table.*dtype float32 but uint8 expected"):
        Bundle(b.meta, {**b.tensors, "mf.table": b.tensors["mf.table"].astype(np.float32)})


# --- component, bundles --------------------------------------------------------------------------

def test_component_spec():
    p = resolve_params("mesh_features", {"levels": 4, "table_size": 1 << 16, "faces": 10})
    assert p == {"levels": 4, "features": 2, "table_size": 1 << 16, "faces": 10, "precision": "f16"}
    assert check_node("mesh_features", p, 3) == 8
    for size in (0, 1, 3, 96, 1 << 25):
        with pytest.raises(ComponentError, match=rf"^table_size: must be a power of two, got {size}$"):
            check_node("mesh_features", {**p, "table_size": size}, 3)
    for faces in (0, (1 << 24) + 1):
        with pytest.raises(ComponentError, match=rf"^faces: must be 1\.\.16777216 .* got {faces}$"):
            check_node("mesh_features", {**p, "faces": faces}, 3)
    for bad, field in (({"features": 3}, "features"), ({"precision": "f8"}, "precision"), ({"levels": 17}, "levels"),
                       ({"table_size": 2.0}, "table_size")):
        with pytest.raises(ComponentError, match=field):
            resolve_params("mesh_features", {**p, **bad})
    with pytest.raises(ComponentError, match="cannot take a 2-wide input"):
        check_node("mesh_features", p, 2)
    with pytest.raises(ComponentError, match="levels \\* table_size \\* features"):
        check_node("mesh_features", {**p, "levels": 16, "table_size": 1 << 24, "features": 8}, 3)
    with pytest.raises(ComponentError, match="table_size: must be a power of two, got 12"):
        MeshFeatures.for_mesh(*MESHES["grid2"], 2, 2, 12)


def test_bundle_round_trip_and_bad_tables(tmp_path):
    g = feature_graph(MESHES["octahedron"], 3, 4, 64, "f16")
    bundle = load(g.export("mesh_features_test").save(tmp_path / "b"))
    assert bundle.inputs[0].dtype == "uint"
    assert bundle.tensor(bundle.node("mf"), "corners").dtype == np.uint32
    x = surface_points(8, 3, 0)
    with torch.no_grad():
        np.testing.assert_array_equal(torch_reference(bundle, x), g(torch.from_numpy(x)).numpy())
    table = bundle.tensor(bundle.node("mf"), "table")
    assert np.array_equal(table.astype(np.float16).astype(np.float32), table)
    bundle.tensors["mf.edges"] = bundle.tensors["mf.edges"].copy()
    bundle.tensors["mf.edges"][3, 1] = 8 << 4            # face 8 of an 8-face mesh
    with pytest.raises(MeshTopologyError, match=r"edges: entry \[3, 1\]"):
        generate(bundle)
    with pytest.raises(MeshTopologyError, match=r"edges: entry \[3, 1\]"):
        GraphModule.from_bundle(bundle)


def test_triangle_id_out_of_range_is_an_error():
    m = MeshFeatures.for_mesh(*MESHES["octahedron"], 2, 2, 16)
    with pytest.raises(ValueError, match=r"triangle id outside 0\.\.7 \(got 0\.\.8\)"):
        m(torch.tensor([[0.0, 0.1, 0.1], [8.0, 0.2, 0.2]]))


# --- training ------------------------------------------------------------------------------------

def test_gradients_reach_the_rows_read():
    m = MeshFeatures.for_mesh(*MESHES["grid2"], 3, 2, 256, precision="f32")
    x = torch.tensor([[1.0, 0.3, 0.2], [4.0, 0.0, 0.5]], requires_grad=True)
    m(x).sum().backward()
    expect = torch.zeros_like(m.table)
    for level in range(3):
        _, _, weight, taps = torch_taps(x[:, 0].long().numpy(), x[:, 1:].detach().numpy(), level, m.corners,
                                        m.edges, 256)
        expect.index_put_((taps.reshape(-1),), weight.reshape(-1, 1).expand(-1, 2), accumulate=True)
    torch.testing.assert_close(m.table.grad, expect)
    assert x.grad is None                            # barycentric gradients are not propagated


def test_f16_rounds_straight_through():
    m16 = MeshFeatures.for_mesh(*MESHES["grid2"], 2, 4, 64, precision="f16", init_scale=0.3, seed=5)
    m32 = MeshFeatures(2, 4, 64, m16.corners, m16.edges, "f32", table=m16.table.detach().half().float())
    x = torch.from_numpy(surface_points(8, 2, 4))
    torch.testing.assert_close(m16(x), m32(x), rtol=0, atol=0)
    m16(x).square().sum().backward()
    assert m16.table.grad.abs().sum() > 0


def test_tiny_fit_reduces_loss():
    torch.manual_seed(0)
    mesh = grid(3, 1)
    g = GraphModule([("x", 3)])
    g.add("mf", MeshFeatures.for_mesh(*mesh, 4, 2, 1 << 8, init_scale=1e-4), "x")
    g.dense("out", "mf", 3)
    g.output("y", "out")
    v, f = mesh
    x = torch.from_numpy(surface_points(len(f), 4, 2, 512))
    t = torch.cat([x[:, 1:], 1 - x[:, 1:].sum(1, keepdim=True)], 1)
    pos = (t[:, :, None] * torch.from_numpy(v[f])[x[:, 0].long()]).sum(1)
    target = torch.sin(6 * pos)                       # a colour that varies over the surface
    losses = fit_losses(g, x, target, steps=150, lr=1e-2)
    assert losses[-1] < 0.2 * losses[0], losses[::30]
