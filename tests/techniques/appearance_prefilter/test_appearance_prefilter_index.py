"""appearance_prefilter's cell -> slot index (codegen/voxel_index.py): the ``bricks`` layout against
the dense grid, in numpy, in the torch march twin and through the real driver.

- numpy: on random sparse voxels every cell of every scale (each grid padded by one cell, scales
  just outside the range) finds the same slot + 1 in the bricks as in the dense grid, for every
  brick side; the byte count without building equals the built tables; best_brick is the smallest;
- GLSL: net_voxel_slot of a bricks node equals numpy over the same queries (tables wrapped into
  many rows by a small GL_MAX_TEXTURE_SIZE, never past it); no 3D texture is made;
- torch: march.py's lookups agree with each other on every cell;
- the shipped grove is on the brick side best_brick picks, its bricks take the bytes the memory
  report gives (a tenth of the dense grid's), and without the ``index`` param it reads as dense.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from inshade.bundle import load
from inshade.codegen import generate
from inshade.codegen.limits import LimitError
from inshade.codegen.voxel_index import (BRICK_SIDES, best_brick, brick_bytes, brick_index, brick_slot,
                                         dense_bytes, index_grid)
from inshade.components.sparse_voxels.torch_twin import SparseVoxels
from inshade.models import GraphModule

from parity import parity_settings, run_sample_pass
from test_sparse_voxels import grid_queries, random_voxels

from inshade.techniques.appearance_prefilter import march, memory

GROVE = Path(__file__).resolve().parents[3] / "trained" / "appearance_prefilter_grove"


def queries(scale_min: int, scale_max: int) -> np.ndarray:
    """(scale, i, j, k) int64 of every padded cell of every scale and just outside the range."""
    return grid_queries(scale_min, scale_max).astype(np.int64)


def dense_slot(cells: np.ndarray, scale_min: int, scale_max: int, q: np.ndarray) -> np.ndarray:
    levels = index_grid(cells, scale_min, scale_max)
    out = np.zeros(len(q), np.uint32)
    for row, (s, i, j, k) in enumerate(q):
        if scale_min <= s <= scale_max and min(i, j, k) >= 0 and max(i, j, k) < (1 << s):
            out[row] = levels[scale_max - s][k, j, i, 0]
    return out


@st.composite
def cases(draw):
    smin = draw(st.integers(0, 3))
    return dict(scale_min=smin, scale_max=draw(st.integers(smin, min(smin + 2, 5))),
                density=draw(st.sampled_from([0.02, 0.3, 1.0])), clustered=draw(st.booleans()),
                brick=draw(st.sampled_from(BRICK_SIDES)), seed=draw(st.integers(0, 2 ** 31 - 1)))


@settings(max_examples=40, deadline=None)
@given(cases())
def test_bricks_find_the_dense_grids_slots(case):
    cells, _ = random_voxels(case["seed"], case["scale_min"], case["scale_max"], case["density"], case["clustered"])
    smin, smax, b = case["scale_min"], case["scale_max"], case["brick"]
    ix = brick_index(cells, smin, smax, b)
    q = queries(smin, smax)
    got = brick_slot(ix, q[:, 0], q[:, 1:])
    np.testing.assert_array_equal(got, dense_slot(cells, smin, smax, q), err_msg=str(case))
    assert (got > 0).sum() == len(cells)                              # every voxel found exactly once
    assert ix.nbytes == brick_bytes(cells, smin, smax, b)
    assert ix.bricks.max() == len(cells) and ix.top.max() == ix.bricks.size // b ** 3
    best = best_brick(cells, smin, smax)
    assert brick_bytes(cells, smin, smax, best) == min(brick_bytes(cells, smin, smax, s) for s in BRICK_SIDES)


def test_brick_layout_by_hand():
    cells = np.array([[1, 0, 0, 0], [1, 1, 0, 1], [3, 7, 2, 5]], np.uint32)
    ix = brick_index(cells, 1, 3, 2)
    # scale 1: one brick (m = 1); scale 2: 2^3 bricks; scale 3: 4^3 bricks
    assert ix.offsets == (0, 1, 9) and ix.top.size == 1 + 8 + 64
    assert ix.top[0] == 1 and ix.top[1:9].sum() == 0
    assert ix.top[9 + (2 * 4 + 1) * 4 + 3] == 2 and ix.bricks.size == 2 * 8
    assert ix.bricks[0] == 1 and ix.bricks[(1 * 2 + 0) * 2 + 1] == 2     # (i, j, k) = (1, 0, 1)
    assert ix.bricks[8 + (1 * 2 + 0) * 2 + 1] == 3                        # (7, 2, 5) & 1 = (1, 0, 1)
    assert dense_bytes(1, 3) == 4 * (8 + 64 + 512)
    with pytest.raises(ValueError, match=r"brick: must be one of \[2, 4, 8\], got 3"):
        brick_index(cells, 1, 3, 3)


def bricks_bundle(cells, spheres, smin, smax, brick, channels=8):
    g = GraphModule([("slot", 1, "voxel_slot", "uint")])
    g.add("vox", SparseVoxels(cells, spheres, channels, smin, smax, "f32", init_scale=1.0, seed=1,
                              index="bricks", brick=brick), "slot")
    g.output("latent", "vox")
    return g.export("voxels_test")


@parity_settings(10)
@given(cases(), st.booleans())
def test_glsl_bricks_match_numpy(gl, case, small):
    """net_voxel_slot through the driver equals the numpy lookup on every query; with small tables
    the rows wrap and no 2D texture exceeds GL_MAX_TEXTURE_SIZE."""
    smin, smax = case["scale_min"], case["scale_max"]
    cells, spheres = random_voxels(case["seed"], smin, smax, case["density"], case["clustered"])
    bundle = bricks_bundle(cells, spheres, smin, smax, case["brick"])
    ix = brick_index(cells, smin, smax, case["brick"])
    limits = None
    if small:   # the smallest side (>= 16) every table fits in rows
        side = 16
        while side * side < max(2 * len(cells), ix.top.size, ix.bricks.size):
            side *= 2
        limits = {"GL_MAX_TEXTURE_SIZE": side}
    generated = generate(bundle, limits=limits)
    assert all(r.dims == 2 for r in generated.resources)                 # no 3D index texture
    if limits:
        assert all(max(r.data.shape[:2]) <= side for r in generated.resources)
        if side > 16:   # one size down, some table no longer fits: refused, never past the limit
            with pytest.raises(LimitError, match="GL_MAX_TEXTURE_SIZE"):
                generate(bundle, limits={"GL_MAX_TEXTURE_SIZE": side // 2})
    q = queries(smin, smax)
    out = run_sample_pass(gl, "passes/sparse_voxels_test.frag", q.astype(np.float32), attachments=2,
                          chunks={"network": generated.chunk}, generated=generated)
    np.testing.assert_array_equal(out[0][:, 0], brick_slot(ix, q[:, 0], q[:, 1:]).astype(np.float32),
                                  err_msg=str(case))


def test_plan_names_the_brick_tables():
    cells, spheres = random_voxels(3, 2, 4, 0.3, True)
    bundle = bricks_bundle(cells, spheres, 2, 4, 4)
    gen = generate(bundle, prefix="dap")
    names = [r.name for r in gen.resources]
    assert names == ["dap_vox_latents", "dap_vox_spheres", "dap_vox_top", "dap_vox_bricks"]
    for line in ("uniform usampler2D dap_vox_top;", "uniform usampler2D dap_vox_bricks;",
                 "uint dap_voxel_slot(int scale, ivec3 cell) {", "const uint DAP_BRICK_TOP_OFFSET[3]"):
        assert line in gen.chunk, line
    assert "usampler3D" not in gen.chunk
    ix = brick_index(cells, 2, 4, 4)
    top, brk = gen.resources[2:]
    assert top.data.size >= ix.top.size and brk.data.size >= ix.bricks.size
    np.testing.assert_array_equal(top.data.reshape(-1)[:ix.top.size], ix.top)
    np.testing.assert_array_equal(brk.data.reshape(-1)[:ix.bricks.size], ix.bricks)


@settings(max_examples=15, deadline=None)
@given(cases())
def test_torch_march_lookups_agree(case):
    smin, smax = case["scale_min"], case["scale_max"]
    cells, _ = random_voxels(case["seed"], smin, smax, case["density"], case["clustered"])
    dense = march.INDEX_LOOKUPS["dense"](cells, smin, smax, case["brick"])
    bricks = march.INDEX_LOOKUPS["bricks"](cells, smin, smax, case["brick"])
    for s in range(smin, smax + 1):
        n = 1 << s
        k, j, i = np.meshgrid(*[np.arange(n)] * 3, indexing="ij")
        c = torch.from_numpy(np.column_stack([i.ravel(), j.ravel(), k.ravel()]).astype(np.int64))
        assert torch.equal(dense[s](c), bricks[s](c)), (s, case)


@pytest.mark.skipif(not GROVE.is_dir(), reason="no shipped grove asset")
def test_the_shipped_grove_is_on_bricks_and_reads_as_dense_without_them():
    bundle = load(GROVE)
    node = bundle.node("vox")
    cells = bundle.tensor(node, "cells")
    smin, smax = node.params["scale_min"], node.params["scale_max"]
    b = node.params["brick"]
    assert node.params["index"] == "bricks" and b == best_brick(cells, smin, smax)
    ix = brick_index(cells, smin, smax, b)
    np.testing.assert_array_equal(brick_slot(ix, cells[:, 0], cells[:, 1:]), np.arange(1, len(cells) + 1))
    mem = memory.memory_report(bundle)
    assert mem["index"] == "bricks" and mem["brick"] == b and mem["index_bytes"] == ix.nbytes
    assert mem["dense_index_bytes"] == 9586688 and ix.nbytes < mem["dense_index_bytes"] / 10
    assert int(cells[-1, 0]) == smax
    del node.params["index"], node.params["brick"]
    mem = memory.memory_report(bundle)
    assert mem["index"] == "dense" and mem["index_bytes"] == mem["dense_index_bytes"] == 9586688


@pytest.mark.parametrize("version", ["330", "450", "es300"])
def test_bricks_chunk_passes_glslang(tmp_path, version):
    """The bricks index's functions (usampler2D tables, a const offset array) through the test pass
    with the reference compiler, every target (ES 3.00 has no default precision for usampler2D)."""
    import shutil
    import subprocess

    from inshade.shaders import assemble

    assert shutil.which("glslangValidator"), "glslangValidator not found on PATH: install glslang-tools"
    cells, spheres = random_voxels(4, 0, 3, 0.3, True)
    generated = generate(bricks_bundle(cells, spheres, 0, 3, 2), target=version)
    path = assemble("passes/sparse_voxels_test.frag", version=version,
                    chunks={"network": generated.chunk}).write(tmp_path, "frag")
    result = subprocess.run(["glslangValidator", str(path)], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout
