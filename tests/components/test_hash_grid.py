"""The multiresolution grid encodings "hash_grid" and "dense_grid" (inshade/grid_layout.py,
components/grids/torch_twin.py, components/grids/emit.py, components/grids/hash_grid.glsl) against tiny-cuda-nn's rules
transcribed here from its source (include/tiny-cuda-nn/common_device.h: lcg_hash and its primes,
grid_index, grid_scale, grid_resolution, pos_fract; encodings/grid.h: params_in_level and the
n-linear interpolation): the layout by hand, the rows read (bit-identical, coordinates up to 2^16 per
axis), the twin's forward and gradient, GLSL parity through generate() (tests/parity.py rule; the
exact path measures bit-identical on llvmpipe), tables wrapped into texture rows, the component checks.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from inshade.bundle import BundleError, load
from inshade.codegen import generate
from inshade.codegen.limits import LimitError
from inshade.components import ComponentError, check_node, resolve_params
from inshade.components.elementwise.torch_twin import Tanh
from inshade.components.grids.torch_twin import DenseGrid, HashGrid
from inshade.grid_layout import GridLayoutError, grid_levels, table_rows
from inshade.models import GraphModule

from fitting import fit_losses
from parity import assert_parity, glsl_eval, parity_settings, torch_reference

HASHES = ("coherent_prime", "prime", "reversed_prime")
f32 = np.float32


# --- tiny-cuda-nn's rules, written from its source (not from inshade/grid_layout.py) ---------------

# common_device.h: the factors of prime_hash, coherent_prime_hash, reversed_prime_hash (first three)
TCNN_FACTORS = {"prime": (1958374283, 2654435761, 805459861),
                "coherent_prime": (1, 2654435761, 805459861),
                "reversed_prime": (2165219737, 1434869437, 2097192037)}
TCNN_MAX_BASES = {2: 0xFFFF, 3: 0x659}     # grid_index's MAX_BASES[N_DIMS]


def tcnn_scale(level: int, per_level_scale: float, base_resolution: int) -> np.float32:
    """grid_scale(level, std::log2(per_level_scale), base_resolution), every step float32, with the
    C library's log2f and exp2f as tiny-cuda-nn's host code calls them (tests/tcnn_reference.py)."""
    from tcnn_reference import _host
    log2s = _host("log2f", per_level_scale)
    return f32(_host("exp2f", f32(f32(level) * log2s)) * f32(base_resolution)) - f32(1)


def tcnn_resolution(scale: np.float32) -> int:
    return int(np.ceil(scale)) + 1                  # grid_resolution: (uint32_t)ceilf(scale) + 1


def tcnn_params_in_level(dims: int, resolution: int, grid: str, log2_hashmap_size: int) -> int:
    """GridEncodingTemplated's constructor: dense size (capped at uint32 max / 2), next multiple of 8,
    then at most 2^log2_hashmap_size for a hash grid."""
    max_params = 0xFFFFFFFF // 2
    n = max_params if float(f32(resolution) ** dims) > float(f32(max_params)) else resolution ** dims
    n = -(-n // 8) * 8
    return min(n, 1 << log2_hashmap_size) if grid == "hash" else n


def tcnn_grid_index(c: np.ndarray, grid: str, hashmap_size: int, resolution: int, hash: str) -> np.ndarray:
    """grid_index(grid_type, hashmap_size, grid_resolution, pos_grid) for uint32 coordinates [..., dims]."""
    c = np.asarray(c, np.uint32)
    dims = c.shape[-1]
    index = np.zeros(c.shape[:-1], np.uint32)
    stride = 1
    if resolution <= TCNN_MAX_BASES[dims]:
        for d in range(dims):
            index = index + c[..., d] * np.uint32(stride)       # uint32 wrap-around
            stride *= resolution
    else:
        stride = 0xFFFFFFFF
    if grid == "hash" and hashmap_size < stride:
        index = np.zeros(c.shape[:-1], np.uint32)                # lcg_hash: xor of coordinate * factor
        for d in range(dims):
            index ^= c[..., d] * np.uint32(TCNN_FACTORS[hash][d])
    return (index % np.uint32(hashmap_size)).astype(np.int64)


def tcnn_layout(dims, levels, base_resolution, per_level_scale, log2_table_size, grid):
    """[(scale, resolution, hashmap_size, offset)] per level."""
    out, offset = [], 0
    for level in range(levels):
        scale = tcnn_scale(level, per_level_scale, base_resolution)
        res = tcnn_resolution(scale)
        size = tcnn_params_in_level(dims, res, grid, log2_table_size)
        out.append((scale, res, size, offset))
        offset += size
    return out


def tcnn_corners(x: np.ndarray, scale: np.float32):
    """pos_fract per axis and the n-linear corners: [(uint32 coords [M, dims], weight [M])] in corner
    order (bit d of the corner number is axis d). p = scale * x + 0.5 rounded twice, as the shader
    spells it (tiny-cuda-nn's fmaf rounds once; the envelope bounds the difference)."""
    p = f32(scale) * x + f32(0.5)
    g = np.floor(p)
    c = g.astype(np.int64) & 0xFFFFFFFF                          # (uint32_t)(int)floor(p)
    f = p - g
    out = []
    for corner in range(1 << x.shape[1]):
        w = np.ones(len(x), np.float32)
        cc = c.copy()
        for d in range(x.shape[1]):
            up = (corner >> d) & 1
            w = w * (f[:, d] if up else f32(1) - f[:, d])
            cc[:, d] = (cc[:, d] + up) & 0xFFFFFFFF
        out.append((cc, w))
    return out


def tcnn_forward(x: np.ndarray, table: np.ndarray, dims, levels, base, pls, log2, grid, hash="coherent_prime"):
    """The encoding, float32, corners accumulated in corner order: [M, levels * F]."""
    x = np.asarray(x, np.float32)
    outs = []
    for scale, res, size, offset in tcnn_layout(dims, levels, base, pls, log2, grid):
        acc = None
        for cc, w in tcnn_corners(x, scale):
            v = w[:, None] * table[offset + tcnn_grid_index(cc, grid, size, res, hash)]
            acc = v if acc is None else acc + v
        outs.append(acc)
    return np.concatenate(outs, 1)


# --- the layout by hand ---------------------------------------------------------------------------

def test_layout_by_hand():
    """Levels of three configurations worked out from the rules (tiny-cuda-nn's grid_scale,
    grid_resolution, params_in_level, grid_index's dense test)."""
    # 2D, base 16, scale 2, 2^8 rows: scale 16 * 2^l - 1; resolution 16 * 2^l; 256, 1024, 4096, 16384
    # vertices, capped at 256 rows: level 0 fits exactly (dense), the others hash.
    a = grid_levels(2, 4, 16, 2.0, 8, "hash")
    assert [float(lv.scale) for lv in a] == [15.0, 31.0, 63.0, 127.0]
    assert [(lv.resolution, lv.rows, lv.offset, lv.dense) for lv in a] == [
        (16, 256, 0, True), (32, 256, 256, False), (64, 256, 512, False), (128, 256, 768, False)]
    assert table_rows(a) == 1024
    # 3D, base 5, scale 1.5, 2^12 rows: scales 4, 6.5, 10.25 -> resolutions 5, 8, 12 -> 125, 512, 1728
    # vertices -> rows 128 (125 rounded up to 8), 512, 1728; all dense.
    b = grid_levels(3, 3, 5, 1.5, 12, "hash")
    assert [float(lv.scale) for lv in b] == pytest.approx([4.0, 6.5, 10.25], abs=2e-6)
    assert [(lv.resolution, lv.rows, lv.offset, lv.dense) for lv in b] == [
        (5, 128, 0, True), (8, 512, 128, True), (12, 1728, 640, True)]
    # 2D, base 16, scale 1.3819 (not a power of two), 2^10 rows: scales 16 * 1.3819^l - 1 = 15, 21.1104,
    # 29.5544, 41.2231 -> resolutions 16, 23, 31, 43 -> 256, 529, 961, 1849 vertices -> rows 256, 536,
    # 968 (dense: 529 <= 536, 961 <= 968), then 1856 capped at 1024 (hashed).
    c = grid_levels(2, 4, 16, 1.3819, 10, "hash")
    assert [float(lv.scale) for lv in c] == pytest.approx([15.0, 21.1104, 29.55436, 41.22307], abs=1e-4)
    assert [(lv.resolution, lv.rows, lv.offset, lv.dense) for lv in c] == [
        (16, 256, 0, True), (23, 536, 256, True), (31, 968, 792, True), (43, 1024, 1760, False)]
    # the same as a dense grid keeps every vertex: the last level is 1856 rows, dense
    d = grid_levels(2, 4, 16, 1.3819, 10, "dense")
    assert [(lv.rows, lv.dense) for lv in d] == [(256, True), (536, True), (968, True), (1856, True)]
    # 3D, resolution 2048 > 0x659: never dense (its index would overflow uint32); 2^33 vertices are
    # capped at 2^31 - 1, rounded up to 2^31, then to the table's 2^19 rows
    [e] = grid_levels(3, 1, 2048, 2.0, 19, "hash")
    assert (e.resolution, e.rows, e.dense) == (2048, 1 << 19, False)


@settings(deadline=None)   # a shared CI machine: timing is no part of the property
@given(dims=st.sampled_from([2, 3]), levels=st.integers(1, 16), base=st.integers(2, 64),
       pls=st.sampled_from([1.0, 1.26, 1.3819, 1.5, 2.0, 2.7, 4.0]), log2=st.integers(1, 24),
       grid=st.sampled_from(["hash", "dense"]))
def test_layout_matches_tiny_cuda_nn(dims, levels, base, pls, log2, grid):
    if grid == "dense":
        levels = min(levels, 4)
    want = tcnn_layout(dims, levels, base, pls, log2, grid)
    if want[-1][0] >= 2 ** 24:       # float32 p keeps no fraction: refused
        with pytest.raises(GridLayoutError, match=rf"^levels: level {next(i for i, w in enumerate(want) if w[0] >= 2 ** 24)} "):
            grid_levels(dims, levels, base, pls, log2, grid)
        return
    got = grid_levels(dims, levels, base, pls, log2, grid)
    assert [(lv.scale, lv.resolution, lv.rows, lv.offset) for lv in got] == want
    for lv, (_, res, size, _) in zip(got, want):    # grid_index's choice: dense where res^dims fits
        assert lv.dense == (res <= TCNN_MAX_BASES[dims] and res ** dims <= size)


# --- the rows read: the hash and the dense index, bit-identical -------------------------------------

def vertex_inputs(seed: int, n: int, dims: int, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Integer vertex coordinates c (0..2^16 per axis, a few negative: uint32 wrap-around) and the
    inputs x = (c - 0.5) / scale that land exactly on them (scale a power of two: x is exact, and
    p = scale * x + 0.5 = c with no rounding)."""
    rng = np.random.default_rng(seed)
    c = rng.integers(0, 65537, (n, dims))
    c[:8] = [[0] * dims, [65536] * dims, [65535] * dims, [1] * dims, [-1] * dims, [-7] * dims,
             [-65536] * dims, [65536, 0, 3][:dims]]
    c[8:40] = rng.integers(-65536, 0, (32, dims))
    x = ((c - 0.5) / scale).astype(np.float32)
    assert np.array_equal(f32(scale) * x + f32(0.5), c.astype(np.float32))
    return c, x


def row_reveal_graph(dims: int, grid: str, base: int, log2: int, hash: str) -> tuple[GraphModule, int]:
    """A 1-level, 1-feature grid whose table row r holds float(r) (exact below 2^24): at a vertex the
    output is the row read."""
    kw = dict(log2_table_size=log2, hash=hash) if grid == "hash" else {}
    cls = HashGrid if grid == "hash" else DenseGrid
    probe = cls(dims, 1, 1, base_resolution=base, precision="f32", **kw)
    rows = probe.table.shape[0]
    g = GraphModule([("x", dims)])
    g.add("grid", cls(dims, 1, 1, base_resolution=base, precision="f32", table=np.arange(rows)[:, None], **kw), "x")
    g.output("row", "grid")
    return g, rows


# (dims, grid, base_resolution: level 0's scale is base - 1, a power of two, log2_table_size)
ROW_CASES = [(dims, "hash", base, log2, h) for dims, base, log2 in ((2, 4097, 20), (3, 4097, 13), (3, 65, 16))
             for h in HASHES] + [(2, "dense", 1025, 24, None), (3, "dense", 129, 24, None)]


@pytest.mark.parametrize("dims,grid,base,log2,hash", ROW_CASES)
def test_rows_read_match_tiny_cuda_nn(gl, gl_limits, dims, grid, base, log2, hash):
    """The row each vertex reads, torch twin and GLSL, against grid_index written from the source,
    for coordinates up to 2^16 per axis (and negative ones, which wrap to uint32)."""
    g, rows = row_reveal_graph(dims, grid, base, log2, hash)
    scale = base - 1
    res, size = tcnn_resolution(f32(scale)), tcnn_params_in_level(dims, base, grid, log2)
    level = g.nodes["grid"].levels[0]
    assert (level.resolution, level.rows, level.dense) == (res, size, res <= TCNN_MAX_BASES[dims] and res ** dims <= size)
    assert level.dense == (grid == "dense")
    c, x = vertex_inputs(dims * 1000 + log2, 2048, dims, scale)
    want = tcnn_grid_index(c.astype(np.int64) & 0xFFFFFFFF, grid, size, res, hash)
    assert want.max() >= size // 2                     # high rows of the level are reached
    with torch.no_grad():
        got_torch = g(torch.from_numpy(x)).numpy()[:, 0]
    np.testing.assert_array_equal(got_torch.astype(np.int64), want, err_msg="torch twin")
    bundle = g.export("grid_rows")
    got_glsl = glsl_eval(gl, bundle, x, limits=gl_limits)[:, 0]
    np.testing.assert_array_equal(got_glsl.astype(np.int64), want, err_msg="GLSL")


# --- the twin's forward and gradient against the transcription (CPU) -------------------------------

@st.composite
def grid_cases(draw, max_rows: int = 1 << 14):
    """A grid of either kind, <= 32 output lanes; a hash grid's table size is chosen, where its levels
    allow, so that coarse levels are dense and fine ones hashed (`mixed`)."""
    kind = draw(st.sampled_from(["hash", "dense"]))
    dims = draw(st.sampled_from([2, 3]))
    features = draw(st.sampled_from([1, 2, 4, 8]))
    levels = draw(st.integers(1, min(8, 32 // features)))
    base = draw(st.integers(2, 16))
    pls = draw(st.sampled_from([1.0, 1.26, 1.3819, 1.5, 2.0, 3.0]))
    case = dict(kind=kind, dims=dims, levels=levels, features=features, base_resolution=base,
                per_level_scale=pls, precision=draw(st.sampled_from(["f16", "f32", "u8"])), mixed=False,
                seed=draw(st.integers(0, 2 ** 31 - 1)))
    if kind == "dense":      # keep the table small: drop fine levels
        while case["levels"] > 1 and table_rows(grid_levels(dims, case["levels"], base, pls, 24, "dense")) > max_rows:
            case["levels"] -= 1
        return case
    full = [lv.resolution ** dims for lv in grid_levels(dims, levels, base, pls, 24, "dense")]
    lo, hi = max(1, int(np.ceil(np.log2(-(-full[0] // 8) * 8)))), min(14, int(np.floor(np.log2(full[-1] - 1))))
    case["mixed"] = lo <= hi and draw(st.booleans())
    case["log2_table_size"] = draw(st.integers(lo, hi)) if case["mixed"] else draw(st.integers(1, 14))
    case["hash"] = draw(st.sampled_from(HASHES))
    return case


def build_grid(case, init_scale: float = 1.0):
    kw = {k: case[k] for k in ("levels", "features", "base_resolution", "per_level_scale", "precision")}
    if case["kind"] == "hash":
        return HashGrid(case["dims"], log2_table_size=case["log2_table_size"], hash=case["hash"], **kw,
                        init_scale=init_scale, seed=case["seed"])
    return DenseGrid(case["dims"], **kw, init_scale=init_scale, seed=case["seed"])


def on_vertices(x: np.ndarray, scale: np.float32) -> tuple[np.ndarray, np.ndarray]:
    """x moved (each coordinate a few float32 steps at most) so that p = scale * x + 0.5 (two roundings)
    is an integer: onto the vertices of the level with that scale. Where no nearby float does, the
    coordinate is left as it was; the returned mask says which rows landed on a vertex."""
    target = np.round(f32(scale) * x + f32(0.5))
    x0 = ((target - 0.5) / np.float64(scale)).astype(np.float32)
    out, hit = x.copy(), np.zeros(x.shape, bool)
    for steps in (0, 1, -1, 2, -2, 3, -3):
        xs = x0
        for _ in range(abs(steps)):
            xs = np.nextafter(xs, np.float32(np.inf if steps > 0 else -np.inf))
        p = f32(scale) * xs + f32(0.5)
        take = ~hit & (p == np.floor(p))
        out[take], hit[take] = xs[take], True
    return out, hit


def grid_inputs(case, seed: int, n: int = 256) -> np.ndarray:
    """Uniform in [0, 1]; an eighth in [-0.25, 1.25] (outside: the rules wrap, both sides alike); 0 and 1;
    a quarter exactly on a level's vertices (every axis) and a quarter on its cell borders (one axis)."""
    rng = np.random.default_rng(seed)
    dims = case["dims"]
    x = rng.uniform(0, 1, (n, dims)).astype(np.float32)
    x[: n // 8] = rng.uniform(-0.25, 1.25, (n // 8, dims))
    x[n // 8] = 0.0
    x[n // 8 + 1] = 1.0
    levels = grid_levels(dims, case["levels"], case["base_resolution"], case["per_level_scale"], 24)
    q = n // 4
    for rows, whole in ((slice(q, 2 * q), True), (slice(2 * q, 3 * q), False)):
        scale = levels[rng.integers(len(levels))].scale
        moved, hit = on_vertices(x[rows], scale)
        if not whole:
            keep = np.zeros_like(hit)
            keep[np.arange(len(keep)), rng.integers(0, dims, len(keep))] = True
            moved, hit = np.where(keep, moved, x[rows]), hit & keep
        x[rows] = moved
        assert hit.any(1).mean() > 0.5, "few inputs landed on vertices"
    return x


@settings(deadline=None)
@given(case=grid_cases(), seed=st.integers(0, 2 ** 31 - 1))
def test_twin_follows_tiny_cuda_nns_rules(case, seed):
    """The torch twin equals the transcription bit for bit (rows, weights, corner order); f16 tables
    are rounded to fp16 as the texture holds them, u8 ones blend their codes' unit values."""
    m = build_grid(case)
    table = m.table.detach().numpy()
    if case["precision"] == "f16":
        table = table.astype(np.float16).astype(np.float32)
    if case["precision"] == "u8":   # the unit values q / 255 blended, decoded after
        table = m.codes(m.table).astype(np.float32) / np.float32(255)
    x = grid_inputs(case, seed, 128)
    with torch.no_grad():
        got = m(torch.from_numpy(x)).numpy()
    want = tcnn_forward(x, table, case["dims"], case["levels"], case["base_resolution"], case["per_level_scale"],
                        case.get("log2_table_size", 24), case["kind"], case.get("hash", "coherent_prime"))
    if case["precision"] == "u8":
        r = m.unorm_range()
        want = np.tile(r["offset"], case["levels"]) + np.tile(r["scale"], case["levels"]) * want
    np.testing.assert_array_equal(got, want)
    if case["mixed"]:
        assert m.levels[0].dense and not m.levels[-1].dense


def test_gradient_reaches_the_rows_read():
    """d(sum of outputs) / d(table): each level's corner weights at the rows it read, from the
    transcription; no gradient to the input (as tiny-cuda-nn without input gradients)."""
    case = dict(kind="hash", dims=2, levels=4, features=2, base_resolution=4, per_level_scale=2.0, precision="f32",
                log2_table_size=6, hash="coherent_prime", seed=3, mixed=True)
    m = build_grid(case)
    assert m.levels[0].dense and not m.levels[-1].dense
    x = torch.tensor([[0.3, 0.7], [0.91, 0.05], [0.5, 0.5]], requires_grad=True)
    m(x).sum().backward()
    want = np.zeros(tuple(m.table.shape), np.float64)
    xn = x.detach().numpy()
    for scale, res, size, offset in tcnn_layout(2, 4, 4, 2.0, 6, "hash"):
        for cc, w in tcnn_corners(xn, scale):
            np.add.at(want, offset + tcnn_grid_index(cc, "hash", size, res, "coherent_prime"), w[:, None].astype(np.float64))
    np.testing.assert_allclose(m.table.grad.numpy(), want, rtol=1e-6, atol=1e-7)
    assert x.grad is None


@pytest.mark.parametrize("precision", ["f32", "f16"])
def test_tiny_fit_reduces_loss(precision):
    """A few Adam steps fit a small 2D image through grid + dense layer (CPU): the table learns."""
    torch.manual_seed(0)
    g = GraphModule([("uv", 2)])
    g.add("grid", HashGrid(2, 6, 2, log2_table_size=10, base_resolution=4, per_level_scale=1.5,
                           precision=precision, init_scale=1e-4), "uv")
    g.dense("out", "grid", 3)
    g.output("rgb", "out")
    uv = torch.rand(1024, 2)
    target = torch.stack([torch.sin(7 * uv[:, 0]) * torch.cos(5 * uv[:, 1]), uv[:, 0] * uv[:, 1],
                          (uv[:, 0] - 0.5).abs()], 1)
    start = g.nodes["grid"].table.detach().clone()
    losses = fit_losses(g, uv, target, steps=80, lr=2e-2)
    assert losses[-1] < 0.1 * losses[0], losses[::10]
    assert (g.nodes["grid"].table.detach() != start).any(1).float().mean() > 0.5   # most rows moved


# --- GLSL parity ---------------------------------------------------------------------------------

@parity_settings(max_examples=12)
@given(case=grid_cases(), seed=st.integers(0, 2 ** 31 - 1))
def test_grid_parity(gl, case, seed):
    g = GraphModule([("x", case["dims"])])
    m = g.add("grid", build_grid(case), "x")
    g.output("y", m)
    grid = g.nodes["grid"]
    if case["mixed"]:
        assert grid.levels[0].dense and not grid.levels[-1].dense, "the grid mixes dense and hashed levels"
    bundle = g.export("grid")
    x = grid_inputs(case, seed)
    assert_parity(glsl_eval(gl, bundle, x), torch_reference(bundle, x), what=str(case))


MIXED = [dict(kind="hash", dims=2, levels=8, features=4, base_resolution=8, per_level_scale=1.3819, precision="f16",
              log2_table_size=10, hash="prime", seed=1, mixed=True),
         dict(kind="hash", dims=3, levels=4, features=8, base_resolution=4, per_level_scale=2.0, precision="f32",
              log2_table_size=12, hash="reversed_prime", seed=2, mixed=True),
         dict(kind="dense", dims=3, levels=3, features=2, base_resolution=3, per_level_scale=1.5, precision="f32",
              seed=3, mixed=False)]


@pytest.mark.parametrize("case", MIXED, ids=["2d_hash_f16", "3d_hash_f32", "3d_dense_f32"])
@pytest.mark.parametrize("storage", ["inline", "texture"])
def test_grid_into_dense(gl, case, storage):
    """The grid feeding a small layer (tanh), both weight placements; the hash grids mix dense and
    hashed levels."""
    torch.manual_seed(case["seed"])
    g = GraphModule([("x", case["dims"])])
    g.add("grid", build_grid(case, init_scale=0.5), "x")
    g.dense("l0", "grid", 7)
    g.add("a0", Tanh(), "l0")
    g.output("y", "a0")
    levels = g.nodes["grid"].levels
    if case["mixed"]:
        assert any(lv.dense for lv in levels) and not all(lv.dense for lv in levels)
    bundle = g.export("grid_mlp")
    x = grid_inputs(case, case["seed"])
    assert_parity(glsl_eval(gl, bundle, x, storage=storage), torch_reference(bundle, x), what=f"{case} {storage}")


@pytest.mark.parametrize("version", ["450", "es300"])
def test_grid_parity_other_targets(gl, version):
    """GLSL 4.50 (where `precise` keeps p unfused) and ES 3.00 give the same numbers."""
    case = MIXED[0]
    g = GraphModule([("x", 2)])
    g.add("grid", build_grid(case), "x")
    g.output("y", "grid")
    bundle = g.export("grid")
    x = grid_inputs(case, 5)
    assert_parity(glsl_eval(gl, bundle, x, version=version), torch_reference(bundle, x), what=version)


# --- tables in texture rows, and limits ------------------------------------------------------------

def test_table_wraps_into_texture_rows(gl):
    """With GL_MAX_TEXTURE_SIZE 64 a 2368-row table is 37 rows of 64 texels (levels 0..3 at offsets
    0, 64, 320, 1344: level boundaries inside texture rows); parity holds."""
    case = dict(kind="hash", dims=2, levels=4, features=8, base_resolution=8, per_level_scale=2.0, precision="f32",
                log2_table_size=10, hash="coherent_prime", seed=4, mixed=True)
    g = GraphModule([("x", 2)])
    g.add("grid", build_grid(case), "x")
    g.output("y", "grid")
    levels = g.nodes["grid"].levels
    assert [(lv.rows, lv.offset, lv.dense) for lv in levels] == [(64, 0, True), (256, 64, True), (1024, 320, True),
                                                                  (1024, 1344, False)]
    bundle = g.export("grid")
    generated = generate(bundle, limits={"GL_MAX_TEXTURE_SIZE": 64})
    assert [r.data.shape for r in generated.resources] == [(37, 64, 4), (37, 64, 4)]   # features 0..3, 4..7
    x = grid_inputs(case, 9)
    assert_parity(glsl_eval(gl, generated, x), torch_reference(bundle, x), what="rows of 64 texels")


def test_table_too_large_for_the_limit():
    """Levels of 64, 256, 1024, 4096 and 4096 rows: 9536 texels, more than 64 x 64."""
    g = GraphModule([("x", 2)])
    g.add("grid", HashGrid(2, 5, 2, log2_table_size=12, base_resolution=8, per_level_scale=2.0), "x")
    g.output("y", "grid")
    with pytest.raises(LimitError, match=r"^node grid: the grid table needs 9536 texels, 64x149 in rows; "
                                         r"GL_MAX_TEXTURE_SIZE is 64 "):
        generate(g.export("grid"), limits={"GL_MAX_TEXTURE_SIZE": 64})


def test_plan_row():
    case = MIXED[0]
    g = GraphModule([("x", 2)])
    g.add("grid", build_grid(case), "x")
    g.output("y", "grid")
    gen = generate(g.export("grid"))
    row = next(r for r in gen.plan.rows if r.type == "hash_grid")
    hashed = sum(not lv.dense for lv in g.nodes["grid"].levels)
    assert f"8 levels x 4 (f16), {hashed} hashed" in row.shape and row.fetches == 8 * 4
    assert [r.dtype for r in gen.resources] == ["f2"]


# --- the component's checks ------------------------------------------------------------------------

def test_component_checks():
    p = resolve_params("hash_grid", {"levels": 4})
    assert p == {"levels": 4, "features": 2, "base_resolution": 16, "per_level_scale": 2.0, "precision": "f16",
                 "log2_table_size": 19, "hash": "coherent_prime"}
    assert check_node("hash_grid", p, 3) == 8
    for kind in ("hash_grid", "dense_grid"):
        for bad, field in (({"features": 3}, "features"), ({"features": 16}, "features"),
                           ({"per_level_scale": 0.5}, "per_level_scale"), ({"levels": 0}, "levels"),
                           ({"levels": 33}, "levels"), ({"base_resolution": 0}, "base_resolution"),
                           ({"precision": "f8"}, "precision")):
            with pytest.raises(ComponentError, match=f"^param '{field}' of {kind} "):
                resolve_params(kind, {"levels": 2, **bad})
        for dims in (1, 4):
            with pytest.raises(ComponentError, match=f"^{kind} cannot take a {dims}-wide input$"):
                check_node(kind, resolve_params(kind, {"levels": 2}), dims)
    for bad, field in (({"log2_table_size": 25}, "log2_table_size"), ({"hash": "rng"}, "hash")):
        with pytest.raises(ComponentError, match=f"^param '{field}' of hash_grid "):
            resolve_params("hash_grid", {"levels": 2, **bad})
    with pytest.raises(ComponentError, match="unknown params for dense_grid: hash, log2_table_size"):
        resolve_params("dense_grid", {"levels": 2, "hash": "prime", "log2_table_size": 10})
    # a dense grid too fine: its index would overflow uint32 (3D past 0x659 vertices per axis) ...
    fine = resolve_params("dense_grid", {"levels": 1, "base_resolution": 1700})
    with pytest.raises(ComponentError, match=r"^levels: the finest dense level has 1700 vertices per axis, "
                                             r"more than 1625 "):
        check_node("dense_grid", fine, 3)
    # ... or its table too long (2D, 10000^2 rows)
    with pytest.raises(ComponentError, match=r"^levels: the table needs 100000000 rows, more than 67108864$"):
        check_node("dense_grid", {**fine, "base_resolution": 10000}, 2)
    # a level so fine that float32 p = scale * x + 0.5 has no fraction (here 2^28: past int32 at 2^31 the
    # rows read would differ between executors); the same config one level shorter is accepted
    coarse = resolve_params("hash_grid", {"levels": 3, "base_resolution": 65536, "per_level_scale": 16.0})
    assert check_node("hash_grid", coarse, 3) == 6
    with pytest.raises(ComponentError, match=r"^levels: level 3 has scale 2\.684e\+08, not below 2\^24 "):
        check_node("hash_grid", {**coarse, "levels": 32}, 3)
    with pytest.raises(ComponentError, match="cannot take a 4-wide input"):
        HashGrid(4, 2)
    with pytest.raises(ComponentError, match=r"^table: shape \[8, 2\], expected \[64, 2\]$"):
        HashGrid(2, 1, 2, base_resolution=8, table=np.zeros((8, 2)))


def test_bad_node_in_a_bundle_names_the_field(tmp_path):
    g = GraphModule([("x", 2)])
    g.add("grid", HashGrid(2, 2, 2, log2_table_size=8, base_resolution=4), "x")
    g.output("y", "grid")
    folder = g.export("grid").save(tmp_path / "b")
    meta = json.loads((folder / "bundle.json").read_text())
    meta["nodes"][0]["params"]["features"] = 3
    (folder / "bundle.json").write_text(json.dumps(meta))
    with pytest.raises(BundleError, match=r"bundle\.json: nodes\[0\]\.params: param 'features' of hash_grid "):
        load(folder)
