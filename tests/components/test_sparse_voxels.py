"""The `add` (residual connection) and `sparse_voxels` components (components/feature_axis/,
components/sparse_voxels/): GLSL against torch through the real driver (tests/parity.py
rule for add; exact for the voxel lookups: texelFetch of the very values torch indexes), the fixed
grid functions P_voxel_slot / P_voxel_sphere over every cell of every scale (and outside them)
against numpy, the component specs and every bad-table error.
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
from inshade.codegen.voxel_index import index_grid
from inshade.components import ComponentError, check_node, check_voxel_tables, resolve_params
from inshade.components.dense.torch_twin import Dense
from inshade.components.feature_axis.torch_twin import Add
from inshade.components.sparse_voxels.torch_twin import SparseVoxels
from inshade.components.unorm import decode
from inshade.models import GraphModule

from parity import assert_parity, glsl_eval, parity_settings, run_sample_pass, torch_reference, uniform_inputs


# --- add ------------------------------------------------------------------------------------------

@st.composite
def add_cases(draw):
    """n lanes per operand (1..20: tails of 1..3 lanes and whole blocks) wired four ways:
    two input ports, one 2n-wide port, two dense outputs (aligned arrays), ports packed after a
    1-lane port (unaligned offsets)."""
    return dict(n=draw(st.integers(1, 20)), wiring=draw(st.sampled_from(["ports", "one", "dense", "offset"])),
                seed=draw(st.integers(0, 2 ** 31 - 1)))


def add_graph(case) -> GraphModule:
    n, wiring = case["n"], case["wiring"]
    torch.manual_seed(case["seed"])
    if wiring == "one":
        g = GraphModule([("x", 2 * n)])
        g.add("sum", Add(), "x")
    elif wiring == "dense":
        g = GraphModule([("x", 3)])
        g.add("d0", Dense(3, n), "x")
        g.add("d1", Dense(3, n), "x")
        g.add("sum", Add(), ["d0", "d1"])
    else:
        ports = [("p", 1)] if wiring == "offset" else []
        g = GraphModule(ports + [("a", n), ("b", n)])
        g.add("sum", Add(), ["a", "b"])
    g.output("y", "sum")
    return g


@parity_settings(12)
@given(add_cases())
def test_add_parity(gl, case):
    g = add_graph(case)
    bundle = g.export("add_test")
    x = uniform_inputs(case["seed"], 64, bundle.in_dim, -4.0, 4.0)
    ref = torch_reference(bundle, x)
    np.testing.assert_allclose(ref, _numpy_add(case, x, g), rtol=0, atol=0)
    assert_parity(glsl_eval(gl, bundle, x), ref, what=str(case))


def _numpy_add(case, x, g):
    """The sum as numpy computes it from the graph's own inputs (dense outputs from torch)."""
    n = case["n"]
    if case["wiring"] == "dense":
        with torch.no_grad():
            xt = torch.from_numpy(x)
            return (g.nodes["d0"](xt) + g.nodes["d1"](xt)).numpy()
    off = 1 if case["wiring"] == "offset" else 0
    return x[:, off:off + n] + x[:, off + n:off + 2 * n]


def test_add_spec_and_errors():
    assert check_node("add", resolve_params("add", {}), 6) == 3
    for width in (1, 3, 7):
        with pytest.raises(ComponentError, match=f"add cannot take a {width}-wide input"):
            check_node("add", {}, width)
    g = GraphModule([("x", 3)])
    with pytest.raises(ComponentError, match="add cannot take a 3-wide input"):
        g.add("sum", Add(), "x")
    with pytest.raises(ValueError, match="add: input must be \\[a \\| b\\], an even width >= 2, got 5"):
        Add()(torch.zeros(2, 5))


def test_add_emits_vec4_adds_for_aligned_blocks():
    g = GraphModule([("x", 3)])
    g.add("d0", Dense(3, 6), "x")
    g.add("d1", Dense(3, 6), "x")
    g.add("sum", Add(), ["d0", "d1"])
    g.output("y", "sum")
    chunk = generate(g.export("t")).chunk
    assert "v_sum[0] = v_d0[0] + v_d1[0];" in chunk                 # one whole block
    assert "v_sum[1].x = v_d0[1].x + v_d1[1].x;" in chunk           # the tail lane by lane
    assert "v_sum[1] = v_d0[1] + v_d1[1];" not in chunk


# --- sparse voxels: random small grids --------------------------------------------------------------

def random_voxels(seed: int, scale_min: int, scale_max: int, density: float, clustered: bool = False):
    """cells [N, 4] uint32 sorted by (scale, k, j, i), spheres inside each cell; clustered: the
    occupied cells gather in a few blobs (as surfaces do), so many bricks stay empty."""
    rng = np.random.default_rng(seed)
    cells = []
    for s in range(scale_min, scale_max + 1):
        n = 1 << s
        occupied = rng.random((n, n, n)) < density                 # [k, j, i]
        if clustered:
            k, j, i = np.meshgrid(*[np.arange(n)] * 3, indexing="ij")
            centre = rng.uniform(0, n, 3)
            occupied &= (np.abs(k - centre[2]) + np.abs(j - centre[1]) + np.abs(i - centre[0])) < 0.4 * n + 1
        kji = np.argwhere(occupied)
        cells.append(np.column_stack([np.full(len(kji), s), kji[:, 2], kji[:, 1], kji[:, 0]]))
    cells = np.concatenate(cells).astype(np.uint32)
    if not len(cells):
        cells = np.array([[scale_max, 0, 0, 0]], np.uint32)
    size = 1.0 / (1 << cells[:, 0].astype(np.int64))
    centre = (cells[:, 1:].astype(np.float64) + rng.uniform(0.2, 0.8, (len(cells), 3))) * size[:, None]
    radius = np.maximum(rng.uniform(0, 0.9, len(cells)) * size, 1e-6)
    return cells, np.column_stack([centre, radius]).astype(np.float32)


@st.composite
def voxel_cases(draw):
    smin = draw(st.integers(0, 3))
    return dict(scale_min=smin, scale_max=draw(st.integers(smin, min(smin + 2, 4))),
                density=draw(st.sampled_from([0.02, 0.3, 1.0])), channels=draw(st.sampled_from([4, 8, 12, 28, 32])),
                precision=draw(st.sampled_from(["f16", "f32", "u8"])), uint=draw(st.booleans()),
                small=draw(st.booleans()), seed=draw(st.integers(0, 2 ** 31 - 1)))


def small_limits(case, bundle) -> dict | None:
    """For case["small"]: the smallest GL_MAX_TEXTURE_SIZE (>= 16) the latent table fits, so the
    tables wrap into many rows; else None (the GL 3.3 minimums)."""
    if not case["small"]:
        return None
    texels = bundle.node("vox").params["voxels"] * case["channels"] // 4
    side = 16
    while side * side < texels:
        side *= 2
    return {"GL_MAX_TEXTURE_SIZE": side}


def voxel_graph(case, cells=None, spheres=None) -> GraphModule:
    if cells is None:
        cells, spheres = random_voxels(case["seed"], case["scale_min"], case["scale_max"], case["density"])
    g = GraphModule([("slot", 1, "voxel_slot", "uint")] if case["uint"] else [("slot", 1)])
    g.add("vox", SparseVoxels(cells, spheres, case["channels"], case["scale_min"], case["scale_max"],
                              case["precision"], init_scale=3.0, seed=case["seed"]), "slot")
    g.output("latent", "vox")
    return g


@parity_settings(16)
@given(voxel_cases())
def test_latent_lookup_matches_torch_exactly(gl, case):
    """Random slots (every slot when few): GLSL's texelFetch returns exactly torch's row (fp16-rounded
    for f16 on both sides); a small GL_MAX_TEXTURE_SIZE makes the tables wrap into many rows."""
    g = voxel_graph(case)
    bundle = g.export("voxels_test")
    n = bundle.node("vox").params["voxels"]
    slots = np.random.default_rng(case["seed"]).integers(0, n, 200)
    slots[:min(n, 100)] = np.arange(min(n, 100))
    x = slots.astype(np.float32)[:, None]
    limits = small_limits(case, bundle)
    generated = generate(bundle, limits=limits)
    if limits:
        side = limits["GL_MAX_TEXTURE_SIZE"]
        assert all(max(r.data.shape[:2]) <= side for r in generated.resources if r.dims == 2)
    ref = torch_reference(bundle, x)
    node = bundle.node("vox")
    if case["precision"] == "u8":   # the decode's product and sum may round differently (e.g. fused)
        np.testing.assert_array_equal(ref, decode(bundle.tensor(node, "latents"), bundle.tensor(node, "scale"),
                                                  bundle.tensor(node, "offset"))[slots])
        assert_parity(glsl_eval(gl, generated, x), ref, what=str(case))
        return
    np.testing.assert_array_equal(ref, bundle.tensor(node, "latents")[slots])
    if case["precision"] == "f16":
        assert np.array_equal(ref.astype(np.float16).astype(np.float32), ref)
    np.testing.assert_array_equal(glsl_eval(gl, generated, x), ref, err_msg=str(case))


def grid_queries(scale_min: int, scale_max: int) -> np.ndarray:
    """(scale, i, j, k) for every cell of every scale, each grid padded by one cell all round
    (outside: 0), plus a few queries at scales just outside the range (0)."""
    rows = []
    for s in range(scale_min, scale_max + 1):
        r = np.arange(-1, (1 << s) + 1)
        k, j, i = np.meshgrid(r, r, r, indexing="ij")
        rows.append(np.column_stack([np.full(k.size, s), i.ravel(), j.ravel(), k.ravel()]))
    for s in (scale_min - 1, scale_max + 1):
        rows.append(np.array([[s, 0, 0, 0], [s, 1, 0, 1]]))
    return np.concatenate(rows).astype(np.float32)


def numpy_slot(cells: np.ndarray, q: np.ndarray) -> np.ndarray:
    table = {tuple(int(v) for v in c): r + 1 for r, c in enumerate(cells)}
    return np.array([table.get(tuple(int(v) for v in row), 0) for row in q], np.float32)


@parity_settings(10)
@given(voxel_cases())
def test_voxel_slot_and_sphere_functions(gl, case):
    """net_voxel_slot over every cell of every scale (and outside the grids and scales) equals the
    numpy table; net_voxel_sphere of every slot (and clamped ones past the end) equals `spheres`."""
    g = voxel_graph(case)
    bundle = g.export("voxels_test")
    cells, spheres = (bundle.tensor(bundle.node("vox"), s) for s in ("cells", "spheres"))
    generated = generate(bundle, limits=small_limits(case, bundle))
    q = grid_queries(case["scale_min"], case["scale_max"])
    out = run_sample_pass(gl, "passes/sparse_voxels_test.frag", q, attachments=2,
                          chunks={"network": generated.chunk}, generated=generated)
    np.testing.assert_array_equal(out[0][:, 0], numpy_slot(cells, q), err_msg=str(case))
    assert (out[0][0, 1:] == [case["scale_min"], case["scale_max"], len(cells)]).all()
    assert (out[0][:, 0] > 0).sum() == len(cells)          # every voxel found exactly once
    want = spheres[np.clip(q[:, 1].astype(np.int64), 0, len(cells) - 1)]
    np.testing.assert_array_equal(out[1], want)


def test_index_grid_levels():
    cells = np.array([[1, 0, 0, 0], [1, 1, 0, 1], [2, 3, 2, 1]], np.uint32)
    levels = index_grid(cells, 1, 2)
    assert [a.shape for a in levels] == [(4, 4, 4, 1), (2, 2, 2, 1)]
    assert levels[0][1, 2, 3, 0] == 3 and levels[0].sum() == 3          # [k, j, i] = slot + 1
    assert levels[1][0, 0, 0, 0] == 1 and levels[1][1, 0, 1, 0] == 2 and levels[1].sum() == 3


def test_plan_resources_and_names():
    case = dict(scale_min=1, scale_max=3, density=0.2, channels=28, precision="f16", uint=True, small=False, seed=1)
    bundle = voxel_graph(case).export("voxels_test")
    n = bundle.node("vox").params["voxels"]
    gen = generate(bundle, prefix="dap")
    lat, sph, grid = gen.resources
    assert lat.dtype == "f2" and lat.data.shape[-1] == 4 and lat.data.shape[0] * lat.data.shape[1] >= 7 * n
    assert sph.dtype == "f4" and grid.dtype == "u4" and grid.data.shape == (8, 8, 8, 1)
    assert [m.shape for m in grid.mips] == [(4, 4, 4, 1), (2, 2, 2, 1)]
    for line in ("#define DAP_SCALE_MIN 1", "#define DAP_SCALE_MAX 3", f"#define DAP_VOXELS {n}",
                 "uint dap_voxel_slot(int scale, ivec3 cell) {", "vec4 dap_voxel_sphere(uint slot) {",
                 "uniform usampler3D dap_vox_grid;"):
        assert line in gen.chunk, line
    row = next(r for r in gen.plan.rows if r.type == "sparse_voxels")
    assert row.texture_bytes == lat.nbytes + sph.nbytes + grid.nbytes
    assert grid.nbytes == 4 * (512 + 64 + 8) and row.fetches == 7 and row.params == n * 28
    with pytest.raises(LimitError, match=r"node vox: the index grid of scale 3 is 8\^3 texels; "
                                         r"GL_MAX_3D_TEXTURE_SIZE is 4"):
        generate(bundle, limits={"GL_MAX_3D_TEXTURE_SIZE": 4})


def test_one_sparse_voxels_node_per_network():
    cells, spheres = random_voxels(0, 1, 1, 0.5)
    g = GraphModule([("slot", 1)])
    g.add("a", SparseVoxels(cells, spheres, 4, 1, 1), "slot")
    g.add("b", SparseVoxels(cells, spheres, 4, 1, 1), "slot")
    g.output("y", "a")
    g.output("z", "b")
    with pytest.raises(ValueError, match="node b: a network holds at most one sparse_voxels node"):
        generate(g.export("t"))


# --- spec, tables, bundles ------------------------------------------------------------------------

def test_component_spec():
    p = resolve_params("sparse_voxels", {"voxels": 5, "channels": 8, "scale_min": 2, "scale_max": 4})
    assert p == {"voxels": 5, "channels": 8, "scale_min": 2, "scale_max": 4, "precision": "f16", "index": "dense",
                 "brick": 4}
    assert check_node("sparse_voxels", p, 1) == 8
    with pytest.raises(ComponentError, match="sparse_voxels cannot take a 2-wide input"):
        check_node("sparse_voxels", p, 2)
    with pytest.raises(ComponentError, match=r"^scale_min: must be <= scale_max \(1\), got 2$"):
        check_node("sparse_voxels", {**p, "scale_max": 1}, 1)
    for bad, field in (({"channels": 6}, "channels"), ({"channels": 68}, "channels"), ({"scale_max": 10}, "scale_max"),
                       ({"scale_min": -1}, "scale_min"), ({"voxels": 0}, "voxels"), ({"precision": "f8"}, "precision")):
        with pytest.raises(ComponentError, match=f"param '{field}' of sparse_voxels"):
            resolve_params("sparse_voxels", {**p, **bad})


GOOD_CELLS = np.array([[1, 0, 0, 0], [1, 1, 0, 0], [1, 0, 1, 1], [2, 3, 3, 3]], np.uint32)
GOOD_SPHERES = np.tile(np.array([[0.5, 0.5, 0.5, 0.1]], np.float32), (4, 1))


def _bad(cells=None, spheres=None, latents=None):
    return (GOOD_CELLS if cells is None else np.asarray(cells, np.uint32),
            GOOD_SPHERES if spheres is None else np.asarray(spheres, np.float32),
            np.zeros((4, 4), np.float32) if latents is None else latents)


BAD_TABLES = {
    "unsorted": (_bad(cells=GOOD_CELLS[[1, 0, 2, 3]]),
                 r"^cells: row 1 \[1, 0, 0, 0\] is out of order \(rows must be sorted by \(scale, k, j, i\)"),
    "repeated": (_bad(cells=GOOD_CELLS[[0, 0, 2, 3]]), r"^cells: row 1 \[1, 0, 0, 0\] repeats"),
    "scale": (_bad(cells=[[1, 0, 0, 0], [1, 1, 0, 0], [1, 0, 1, 1], [3, 3, 3, 3]]),
              r"^cells: row 3 has scale 3, outside scale_min\.\.scale_max 1\.\.2$"),
    "cell": (_bad(cells=[[1, 0, 0, 0], [1, 2, 0, 0], [1, 0, 1, 1], [2, 3, 3, 3]]),
             r"^cells: row 1 \(scale 1, cell \[2, 0, 0\]\) is outside the 2\^3 grid of its scale$"),
    "radius": (_bad(spheres=np.where(np.arange(4)[:, None] == 2, [0.5, 0.5, 0.5, 0.0], GOOD_SPHERES)),
               r"^spheres: row 2 has radius 0 \(must be >= 1e-6\)$"),
    "sphere nan": (_bad(spheres=np.where(np.arange(4)[:, None] == 3, np.nan, GOOD_SPHERES)),
                   r"^spheres: NaN or Inf at row 3$"),
    "latent nan": (_bad(latents=np.where(np.arange(4)[:, None] == 2, np.nan, 0.0).repeat(4, 1)),
                   r"^latents: NaN at row 2$"),
    "latent inf": (_bad(latents=np.where(np.arange(4)[:, None] == 1, np.inf, 0.0).repeat(4, 1)),
                   r"^latents: Inf at row 1$"),
    "rows": (_bad(latents=np.zeros((3, 4), np.float32)),
             r"^latents: shape \[3, 4\], expected \[4, Z\] \(one row per cell: "
             r"the index grid points at rows 0\.\.3\)$"),
}


@pytest.mark.parametrize("name", list(BAD_TABLES))
def test_bad_tables_are_one_clear_error(name):
    (cells, spheres, latents), message = BAD_TABLES[name]
    with pytest.raises(ComponentError, match=message):
        check_voxel_tables(cells, spheres, 1, 2, latents)
    if name != "rows":        # the module refuses the same tables when built from arrays
        with pytest.raises((ComponentError, ValueError), match=message[1:]):
            SparseVoxels(cells, spheres, 4, 1, 2, "f32", latents=latents)


def good_bundle(precision="f32") -> Bundle:
    g = GraphModule([("slot", 1, "voxel_slot", "uint")])
    g.add("vox", SparseVoxels(GOOD_CELLS, GOOD_SPHERES, 4, 1, 2, precision, init_scale=1.0), "slot")
    g.output("latent", "vox")
    return g.export("voxels_test")


@pytest.mark.parametrize("name", ["unsorted", "repeated", "scale", "cell", "radius"])
def test_a_bundle_with_bad_tables_is_refused_by_both_executors(tmp_path, name):
    """A stranger's bundle: the tables are checked where a bundle is used, by the torch module
    (GraphModule.from_bundle) and by codegen (generate), with the same message."""
    (cells, spheres, _), message = BAD_TABLES[name]
    bundle = load(good_bundle().save(tmp_path / "b"))
    bundle.tensors["vox.cells"], bundle.tensors["vox.spheres"] = cells, spheres
    with pytest.raises(ComponentError, match=message):
        GraphModule.from_bundle(bundle)
    with pytest.raises(ComponentError, match=message):
        generate(bundle)


def test_bundle_level_errors(tmp_path):
    """NaN latents and a table of another length never load (the bundle's generic checks name the
    tensor); the grid is built from cells, so a slot past the latent table cannot be written."""
    good = good_bundle()
    bad = dict(good.tensors)
    bad["vox.latents"] = good.tensors["vox.latents"].copy()
    bad["vox.latents"][2, 1] = np.nan
    with pytest.raises(BundleError, match=r"vox\.latents: contains NaN or Inf"):
        Bundle(good.meta, bad)
    short = {**good.tensors, "vox.spheres": good.tensors["vox.spheres"][:3]}
    with pytest.raises(BundleError, match=r"vox\.spheres: shape \[3, 4\] but \[4, 4\] expected"):
        Bundle(good.meta, short)
    levels = index_grid(GOOD_CELLS, 1, 2)
    assert max(int(a.max()) for a in levels) == len(GOOD_CELLS)


def test_bundle_round_trip(tmp_path):
    g = GraphModule([("slot", 1, "voxel_slot", "uint")])
    g.add("vox", SparseVoxels(GOOD_CELLS, GOOD_SPHERES, 8, 1, 2, "f16", init_scale=1.0, seed=3), "slot")
    g.output("latent", "vox")
    bundle = load(g.export("voxels_test").save(tmp_path / "b"))
    assert bundle.tensor(bundle.node("vox"), "cells").dtype == np.uint32
    x = np.array([[0], [3], [1]], np.float32)
    with torch.no_grad():
        np.testing.assert_array_equal(torch_reference(bundle, x), g(torch.from_numpy(x)).numpy())
    lat = bundle.tensor(bundle.node("vox"), "latents")
    assert np.array_equal(lat.astype(np.float16).astype(np.float32), lat)


def test_slot_out_of_range_is_an_error_in_torch():
    m = SparseVoxels(GOOD_CELLS, GOOD_SPHERES, 4, 1, 2)
    for bad in (4.0, -1.0, 1.5):
        with pytest.raises(ValueError, match=rf"sparse_voxels: slot {bad:g} is not a row 0\.\.3"):
            m(torch.tensor([[0.0], [bad]]))


def test_gradients_reach_only_the_rows_read_and_f16_is_straight_through():
    m = SparseVoxels(GOOD_CELLS, GOOD_SPHERES, 4, 1, 2, "f16", init_scale=0.3, seed=2)
    m32 = SparseVoxels(GOOD_CELLS, GOOD_SPHERES, 4, 1, 2, "f32", latents=m.latents.detach().half().float())
    x = torch.tensor([[1.0], [3.0], [1.0]])
    torch.testing.assert_close(m(x), m32(x), rtol=0, atol=0)
    m(x).sum().backward()
    np.testing.assert_array_equal(m.latents.grad.numpy(), np.array([[0] * 4, [2] * 4, [0] * 4, [1] * 4], np.float32))
    assert not m.cells.requires_grad and not m.spheres.requires_grad


@pytest.mark.parametrize("version", ["330", "450", "es300"])
def test_generated_chunk_passes_glslang(tmp_path, version):
    """The generated chunk (usampler3D grid, its fixed functions) through the test pass with the
    reference compiler, every target (ES 3.00 has no default precision for usampler3D)."""
    import shutil
    import subprocess

    from inshade.shaders import assemble

    assert shutil.which("glslangValidator"), "glslangValidator not found on PATH: install glslang-tools"
    case = dict(scale_min=0, scale_max=2, density=0.3, channels=8, precision="f16", uint=True, small=False, seed=4)
    generated = generate(voxel_graph(case).export("voxels_test"), target=version)
    path = assemble("passes/sparse_voxels_test.frag", version=version,
                    chunks={"network": generated.chunk}).write(tmp_path, "frag")
    result = subprocess.run(["glslangValidator", str(path)], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout
