"""The multiresolution grid encodings -- hash_grid, dense_grid -- on every shading language beside OpenGL's
GLSL (WGSL, Vulkan GLSL, HLSL, Slang: SPIR-V on wgpu over this machine's Vulkan device), held to
the rules of their GL test (tests/components/test_hash_grid.py: the parity rule of tests/parity.py, and
the rows read bit-identical to tiny-cuda-nn's, uint32 wrap-around included), and the shipped grid
bundles on every target."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.bundle import load
from inshade.codegen import generate
from inshade.components.elementwise.torch_twin import Tanh
from inshade.models import GraphModule
from inshade.runtime.compute import TARGETS, run_target
from parity import assert_parity, parity_settings, torch_reference, unit_directions
from test_hash_grid import (MIXED, build_grid, grid_cases, grid_inputs, row_reveal_graph, tcnn_grid_index,
                            tcnn_params_in_level, tcnn_resolution, vertex_inputs)

REPO = Path(__file__).resolve().parents[2]
SHIPPED = sorted(p for p in (REPO / "trained").glob("*/bundle.json")
                 if any(n.type in ("hash_grid", "dense_grid") for n in load(p).nodes))

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def outputs(gen, x, target):
    return run_target(gen, x, target)[0]


def check(bundle, x, target, what, **gen):
    out = outputs(generate(bundle, target=target, **gen), x, target)
    if out is not None:
        assert_parity(out, torch_reference(bundle, x), what=f"{target} {what}")


def grid_graph(case, init_scale: float = 1.0, layer: bool = False) -> GraphModule:
    """The grid alone, or (``layer``) feeding a small layer (tanh)."""
    g = GraphModule([("x", case["dims"])])
    g.add("grid", build_grid(case, init_scale), "x")
    if layer:
        g.dense("l0", "grid", 7)
        g.add("a0", Tanh(), "l0")
    g.output("y", "a0" if layer else "grid")
    return g


@pytest.mark.parametrize("target", TARGETS)
@parity_settings(max_examples=3)
@given(case=grid_cases(), seed=st.integers(0, 2 ** 31 - 1))
def test_grid_parity(target, case, seed):
    """Either kind, 2D or 3D, 1..8 features, f16 or f32, dense and hashed levels mixed; inputs on vertices,
    on cell borders and outside [0, 1]."""
    check(grid_graph(case).export("grid"), grid_inputs(case, seed), target, str(case))


# one per hash and both dense sizes (test_hash_grid.py's ROW_CASES, fewer)
ROW_CASES = [(2, "hash", 4097, 20, "coherent_prime"), (3, "hash", 4097, 13, "prime"),
             (3, "hash", 65, 16, "reversed_prime"), (2, "dense", 1025, 24, None), (3, "dense", 129, 24, None)]


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("dims,grid,base,log2,hash", ROW_CASES)
def test_rows_read_match_tiny_cuda_nn(target, dims, grid, base, log2, hash):
    """The row each vertex reads against grid_index written from tiny-cuda-nn's source, for coordinates up
    to 2^16 per axis and negative ones (uint32 wrap-around: WGSL's u32 and HLSL's uint wrap as GLSL's)."""
    g, _ = row_reveal_graph(dims, grid, base, log2, hash)
    res, size = tcnn_resolution(np.float32(base - 1)), tcnn_params_in_level(dims, base, grid, log2)
    c, x = vertex_inputs(dims * 1000 + log2, 512, dims, base - 1)
    want = tcnn_grid_index(c.astype(np.int64) & 0xFFFFFFFF, grid, size, res, hash)
    got = run_target(generate(g.export("grid_rows"), target=target), x, target)[0][:, 0]
    np.testing.assert_array_equal(got.astype(np.int64), want, err_msg=target)


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("case", MIXED, ids=["2d_hash_f16", "3d_hash_f32", "3d_dense_f32"])
def test_grid_into_dense(target, case):
    """The grid feeding a small layer (tanh); the hash grids mix dense and hashed levels."""
    torch.manual_seed(case["seed"])
    bundle = grid_graph(case, init_scale=0.5, layer=True).export("grid_mlp")
    check(bundle, grid_inputs(case, case["seed"]), target, f"{case} into dense")


@pytest.mark.parametrize("target", TARGETS)
def test_table_wraps_into_texture_rows(target):
    """Rows of 64 texels: level boundaries inside texture rows."""
    case = dict(kind="hash", dims=2, levels=4, features=8, base_resolution=8, per_level_scale=2.0, precision="f32",
                log2_table_size=10, hash="coherent_prime", seed=4, mixed=True)
    bundle = grid_graph(case).export("grid")
    gen = generate(bundle, target=target, limits={"GL_MAX_TEXTURE_SIZE": 64})
    assert [r.data.shape for r in gen.resources] == [(37, 64, 4), (37, 64, 4)]
    x = grid_inputs(case, 9)
    assert_parity(run_target(gen, x, target)[0], torch_reference(bundle, x), what=f"{target} rows of 64 texels")


def shipped_inputs(bundle, n: int) -> np.ndarray:
    """Positions and coordinates a little past [0, 1]; directions on the unit sphere."""
    rng = np.random.default_rng(11)
    cols = [unit_directions(12, n) if i.semantic == "direction" else rng.uniform(-0.1, 1.1, (n, i.dim))
            for i in bundle.inputs]
    return np.concatenate(cols, 1).astype(np.float32)


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("path", SHIPPED, ids=[p.parent.name for p in SHIPPED])
def test_shipped_grid_bundles_on_every_target(target, path):
    assert SHIPPED, "no shipped bundle holds a grid encoding"
    bundle = load(path)
    check(bundle, shipped_inputs(bundle, 192), target, path.parent.name)
