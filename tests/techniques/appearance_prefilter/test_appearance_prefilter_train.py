"""appearance_prefilter's decoders and trainer (techniques/appearance_prefilter/model.py, train.py,
memory.py): the graph's shape and rules on synthetic contract arrays, the loss (Eq. 19) against a
direct formula, the raw lanes never trained, then the quick preset end to end (real scene, voxels
and bake: seconds) -- loss decreases, the asset's bundle loads, its torch forward equals the trained
module's, and its generated GLSL equals torch under the repo's 1e-5 rule through the real driver.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from inshade.bundle import load
from inshade.codegen import generate
from inshade.codegen.voxel_index import best_brick, brick_index
from inshade.models import GraphModule
from inshade.techniques.appearance_prefilter import memory, model, train

from parity import assert_parity, glsl_eval, torch_reference, unit_directions

TRAINED = Path(__file__).resolve().parents[3] / "trained"


# --- synthetic contract arrays ------------------------------------------------------------------

def synthetic_data(n: int = 40, views: int = 4, mask: int = 4, bins=(2, 4), seed: int = 0) -> dict:
    """The contract's per-voxel arrays for n voxels at scales 1..2 (random but well-formed): some
    views see nothing (coverage all zero, albedo and phase 0)."""
    rng = np.random.default_rng(seed)
    cells = []
    for s in (1, 2):
        m = 1 << s
        kji = np.argwhere(rng.random((m, m, m)) < 0.6)
        cells.append(np.column_stack([np.full(len(kji), s), kji[:, 2], kji[:, 1], kji[:, 0]]))
    cells = np.concatenate(cells)[:n].astype(np.uint32)
    n = len(cells)
    size = 0.5 ** cells[:, 0].astype(np.float64)
    spheres = np.column_stack([(cells[:, 1:] + 0.5) * size[:, None], 0.6 * size]).astype(np.float32)
    b = bins[0] * bins[1]
    hit = rng.random((n, views)) < 0.8
    coverage = rng.random((n, views, mask, mask)).astype(np.float32) * hit[..., None, None]
    w = unit_directions(seed, n * views).reshape(n, views, 3)
    light = unit_directions(seed + 1, n * views * b).reshape(n, views, b, 3)
    return {"cells": cells, "spheres": spheres, "views": w, "coverage": coverage,
            "albedo": (rng.random((n, views, 3)) * hit[..., None]).astype(np.float32),
            "light_local": light, "phase": (rng.random((n, views, b)) * 0.3 * hit[..., None]).astype(np.float32)}


def test_raw_features_and_compression():
    data = synthetic_data()
    raw = model.raw_features(data)
    hit = (data["coverage"].reshape(*data["coverage"].shape[:2], -1) > 0).any(-1)
    v = 3
    want_albedo = data["albedo"][v][hit[v]].mean(0)
    want_phase = math.log1p(2.0 * data["phase"][v][hit[v]].mean()) / math.log1p(2.0)
    np.testing.assert_allclose(raw[v], [*want_albedo, want_phase], rtol=1e-6)
    assert model.compress(np.float32(1.0)) == pytest.approx(1.0) and model.compress(np.float32(0.0)) == 0.0
    empty = dict(data, coverage=np.zeros_like(data["coverage"]))
    assert (model.raw_features(empty) == 0).all()


def test_graph_inputs_outputs_and_nodes():
    data = synthetic_data()
    g = model.build_decoders(data, data["cells"], data["spheres"], mask=4, bins=8)
    assert [(n, d) for n, d, _ in g.inputs] == [("slot", 1), ("view", 3), ("light", 3)]
    assert g.input_dtypes["slot"] == "uint"
    assert [o[0] for o in g.outputs] == list(model.OUTPUTS)
    assert [g.dim(o[1]) for o in g.outputs] == [16, 3, 1, 8]
    assert list(g.nodes)[0] == "vox" and g.nodes["vox"].type == "sparse_voxels"
    assert sum(1 for c in g.nodes.values() if c.type == "add") == 9          # 3 decoders x 3 residual blocks
    raw = g.nodes["vox"].latents.detach()[:, 28:]
    np.testing.assert_array_equal(raw.numpy(), model.raw_features(data))     # fp32 here, rounded in forward
    x = torch.cat([torch.arange(5.0)[:, None], torch.from_numpy(data["views"][:5, 0]),
                   torch.from_numpy(data["light_local"][:5, 0, 0])], 1)
    with torch.no_grad():
        out = model.split_outputs(g(x), 4, 8)
    assert ((out["coverage"] > 0) & (out["coverage"] < 1)).all()
    with torch.no_grad():   # the slice head never sees the light
        x2 = x.clone()
        x2[:, 4:] = torch.from_numpy(data["light_local"][:5, 1, 3])
        out2 = model.split_outputs(g(x2), 4, 8)
    torch.testing.assert_close(out2["slice"], out["slice"], rtol=0, atol=0)
    assert not torch.equal(out2["phase"], out["phase"])
    with pytest.raises(ValueError, match="latent \\+ raw: 27 \\+ 4 must be a multiple of 4"):
        model.build_decoders(data, data["cells"], data["spheres"], latent=27)
    with pytest.raises(ValueError, match="voxels: raw features of shape \\[3, 4\\]"):
        model.build_decoders(np.zeros((3, 4)), data["cells"], data["spheres"])


def test_xavier_normal_init():
    data = synthetic_data()
    g = model.build_decoders(None, data["cells"], data["spheres"], width=64, mask=4, bins=8, seed=3)
    w = g.nodes["cov_r0d0"].linear.weight.detach()
    assert abs(float(w.std()) - math.sqrt(2.0 / 128)) < 0.01
    assert float(g.nodes["cov_r0d0"].linear.bias.detach().abs().max()) == 0.0
    assert float(g.nodes["vox"].latents.detach()[:, 28:].abs().max()) == 0.0        # no data: raw lanes zero


def test_loss_is_eq19():
    torch.manual_seed(0)
    n, m2, b = 6, 16, 8
    cov = torch.rand(n, m2)
    cov[2] = 0.0                                          # an empty view: only coverage counts
    pred = {"coverage": torch.rand(n, m2), "albedo": torch.rand(n, 3), "phase": torch.randn(n) * 0.1,
            "slice": torch.rand(n, b)}
    alb, ph, bins = torch.rand(n, 3), torch.rand(n) * 0.2, torch.rand(n, b) * 0.2
    terms = model.losses(pred, cov, alb, ph, bins)
    keep = torch.tensor([1, 1, 0, 1, 1, 1], dtype=torch.bool)
    rel = (pred["phase"] - ph).square() / (pred["phase"].abs() + 0.01).square()
    torch.testing.assert_close(terms["coverage"], (pred["coverage"] - cov).square().mean())
    torch.testing.assert_close(terms["phase"], rel[keep].mean())
    torch.testing.assert_close(terms["albedo"], (pred["albedo"] - alb).abs().mean(-1)[keep].mean())
    slice_err = (pred["slice"] - bins * (4 * math.pi / b)).square().mean(-1)
    torch.testing.assert_close(terms["slice"], slice_err[keep].mean())
    pred["phase"].requires_grad_(True)
    model.losses(pred, cov, alb, ph, bins)["phase"].backward()
    g = pred["phase"].grad                                # the denominator is detached
    want = 2 * (pred["phase"] - ph).detach() / (pred["phase"].detach().abs() + 0.01).square() * keep / keep.sum()
    torch.testing.assert_close(g, want)


def test_raw_lanes_are_never_trained():
    data = synthetic_data()
    settings = dict(train.preset_settings("quick"), scales=[1, 2], steps=20, batch=64, latent=12)
    graph, history = train.fit(data, settings, device="cpu", progress=False)
    lat = graph.nodes["vox"].latents.detach()
    np.testing.assert_array_equal(lat[:, 12:].numpy(), model.raw_features(data))
    init = model.build_decoders(data, data["cells"], data["spheres"], latent=12, mask=4, bins=8)
    assert not torch.equal(lat[:, :12], init.nodes["vox"].latents.detach()[:, :12])
    assert len(history) == 2 and history[-1]["step"] == 19
    # each decoder's first layer reads its own latent lanes only (coverage 5 | albedo 1 | phase 6 of 12,
    # raw: albedo 3 to albedo, T(phase) to phase), zero elsewhere after training too
    assert model.latent_split(12) == (5, 1, 6)
    for name, lanes in (("cov_in", range(0, 5)), ("alb_in", [5, 12, 13, 14]), ("ph_in", [*range(6, 12), 15])):
        w = graph.nodes[name].linear.weight.detach()[:, :16]
        read = (w != 0).any(0).nonzero().flatten().tolist()
        assert read == list(lanes), (name, read)


def test_phase_loss_never_reaches_the_coverage_latent():
    data = synthetic_data()
    g = model.build_decoders(data, data["cells"], data["spheres"], mask=4, bins=8)
    x = torch.cat([torch.arange(8.0)[:, None], torch.from_numpy(data["views"][:8, 0]),
                   torch.from_numpy(data["light_local"][:8, 0, 0])], 1)
    out = model.split_outputs(g(x), 4, 8)
    (out["phase"].sum() + out["slice"].sum()).backward()
    grad = g.nodes["vox"].latents.grad[:8]
    n_cov, n_alb, n_ph = model.latent_split(28)
    assert (grad[:, :n_cov + n_alb] == 0).all() and (grad[:, n_cov + n_alb:28] != 0).any()
    assert (grad[:, 28:] == 0).all()                              # raw lanes: never


# --- the quick preset end to end ------------------------------------------------------------------

@pytest.fixture(scope="module")
def quick_asset(tmp_path_factory):
    out = tmp_path_factory.mktemp("dap") / "appearance_prefilter_slabs"
    cache = tmp_path_factory.mktemp("cache")
    assert train.main(["--preset", "quick", "--out", str(out), "--cache", str(cache), "--device", "cpu"]) == 0
    return out


def test_quick_training_writes_the_asset(quick_asset):
    files = sorted(p.name for p in quick_asset.iterdir())
    assert files == ["bundle.json", "metrics.json", "reference.exr", "scene.json", "weights.safetensors"]
    m = json.loads((quick_asset / "metrics.json").read_text())
    assert m["preset"] == "quick" and m["settings"] == train.preset_settings("quick")
    first, last = m["history"][0], m["history"][-1]
    assert last["total"] < 0.6 * first["total"], (first, last)
    assert last["coverage"] < first["coverage"] and last["albedo"] < first["albedo"]
    assert m["voxels"] == sum(m["voxels_per_scale"].values()) and set(m["voxels_per_scale"]) == {"2", "3"}
    scene = json.loads((quick_asset / "scene.json").read_text())
    assert scene["program"] == "passes/appearance_prefilter.frag"
    assert scene["networks"] == [{"bundle": ".", "prefix": "dap"}]
    assert scene["reference"] == {"image": "reference.exr", "colour": "linear", "space": "screen"}


def test_bench_measures_the_quick_asset_against_the_ray_traced_truth(quick_asset, tmp_path, capsys):
    """`inshade bench appearance_prefilter` on the quick asset at one scale: every method measured
    against the reference, the memory and speed rows, JSON + markdown + plot."""
    from inshade.techniques.appearance_prefilter import bench
    from inshade.techniques.appearance_prefilter import hidden_occlusion as bench_hidden

    out = tmp_path / "bench"
    assert bench.main(["--assets", str(quick_asset), "--scales", "3", "--spp", "4", "--rounds", "1",
                       "--out", str(out)]) == 0
    r = json.loads((out / "appearance_prefilter.json").read_text())
    (row,) = r["assets"][quick_asset.name]["rows"]
    assert row["scale"] == 3 and row["voxels"] == json.loads((quick_asset / "metrics.json").read_text())["voxels_per_scale"]["3"]
    for method in ("prefiltered", "decimated", "1spp"):
        assert math.isfinite(row[method]["mse"]) and row[method]["mse"] >= 0.0
    assert row["prefiltered"]["mse"] > 0.0   # a prefiltered image is not the ray-traced one
    assert row["equal_quality"]["spp"] in bench.EQ_SPP and row["prefiltered_ms"] > 0.0
    assert r["machine"]["gl_renderer"]
    md = (out / "appearance_prefilter.md").read_text()
    assert "GL_RENDERER" in md and "### Speed (same run)" in md
    assert (out / "appearance_prefilter.png").stat().st_size > 0
    # the quick scene is the slabs: masks against mean alpha, at the scene's view and along the slabs
    hidden = r["assets"][quick_asset.name]["hidden_occlusion"]
    assert [h["view"] for h in hidden] == [label for label, _ in bench_hidden.VIEWS]
    for h in hidden:
        assert h["scale"] == 3 and 0.0 < h["mse_masks"] != h["mse_mean_alpha"] > 0.0
    assert "### Hidden occlusion" in md
    assert bench.main(["--assets", str(quick_asset), "--scales", "9", "--out", str(out)]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1].startswith("inshade: error: --scales: 9 is outside")


def test_quick_bundle_loads_and_matches_the_trained_module(quick_asset):
    bundle = load(quick_asset)
    assert bundle.kind == "appearance_prefilter"
    assert bundle.meta["render"] == {"mask": 4, "bins": 8, "bins_theta": 2, "bins_phi": 4}
    assert bundle.converted.get("vox.latents") == "float16"        # stored F16
    assert [p.name for p in bundle.outputs] == list(model.OUTPUTS) and bundle.out_dim == 28
    m = json.loads((quick_asset / "metrics.json").read_text())
    mem = memory.memory_report(bundle)
    assert m["memory"] == mem
    n = mem["voxels"]
    node = bundle.node("vox")
    cells, brick = bundle.tensor(node, "cells"), node.params["brick"]
    assert node.params["index"] == "bricks" and brick == best_brick(cells, 2, 3)
    index = brick_index(cells, 2, 3, brick).nbytes
    assert mem["latent_bytes_per_voxel"] == 64 and mem["index"] == "bricks" and mem["index_bytes"] == index
    assert mem["dense_index_bytes"] == 4 * (64 + 512) and index < mem["dense_index_bytes"]
    assert mem["bytes_per_voxel"] == pytest.approx(64 + 16 + index / n, abs=0.01)
    # the asset's torch forward equals the module rebuilt from the same tensors, on samples of the data
    graph = GraphModule.from_bundle(bundle)
    x = sample_inputs(n, 96, seed=1)
    with torch.no_grad():
        again = GraphModule.from_bundle(load(quick_asset))(torch.from_numpy(x)).numpy()
        np.testing.assert_array_equal(graph(torch.from_numpy(x)).numpy(), again)


def sample_inputs(n: int, k: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    slots = rng.integers(0, n, k).astype(np.float32)
    return np.concatenate([slots[:, None], unit_directions(seed, k), unit_directions(seed + 1, k)], 1)


def test_trained_module_equals_its_bundle():
    """fit's module (fp32 latents rounded to fp16 in forward) and the exported bundle agree exactly."""
    data = synthetic_data()
    settings = dict(train.preset_settings("quick"), scales=[1, 2], steps=5, batch=32)
    graph, _ = train.fit(data, settings, device="cpu", progress=False)
    bundle = graph.export("appearance_prefilter")
    x = sample_inputs(len(data["cells"]), 64, seed=2)
    with torch.no_grad():
        np.testing.assert_array_equal(torch_reference(bundle, x), graph(torch.from_numpy(x)).numpy())


def test_quick_bundle_glsl_matches_torch(gl, quick_asset):
    """The asset's decoders as generated GLSL (prefix net, evaluate pass; 28 outputs = 7 draw buffers)
    against torch under the 1e-5 rule, at every slot and random view/light directions. Weights in a
    texture: the inline literals ``auto`` picks here compile ~3x slower on a cold llvmpipe (the dense
    storage modes have their own parity tests; new here are sparse_voxels, add and their wiring)."""
    bundle = load(quick_asset)
    n = bundle.node("vox").params["voxels"]
    limit = gl.info["GL_MAX_DRAW_BUFFERS"]
    assert -(-bundle.out_dim // 4) <= limit, f"{bundle.out_dim} outputs need more than {limit} draw buffers"
    x = sample_inputs(n, 2 * n, seed=3)
    x[:n, 0] = np.arange(n)
    assert_parity(glsl_eval(gl, bundle, x, storage="texture"), torch_reference(bundle, x),
                  what="appearance_prefilter quick")
    chunk = generate(bundle).chunk
    assert "uniform usampler2D net_vox_top;" in chunk and "usampler3D" not in chunk   # the bricks index


@pytest.mark.parametrize("name", ["grove", "forest", "slabs"])
def test_shipped_decoders_glsl_match_torch(gl, name):
    """Each shipped asset's decoders under the 1e-5 rule at every slot, random view/light directions;
    the 100 outputs read in groups of 32 lanes (a ``select`` node each), within 8 draw buffers."""
    import copy

    from inshade.bundle import Bundle

    bundle = load(TRAINED / f"appearance_prefilter_{name}")
    n = bundle.node("vox").params["voxels"]
    x = sample_inputs(n, n, seed=4)
    x[:, 0] = np.arange(n)
    ref = torch_reference(bundle, x)
    lanes = 4 * min(8, gl.info["GL_MAX_DRAW_BUFFERS"])
    for start in range(0, bundle.out_dim, lanes):
        pick = list(range(start, min(bundle.out_dim, start + lanes)))
        meta = copy.deepcopy(bundle.meta)
        meta.pop("render", None)
        meta["nodes"].append({"id": "pick", "type": "select", "inputs": [o["node"] for o in meta["outputs"]],
                              "params": {"lanes": pick}})
        meta["outputs"] = [{"name": "lanes", "node": "pick", "semantic": "generic"}]
        assert_parity(glsl_eval(gl, Bundle(meta, bundle.tensors), x, storage="texture"), ref[:, pick],
                      what=f"appearance_prefilter_{name} outputs {pick[0]}..{pick[-1]}")


def test_bad_options_are_one_error_line(tmp_path, capsys):
    for args, message in ((["--latent", "27"], "--latent: 27 + 4 raw lanes must be a multiple of 4, at most 64"),
                          (["--scales", "3", "2"], "--scales: need 0 <= S_MIN <= S_MAX <= 9, got 3 2"),
                          (["--mask", "0"], "--mask: must be >= 1, got 0"),
                          (["--lr", "-1"], "--lr: must be > 0, got -1.0"),
                          (["--weight-decay", "-1"], "--weight-decay: must be >= 0, got -1.0")):
        assert train.main(["--preset", "quick", "--out", str(tmp_path / "x"), *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [f"inshade: error: {message}"]
    assert not (tmp_path / "x").exists()



def test_mean_mask_averages_only_the_coverage_lanes():
    """hidden_occlusion.MeanMask: each row's first mask² lanes become their mean, the rest are the
    decoder's own."""
    import torch

    from inshade.techniques.appearance_prefilter.hidden_occlusion import MeanMask

    x = torch.randn(5, 20, generator=torch.Generator().manual_seed(0))
    y = MeanMask(torch.nn.Identity(), 16)(x)
    assert torch.equal(y[:, 16:], x[:, 16:])
    assert torch.allclose(y[:, :16], x[:, :16].mean(-1, keepdim=True).expand(5, 16))
