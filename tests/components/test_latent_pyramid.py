"""Latent texture pyramid (models/latent_pyramid.py, components/latent_pyramid/emit.py): GLSL parity on
both paths, an independent numpy reference for the twin, training (gradients to the texels,
mixed levels in one batch), fp16 precision, the plan, and bad bundles refused at load and by
the CLI.

Exact path ("exact" = 4 texelFetch + fp32 mix): the rule of tests/parity.py, f32 and f16 latents
(the twin rounds f16 texels to fp16, the texture holds the same values).

Fast path ("fast" = textureLod at the integer level, hardware bilinear). Documented bound:

    |fast - exact| <= 2 * 2^-8 * D  +  1e-5 * max(1, |exact|)

with D the largest difference between two texels adjacent (repeat wrap included) in the level
read. Why: hardware filtering quantises each axis' fraction to as few as 8 bits (error <= 2^-8)
and moving a fraction by e moves a bilinear interpolant by at most e * D, for each of 2 axes
(the same argument as tests/components/test_lookup_array.py). Measured on llvmpipe (float textures, f16 and
f32): |fast - exact| <= 3e-7, i.e. llvmpipe filters float textures with fp32 weights; real GPUs
use 8-bit weights, which is what the bound is written for.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.bundle import BundleError, load
from inshade.codegen import generate
from inshade.components import COMPONENTS, ComponentError, check_node, resolve_params
from inshade.components.latent_pyramid.torch_twin import LatentPyramid
from inshade.components.unorm import decode
from inshade.models import GraphModule

from parity import assert_parity, check_parity, glsl_eval, parity_settings, torch_reference

REPO = Path(__file__).resolve().parents[2]


@st.composite
def pyramid_cases(draw):
    res = draw(st.sampled_from([1, 2, 4, 8, 16]))
    levels = draw(st.integers(1, res.bit_length()))
    return dict(res=res, levels=levels, channels=draw(st.sampled_from([4, 8, 12])),
                precision=draw(st.sampled_from(["f16", "f32", "u8"])), seed=draw(st.integers(0, 2**31 - 1)))


def pyramid_graph(case, scale=1.0) -> GraphModule:
    g = GraphModule([("uvl", 3)])
    g.add("lat", LatentPyramid(case["res"], case["levels"], case["channels"], case["precision"],
                               scale=scale, seed=case["seed"] % 2**31), "uvl")
    g.output("z", "lat")
    return g


def pyramid_inputs(seed, n, res, levels):
    """uv in [-1.5, 2.5] (repeat), levels in [-1.5, levels + 0.5] (floor + clamp); plus texel
    centres, texel edges, integer uv and integer levels at every level."""
    rng = np.random.default_rng(seed)
    x = np.stack([rng.uniform(-1.5, 2.5, n), rng.uniform(-1.5, 2.5, n), rng.uniform(-1.5, levels + 0.5, n)], 1)
    k = n // 4
    lv = rng.integers(0, levels, k)
    side = np.maximum(res >> lv, 1)
    x[:k, 0] = (rng.integers(-side, 2 * side) + 0.5) / side
    x[:k, 1] = rng.integers(-side, 2 * side) / side
    x[:k, 2] = lv
    x[-4:] = [[0, 0, 0], [1, 1, levels - 1], [-1, 0.5, 99], [0.999, 0.001, -5]]
    return x.astype(np.float32)


def level_values(bundle, k: int, node: str = "lat") -> np.ndarray:
    """Level k's values as the shader decodes them (a u8 pyramid's codes through its range)."""
    t = bundle.tensors
    if bundle.node(node).params["precision"] == "u8":
        return decode(t[f"{node}.level{k}"], t[f"{node}.scale"], t[f"{node}.offset"])
    return t[f"{node}.level{k}"]


def numpy_lookup(levels: list[np.ndarray], x: np.ndarray) -> np.ndarray:
    """Independent reference, one query at a time: the convention of the module docstring."""
    out = np.zeros((x.shape[0], levels[0].shape[-1]))
    for r, (u, v, lv) in enumerate(x.astype(np.float64)):
        k = int(min(max(np.floor(lv), 0), len(levels) - 1))
        a = levels[k].astype(np.float64)
        n = a.shape[0]
        tx, ty = u * n - 0.5, v * n - 0.5
        fx, fy = tx - np.floor(tx), ty - np.floor(ty)
        x0, y0 = int(np.floor(tx)) % n, int(np.floor(ty)) % n
        x1, y1 = (x0 + 1) % n, (y0 + 1) % n
        out[r] = ((1 - fy) * ((1 - fx) * a[y0, x0] + fx * a[y0, x1])
                  + fy * ((1 - fx) * a[y1, x0] + fx * a[y1, x1]))
    return out


@given(case=pyramid_cases())
@parity_settings(10)
def test_exact_parity(gl, case):
    bundle = pyramid_graph(case).export("latent")
    x = pyramid_inputs(case["seed"] + 1, 300, case["res"], case["levels"])
    ref = torch_reference(bundle, x)
    assert_parity(ref, numpy_lookup([level_values(bundle, k) for k in range(case["levels"])], x),
                  what="torch twin vs numpy reference")
    check_parity(gl, bundle, x, reference=ref, what=f"latent_pyramid exact {case}")


def _max_adjacent_difference(level: np.ndarray) -> float:
    a = level.astype(np.float64)
    return float(max(np.abs(a - np.roll(a, 1, 0)).max(), np.abs(a - np.roll(a, 1, 1)).max()))


def fast_bound(bundle, x: np.ndarray, exact: np.ndarray) -> np.ndarray:
    """The fast path's bound: 2 * 2^-8 * D (D the largest adjacent texel difference of the level read,
    repeat wrap included: the hardware's 8-bit filter weights) + the parity rule; a u8 pyramid adds one
    code step, scale / 255 (the driver filters unorm8 texels to an 8-bit result)."""
    node = next(n for n in bundle.nodes if n.type == "latent_pyramid")
    levels = node.params["levels"]
    k = np.clip(np.floor(x[:, 2]), 0, levels - 1).astype(int)
    d = np.array([_max_adjacent_difference(level_values(bundle, j, node.id)) for j in range(levels)])[k]
    step = bundle.tensor(node, "scale") / 255.0 if node.params["precision"] == "u8" else 0.0
    return 2 * 2.0 ** -8 * d[:, None] + step + 1e-5 * np.maximum(1.0, np.abs(exact))


@given(case=pyramid_cases())
@parity_settings(6)
def test_fast_path_bound(gl, case):
    bundle = pyramid_graph(case).export("latent")
    x = pyramid_inputs(case["seed"] + 2, 300, case["res"], case["levels"])
    exact = glsl_eval(gl, bundle, x).astype(np.float64)
    fast = glsl_eval(gl, bundle, x, options={"latent_pyramid": {"filter": "fast"}}).astype(np.float64)
    ratio = float((np.abs(fast - exact) / fast_bound(bundle, x, exact)).max())
    assert ratio <= 1.0, f"fast path exceeds 2 * 2^-8 * D (+ a u8 code step + rule): err / bound = {ratio:.3f}, {case}"


def test_plan_rows():
    case = dict(res=16, levels=3, channels=8, precision="f16", seed=0)
    bundle = pyramid_graph(case).export("latent")
    texels = (16 * 16 + 8 * 8 + 4 * 4) * 8
    for mode, fetches in (("exact", 8), ("fast", 2)):
        gen = generate(bundle, options={"latent_pyramid": {"filter": mode}})
        (row,) = gen.plan.rows
        assert (row.fetches, row.texture_bytes, row.params) == (fetches, texels * 2, texels)
        assert [r.levels for r in gen.resources] == [3, 3] and {r.wrap for r in gen.resources} == {"repeat"}
        assert {r.dtype for r in gen.resources} == {"f2"}
    f32 = generate(pyramid_graph(dict(case, precision="f32")).export("latent"))
    assert f32.plan.rows[0].texture_bytes == texels * 4 and {r.dtype for r in f32.resources} == {"f4"}


def test_mixed_levels_and_gradients():
    """One batch over several levels equals per-level batches; the loss's gradient reaches exactly
    the 4 texels of each query's level with the bilinear weights (computed here by hand)."""
    m = LatentPyramid(8, 4, 4, seed=3)
    x = torch.tensor([[0.30, 0.70, 0.0], [0.30, 0.70, 1.7], [0.05, 0.95, 2.2], [0.55, 0.10, 9.0]])
    out = m(x)
    for r in range(4):
        torch.testing.assert_close(out[r], m(x[r:r + 1])[0])
    w = torch.tensor([1.0, -2.0, 0.5, 3.0])
    (out[0] * w).sum().backward()
    g0 = m.texels[0].grad
    # query 0 at level 0 (8x8): t = (0.3 * 8 - 0.5, 0.7 * 8 - 0.5) = (1.9, 5.1)
    fx, fy = 0.9, 0.1
    expect = torch.zeros(8, 8, 4)
    for (yy, xx), wt in {(5, 1): (1 - fx) * (1 - fy), (5, 2): fx * (1 - fy), (6, 1): (1 - fx) * fy,
                         (6, 2): fx * fy}.items():
        expect[yy, xx] = wt * w
    torch.testing.assert_close(g0, expect, atol=1e-5, rtol=1e-5)
    assert all(m.texels[k].grad is None or not m.texels[k].grad.any() for k in (1, 2, 3))
    # a query at the wrap seam reaches texels on both edges (level 3 is 1x1: every tap is texel 0)
    m.zero_grad()
    m(torch.tensor([[0.0, 0.0, 2.0]])).sum().backward()
    g2 = m.texels[2].grad.abs().sum(-1)
    assert set(map(tuple, g2.nonzero().tolist())) == {(0, 0), (0, 1), (1, 0), (1, 1)}
    # a training step moves the texels
    opt = torch.optim.Adam(m.parameters(), lr=0.1)
    before = m.texels[0].detach().clone()
    opt.zero_grad()
    m(x).square().sum().backward()
    opt.step()
    assert not torch.equal(before, m.texels[0].detach())


def test_f16_rounding_and_export():
    arrays = [np.full((2, 2, 4), 0.1, np.float32), np.full((1, 1, 4), 1 / 3, np.float32)]
    m = LatentPyramid.from_arrays(arrays, precision="f16")
    tensors = m.export_tensors()
    assert tensors["level0"].dtype == np.float32
    assert np.array_equal(tensors["level0"], arrays[0].astype(np.float16).astype(np.float32))
    out = m(torch.tensor([[0.25, 0.25, 0.0]]))
    assert float(out[0, 0].detach()) == float(np.float16(0.1))
    # straight-through: the gradient still reaches the fp32 texels
    out.sum().backward()
    assert m.texels[0].grad.abs().sum() > 0
    f32 = LatentPyramid.from_arrays(arrays)
    assert np.array_equal(f32.export_tensors()["level1"], arrays[1])


def test_component_spec():
    p = resolve_params("latent_pyramid", {"resolution": 8, "levels": 4})
    assert p == {"resolution": 8, "levels": 4, "channels": 8, "precision": "f32"}
    assert check_node("latent_pyramid", p, 3) == 8
    shapes = {k: v.shape for k, v in COMPONENTS["latent_pyramid"].tensors(p, 3).items()}
    assert shapes == {"level0": (8, 8, 8), "level1": (4, 4, 8), "level2": (2, 2, 8), "level3": (1, 1, 8)}
    for bad, field in (({"resolution": 12, "levels": 1}, "resolution"), ({"resolution": 8, "levels": 1,
                       "channels": 6}, "channels"), ({"resolution": 8, "levels": 1, "precision": "f8"}, "precision")):
        with pytest.raises(ComponentError, match=field):
            resolve_params("latent_pyramid", bad)
    with pytest.raises(ComponentError, match="levels"):
        check_node("latent_pyramid", resolve_params("latent_pyramid", {"resolution": 8, "levels": 5}), 3)
    with pytest.raises(ComponentError, match="3-wide|cannot take"):
        check_node("latent_pyramid", p, 2)


# --- bad bundles ---------------------------------------------------------------------------------

def _saved(tmp_path, edit_meta=None, edit_tensors=None, precision="f32") -> Path:
    bundle = pyramid_graph(dict(res=8, levels=3, channels=8, precision=precision, seed=1)).export("latent")
    folder = bundle.save(tmp_path / "b")
    if edit_meta or edit_tensors:
        from safetensors.numpy import load_file, save_file
        meta = json.loads((folder / "bundle.json").read_text())
        tensors = load_file(str(folder / "weights.safetensors"))
        if edit_meta:
            edit_meta(meta)
        if edit_tensors:
            edit_tensors(tensors)
        (folder / "bundle.json").write_text(json.dumps(meta))
        save_file(tensors, str(folder / "weights.safetensors"))
    return folder


def _nan(t):
    t["lat.level1"] = t["lat.level1"].copy()
    t["lat.level1"][1, 2, 3] = np.nan


def _not_f16(t):
    t["lat.level0"] = t["lat.level0"].copy()
    t["lat.level0"][0, 0, 0] = np.float32(0.1)


def _set_param(**kv):
    def edit(meta):
        meta["nodes"][0]["params"].update(kv)
    return edit


BAD = {
    "missing level": (None, lambda t: t.pop("lat.level2"), "weights.safetensors", "lat.level2", "missing tensor"),
    "wrong channel count": (None, lambda t: t.update({"lat.level1": np.zeros((4, 4, 6), np.float32)}),
                            "weights.safetensors", "lat.level1", r"shape \[4, 4, 6\] but \[4, 4, 8\]"),
    "non-power-of-two level": (None, lambda t: t.update({"lat.level1": np.zeros((3, 3, 8), np.float32)}),
                               "weights.safetensors", "lat.level1", r"shape \[3, 3, 8\] but \[4, 4, 8\]"),
    "non-power-of-two resolution": (_set_param(resolution=12), None, "bundle.json", "nodes[0].params",
                                    "resolution.* a power of two"),
    "channels not a multiple of 4": (_set_param(channels=6), None, "bundle.json", "nodes[0].params",
                                     "channels.* a multiple of 4"),
    "NaN latent": (None, _nan, "weights.safetensors", "lat.level1", "NaN"),
}


@pytest.mark.parametrize("name", list(BAD))
def test_bad_bundle_refused_at_load(tmp_path, name):
    meta, tensors, file, field, what = BAD[name]
    folder = _saved(tmp_path, meta, tensors)
    with pytest.raises(BundleError, match=what) as e:
        load(folder)
    msg = str(e.value)
    assert str(folder / file) in msg and field in msg, msg


def test_f16_latents_must_be_fp16_representable(tmp_path):
    folder = _saved(tmp_path, None, _not_f16, precision="f16")
    with pytest.raises(BundleError, match=r"lat\.level0: value .* not representable as float16"):
        load(folder)
    assert load(_saved(tmp_path / "ok", precision="f16")).node("lat").params["precision"] == "f16"


def test_cli_refuses_nan_latents(tmp_path):
    folder = _saved(tmp_path, None, _nan)
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run([sys.executable, "-m", "inshade.cli", "-q", "info", str(folder)], capture_output=True,
                          text=True, env=env, timeout=120, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("inshade: error:"), proc.stderr
    assert "lat.level1" in lines[0] and "weights.safetensors" in lines[0] and "NaN" in lines[0]
