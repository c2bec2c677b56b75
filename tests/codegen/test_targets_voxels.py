"""sparse_voxels (deep appearance prefiltering's voxel latents) on every shading language beside OpenGL's
GLSL (WGSL, Vulkan GLSL, HLSL, Slang: SPIR-V on wgpu over this machine's Vulkan device), held to the rule
of its GL test (tests/components/test_sparse_voxels.py: exact, texel reads of the very values torch
indexes), for both cell -> slot indexes (dense, bricks), and the shipped appearance_prefilter bundles on
every target.

A renderer marching the voxels calls the network's P_voxel_slot / P_voxel_sphere beside P_eval, so the
check does too: a small host function per language (as the GL test's sample pass does) wraps the
network (prefix ``vox``) as ``net_eval`` with one more input block, the query (scale, i, j, k), and two
more output blocks: (vox_voxel_slot(scale, cell), VOX_SCALE_MIN, VOX_SCALE_MAX, VOX_VOXELS) and
vox_voxel_sphere(max(i, 0)). That also makes every table a used binding of the compute pipeline."""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from inshade.bundle import load
from inshade.codegen import generate
from inshade.codegen.voxel_index import BRICK_SIDES, brick_index
from inshade.components.sparse_voxels.torch_twin import SparseVoxels
from inshade.models import GraphModule
from inshade.runtime.compute import TARGETS, run_target
from parity import assert_parity, parity_settings, torch_reference, unit_directions
from test_sparse_voxels import grid_queries, numpy_slot, random_voxels, voxel_cases

REPO = Path(__file__).resolve().parents[2]
SHIPPED = sorted((REPO / "trained").glob("appearance_prefilter_*/bundle.json"))

pytestmark = pytest.mark.usefixtures("one_torch_thread")

# GLSL and HLSL alike, but for the names of two types (vec4, ivec3)
_C_HOST = """
#define NET_IN_BLOCKS (VOX_IN_BLOCKS + 1)
#define NET_OUT_BLOCKS (VOX_OUT_BLOCKS + 2)
{uint_define}
void net_eval({uint_param}in {vec4} x[NET_IN_BLOCKS], out {vec4} y[NET_OUT_BLOCKS]) {{
    {vec4} a[VOX_IN_BLOCKS];
    {vec4} b[VOX_OUT_BLOCKS];
    for (int k = 0; k < VOX_IN_BLOCKS; ++k) a[k] = x[k];
    vox_eval({uint_arg}a, b);
    for (int j = 0; j < VOX_OUT_BLOCKS; ++j) y[j] = b[j];
    {vec4} q = x[VOX_IN_BLOCKS];
    y[VOX_OUT_BLOCKS] = {vec4}(float(vox_voxel_slot(int(q.x), {ivec3}(q.yzw))), float(VOX_SCALE_MIN),
                               float(VOX_SCALE_MAX), float(VOX_VOXELS));
    y[VOX_OUT_BLOCKS + 1] = vox_voxel_sphere(uint(max(q.y, 0.0)));
}}
"""
_GLSL_HOST = _C_HOST.replace("{vec4}", "vec4").replace("{ivec3}", "ivec3")
_HLSL_HOST = _C_HOST.replace("{vec4}", "float4").replace("{ivec3}", "int3")

_WGSL_HOST = """
const NET_IN_BLOCKS: i32 = VOX_IN_BLOCKS + 1;
const NET_OUT_BLOCKS: i32 = VOX_OUT_BLOCKS + 2;
{uint_define}
fn net_eval({uint_param}x_in: array<vec4<f32>, NET_IN_BLOCKS>) -> array<vec4<f32>, NET_OUT_BLOCKS> {{
    var x = x_in;
    var a: array<vec4<f32>, VOX_IN_BLOCKS>;
    for (var k: i32 = 0; k < VOX_IN_BLOCKS; k++) {{ a[k] = x[k]; }}
    var b = vox_eval({uint_arg}a);
    var y: array<vec4<f32>, NET_OUT_BLOCKS>;
    for (var k: i32 = 0; k < VOX_OUT_BLOCKS; k++) {{ y[k] = b[k]; }}
    let q = x[VOX_IN_BLOCKS];
    y[VOX_OUT_BLOCKS] = vec4<f32>(f32(vox_voxel_slot(i32(q.x), vec3<i32>(q.yzw))), f32(VOX_SCALE_MIN),
                                  f32(VOX_SCALE_MAX), f32(VOX_VOXELS));
    y[VOX_OUT_BLOCKS + 1] = vox_voxel_sphere(u32(max(q.y, 0.0)));
    return y;
}}
"""

# target -> (host source, its uint-input pieces: define, parameter, argument)
HOSTS = {
    "vulkan": (_GLSL_HOST, ("#define NET_IN_UINT_BLOCKS VOX_IN_UINT_BLOCKS", "in uvec4 xu[NET_IN_UINT_BLOCKS], ",
                            "xu, ")),
    "hlsl": (_HLSL_HOST, ("#define NET_IN_UINT_BLOCKS VOX_IN_UINT_BLOCKS", "in uint4 xu[NET_IN_UINT_BLOCKS], ",
                          "xu, ")),
    "wgsl": (_WGSL_HOST, ("const NET_IN_UINT_BLOCKS: i32 = VOX_IN_UINT_BLOCKS;",
                          "xu: array<vec4<u32>, NET_IN_UINT_BLOCKS>, ", "xu, ")),
}
HOSTS["slang"] = HOSTS["hlsl"]


def host(bundle, target, **options):
    """The network (prefix vox) with the host function calling it and its voxel functions, as net_eval."""
    gen = generate(bundle, target=target, prefix="vox", **options)
    text, uint_pieces = HOSTS[target]
    pieces = uint_pieces if gen.uint_lanes else ("", "", "")
    chunk = gen.chunk + text.format(**dict(zip(("uint_define", "uint_param", "uint_arg"), pieces)))
    in_dim = 4 * gen.in_blocks + len(gen.uint_lanes) + 4
    return dataclasses.replace(gen, chunk=chunk, prefix="net", function="net_eval", in_dim=in_dim,
                               out_dim=4 * gen.out_blocks + 8), gen


def run_host(bundle, x, q, target, **options):
    """(network outputs, slot + 1 per query, (scale_min, scale_max, voxels), sphere per query's i)."""
    wrapped, gen = host(bundle, target, **options)
    pad = np.zeros((len(x), 4 * gen.in_blocks - gen.float_in_dim), np.float32)
    out = run_target(wrapped, np.concatenate([x, pad, q], 1), target)[0]
    o = 4 * gen.out_blocks
    return out[:, :gen.out_dim], out[:, o], out[0, o + 1:o + 4], out[:, o + 4:o + 8]


def assert_voxel_functions(slot, consts, sphere, cells, spheres, q, smin, smax, what):
    """The GL test's rule for P_voxel_slot / P_voxel_sphere: exact."""
    np.testing.assert_array_equal(slot, numpy_slot(cells, q), err_msg=what)
    np.testing.assert_array_equal(consts, [smin, smax, len(cells)], err_msg=what)
    np.testing.assert_array_equal(sphere, spheres[np.clip(q[:, 1].astype(np.int64), 0, len(cells) - 1)],
                                  err_msg=what)


@st.composite
def index_cases(draw):
    return dict(draw(voxel_cases()), index=draw(st.sampled_from(["dense", "bricks"])),
                brick=draw(st.sampled_from(BRICK_SIDES)))


def small_limits(case, cells) -> dict | None:
    """For case["small"]: the smallest GL_MAX_TEXTURE_SIZE (>= 16) every table fits in rows, so the
    tables wrap into many; else None (each target's guaranteed limits)."""
    if not case["small"]:
        return None
    texels = [len(cells) * case["channels"] // 4]
    if case["index"] == "bricks":
        ix = brick_index(cells, case["scale_min"], case["scale_max"], case["brick"])
        texels += [ix.top.size, ix.bricks.size]
    side = 16
    while side * side < max(texels):
        side *= 2
    return {"GL_MAX_TEXTURE_SIZE": side}


@pytest.mark.parametrize("target", TARGETS)
@parity_settings(max_examples=6)
@given(case=index_cases())
def test_voxel_parity(target, case):
    """Random voxels, channels, precisions, slot kinds (uint or exact float) and both indexes, tables in
    wide rows or wrapped into many: the latent rows equal torch's, and the voxel functions over every
    cell of every scale (and outside them) equal numpy, exactly."""
    smin, smax = case["scale_min"], case["scale_max"]
    cells, spheres = random_voxels(case["seed"], smin, smax, case["density"])
    g = GraphModule([("slot", 1, "voxel_slot", "uint")] if case["uint"] else [("slot", 1)])
    g.add("vox", SparseVoxels(cells, spheres, case["channels"], smin, smax, case["precision"], init_scale=3.0,
                              seed=case["seed"], index=case["index"], brick=case["brick"]), "slot")
    g.output("latent", "vox")
    bundle = g.export("voxels_test")
    q = grid_queries(smin, smax)
    x = np.random.default_rng(case["seed"]).integers(0, len(cells), (len(q), 1)).astype(np.float32)
    out, slot, consts, sphere = run_host(bundle, x, q, target, limits=small_limits(case, cells))
    if case["precision"] == "u8":   # the decode's product and sum may round differently (e.g. fused)
        assert_parity(out, torch_reference(bundle, x), what=f"{target} {case}")
    else:
        np.testing.assert_array_equal(out, torch_reference(bundle, x), err_msg=f"{target} {case}")
    assert_voxel_functions(slot, consts, sphere, cells, spheres, q, smin, smax, f"{target} {case}")


def shipped_queries(cells: np.ndarray, smin: int, smax: int, n: int, seed: int) -> np.ndarray:
    """(scale, i, j, k): half the cells of random voxels, half random cells of random scales (mostly
    empty), the last few outside the grid or the scale range."""
    rng = np.random.default_rng(seed)
    found = cells[rng.integers(0, len(cells), n // 2)].astype(np.int64)
    scale = rng.integers(smin, smax + 1, n - n // 2)
    anywhere = np.column_stack([scale, rng.integers(0, 1 << scale[:, None], (len(scale), 3))])
    q = np.concatenate([found, anywhere]).astype(np.float32)
    q[-4:] = [[smin - 1, 0, 0, 0], [smax + 1, 0, 0, 0], [smax, -1, 0, 0], [smin, 0, 1 << smin, 0]]
    return q


# the Slang compiler takes ~30 s over each shipped decoder's literals here: one of them unless INSHADE_SLOW=1
SHIPPED_CASES = [(t, p) for p in SHIPPED for t in TARGETS
                 if t != "slang" or p == SHIPPED[0] or os.environ.get("INSHADE_SLOW")]


@pytest.mark.parametrize("target, path", SHIPPED_CASES, ids=lambda v: getattr(getattr(v, "parent", None), "name", v))
def test_the_shipped_prefilter_networks_on_every_target(target, path):
    """Decoders within the parity rule, the voxel lookups exact, 128 points."""
    bundle = load(path)
    node = next(n for n in bundle.nodes if n.type == "sparse_voxels")
    p = node.params
    cells, spheres = (bundle.tensor(node, s) for s in ("cells", "spheres"))
    n = 128
    rng = np.random.default_rng(7)
    x = np.concatenate([rng.integers(0, p["voxels"], (n, 1)).astype(np.float32), unit_directions(1, n),
                        unit_directions(2, n)], 1).astype(np.float32)
    q = shipped_queries(cells, p["scale_min"], p["scale_max"], n, 3)
    out, slot, consts, sphere = run_host(bundle, x, q, target)
    assert_parity(out, torch_reference(bundle, x), what=f"{target} {path.parent.name}")
    assert_voxel_functions(slot, consts, sphere, cells, spheres, q, p["scale_min"], p["scale_max"],
                           f"{target} {path.parent.name}")


def test_the_voxel_functions_have_one_name_in_every_language():
    """What a marching renderer calls, by the same names everywhere; the integer index as each
    language spells an R32UI 3D texture."""
    cells, spheres = random_voxels(1, 1, 2, 0.3)
    g = GraphModule([("slot", 1, "voxel_slot", "uint")])
    g.add("vox", SparseVoxels(cells, spheres, 8, 1, 2, "f32"), "slot")
    g.output("latent", "vox")
    bundle = g.export("voxels_test")
    spelled = {"330": ("uint dap_voxel_slot(int scale, ivec3 cell) {", "uniform usampler3D dap_vox_grid;"),
               "vulkan": ("uint dap_voxel_slot(int scale, ivec3 cell) {", "uniform utexture3D dap_vox_grid;"),
               "wgsl": ("fn dap_voxel_slot(scale: i32, cell: vec3<i32>) -> u32 {",
                        "var dap_vox_grid: texture_3d<u32>;"),
               "hlsl": ("uint dap_voxel_slot(int scale, int3 cell) {", "Texture3D<uint4> dap_vox_grid :"),
               "slang": ("public uint dap_voxel_slot(int scale, int3 cell) {", "Texture3D<uint4> dap_vox_grid :")}
    for target, texts in spelled.items():
        chunk = generate(bundle, target=target, prefix="dap").chunk
        for text in (*texts, "dap_voxel_sphere(", "DAP_SCALE_MIN", "DAP_SCALE_MAX", "DAP_VOXELS"):
            assert text in chunk, (target, text)
