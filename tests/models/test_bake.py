"""The sharded bake executor (models/bake.py) and PRT's transfer bake on it (techniques/prt/transfer.py),
plus `inshade train prt`'s presets (techniques/prt/train.py).

Bit-identity is the contract: a sharded dataset equals one unsharded estimate over all points, and
the process pool and Ray (a local cluster, ``ray.init(num_cpus=2)``) give the in-process bytes.
"""
from __future__ import annotations

import json
import shlex
from pathlib import Path

import numpy as np
import pytest
import torch

from inshade.models import bake
from inshade.models.bake import BakeError, Executor, Shard, run_shards
from inshade.models.sdf import SdfModule
from inshade.geometry.sdf import parse_sdf
from inshade.techniques.prt import train as prt_train
from inshade.techniques.prt import transfer_training
from inshade.techniques.prt.transfer import build_dataset, mesh_transfer, sdf_transfer

ROOT = Path(__file__).resolve().parents[2]
# tiny bakes: 8 dirs x 16 points a chunk, so 200 points are 13 shards (the last one short)
TINY = dict(n_points=200, n_dirs=8, seed=3, holdout=20, holdout_dirs=16, chunk_rays=8 * 16)

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _sdf():
    slab = {"type": "transform", "translate": [0, 0, -0.25], "child": {"type": "box", "size": [2, 2, 0.25]}}
    ball = {"type": "transform", "translate": [0, 0, 1.0], "child": {"type": "sphere", "radius": 0.5}}
    return SdfModule(parse_sdf({"format": "inshade.geometry.sdf", "version": 1, "bound": {"center": [0, 0, 0], "radius": 2.5},
                                "root": {"type": "union", "children": [slab, ball]}}))


def _mesh():
    import trimesh

    slab = trimesh.creation.box(extents=[4, 4, 0.5])
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    ball.apply_translation([0, 0, 1.0])
    return trimesh.util.concatenate([slab, ball])


def _bake(geometry, executor=None, cache=None):
    t = dict(TINY)
    return build_dataset(geometry, t.pop("n_points"), t.pop("n_dirs"), cache, progress=False, executor=executor, **t)


def _same(a: dict, b: dict) -> None:
    for k in ("position", "normal", "transfer", "heldout_position", "heldout_normal", "heldout_transfer"):
        assert torch.equal(a[k], b[k]), k
    assert a["key"] == b["key"]


@pytest.fixture(scope="module")
def sdf_in_process():
    return _bake(_sdf())


# --- sharded == unsharded, whichever runner ------------------------------------------------------

@pytest.mark.parametrize("kind", ["sdf", "mesh"])
def test_shards_equal_one_unsharded_estimate(kind, sdf_in_process):
    geometry = _sdf() if kind == "sdf" else _mesh()
    data = sdf_in_process if kind == "sdf" else _bake(geometry)
    fn = sdf_transfer if kind == "sdf" else mesh_transfer
    whole = fn(geometry, data["position"], data["normal"], TINY["n_dirs"], seed=TINY["seed"],
               chunk_rays=TINY["chunk_rays"])
    held = fn(geometry, data["heldout_position"], data["heldout_normal"], TINY["holdout_dirs"],
              seed=TINY["seed"] + 1, chunk_rays=TINY["chunk_rays"])
    assert torch.equal(whole, data["transfer"]) and torch.equal(held, data["heldout_transfer"])
    # and the shards really are independent draws: a shard's directions are not its neighbour's
    assert not torch.equal(data["transfer"][:16], data["transfer"][16:32])


def test_process_pool_matches_in_process():
    # the mesh here, the SDF through Ray below: both geometry kinds cross a process boundary
    mesh = _mesh()
    _same(_bake(mesh, Executor(workers=2)), _bake(mesh))


def test_ray_matches_in_process(sdf_in_process):
    import ray   # the [cluster] extra, part of [test]

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        _same(_bake(_sdf(), Executor(ray="auto")), sdf_in_process)
    finally:
        ray.shutdown()


# --- the cache -----------------------------------------------------------------------------------

CALLS: list = []


def _square(common, args):
    CALLS.append(args["i"])
    if args["i"] == common.get("fail_at"):
        raise RuntimeError("worker died")
    return {"y": np.full(3, args["i"] * common["k"], np.float32)}


def test_an_interrupted_bake_resumes_from_its_cached_shards(tmp_path):
    shards = [Shard(f"s{i}", {"i": i}) for i in range(5)]
    CALLS.clear()
    with pytest.raises(RuntimeError, match="worker died"):
        run_shards(_square, shards, {"k": 2, "fail_at": 3}, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s0.safetensors", "s1.safetensors", "s2.safetensors"]
    CALLS.clear()
    out = run_shards(_square, shards, {"k": 2}, tmp_path)
    assert CALLS == [3, 4]                                     # only the missing shards ran
    assert [float(r["y"][0]) for r in out] == [0, 2, 4, 6, 8]
    CALLS.clear()
    assert [float(r["y"][0]) for r in run_shards(_square, shards, {"k": 2}, tmp_path)] == [0, 2, 4, 6, 8]
    assert CALLS == []


def test_a_failing_shard_in_the_pool_stops_the_bake(tmp_path):
    shards = [Shard(f"s{i}", {"i": i}) for i in range(4)]
    with pytest.raises(RuntimeError, match="worker died"):     # the worker's own error, not a broken pool
        run_shards(_square, shards, {"k": 1, "fail_at": 1}, tmp_path, Executor(workers=2))
    assert not (tmp_path / "s1.safetensors").exists()


def test_dataset_cache_replaces_the_shard_cache(tmp_path, sdf_in_process):
    data = _bake(_sdf(), cache=tmp_path)
    _same(data, sdf_in_process)
    assert [p.name for p in tmp_path.iterdir()] == [f"transfer-{data['key']}.safetensors"]


def test_a_foreign_or_corrupt_shard_file_is_one_clear_error(tmp_path):
    (tmp_path / "s0.safetensors").write_bytes(b"not a safetensors file")
    with pytest.raises(BakeError, match=r"s0\.safetensors: unreadable bake shard .*delete it"):
        run_shards(_square, [Shard("s0", {"i": 0})], {"k": 1}, tmp_path)
    bake.save_shard(tmp_path / "s1.safetensors", "other", {"y": np.zeros(1, np.float32)})
    with pytest.raises(BakeError, match=r"s1\.safetensors: not shard 's1' of this bake"):
        run_shards(_square, [Shard("s1", {"i": 1})], {"k": 1}, tmp_path)


def test_bad_executor_options_are_one_clear_error(capsys):
    with pytest.raises(BakeError, match="--workers: must be an int >= 0"):
        Executor(workers=-1)
    with pytest.raises(BakeError, match="give one of them"):
        Executor(workers=2, ray="auto")
    with pytest.raises(BakeError, match="names must be unique"):
        run_shards(_square, [Shard("a", {"i": 0}), Shard("a", {"i": 1})], {"k": 1})
    sdf = str(ROOT / "trained/prt_creature/sdf.json")
    import sys

    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(sys.modules, "ray", None)           # as on a machine without the [cluster] extra
        with pytest.raises(BakeError, match=r"--ray: Ray is not installed \(pip install 'inshade\[cluster\]'\)"):
            run_shards(_square, [Shard("a", {"i": 0})], {"k": 1}, executor=Executor(ray="auto"))
    assert prt_train.main(["--sdf", sdf, "--out", "/nonexistent/x", "--workers", "-1"]) == 2
    assert "inshade: error: --workers: must be an int >= 0, got -1" in capsys.readouterr().err


# --- presets (the shipped assets' recipes) -------------------------------------------------------

ASSETS = sorted(prt_train.SHIP_ASSETS)


def test_ship_base_is_the_trainers_defaults():
    for k, v in transfer_training.DEFAULTS.items():
        if k in prt_train.SHIP_BASE:
            assert prt_train.SHIP_BASE[k] == v, k


@pytest.mark.parametrize("name", ASSETS)
def test_shipped_assets_record_their_ship_preset(name):
    metrics = json.loads((ROOT / "trained" / name / "metrics.json").read_text())
    assert metrics["preset"] == "ship"
    assert metrics["settings"] == prt_train.preset_settings("ship", name)
    # and the preset is what the recorded commands ran: the transfer command (every option written
    # out) and the quality measurement's own record
    s = metrics["settings"]
    options = dict(o[2:].split("=", 1) for o in shlex.split(metrics["provenance"]["command"])[3:] if "=" in o)
    for k in ("width", "layers", "points", "dirs", "steps", "batch", "pos_freqs", "normal_freqs", "seed"):
        assert int(options[k.replace("_", "-")]) == s[k], k
    assert float(options["lr"]) == s["lr"] and options["output"] == s["output"]
    assert ("--drop-enclosed" in metrics["provenance"]["command"]) == s["drop_enclosed"]
    q = metrics["quality"]
    assert (q["n_views"], q["size"], q["n_dirs"]) == (s["quality_views"], s["quality_size"], s["quality_dirs"])
    scene = json.loads((ROOT / "trained" / name / "scene.json").read_text())
    assert scene["title"] == s["title"]
    if s["camera_from"]:
        assert scene["camera"] == json.loads((ROOT / s["camera_from"]).read_text())["camera"]


def test_the_ship_recipe_is_the_creatures():
    s = prt_train.preset_settings("ship", "prt_creature")
    assert (s["points"], s["dirs"], s["steps"], s["batch"], s["lr"]) == (60000, 256, 6000, 4096, 2e-3)
    assert prt_train.preset_settings("ship", "my_asset") == prt_train.SHIP_BASE


def test_train_prt_quick_records_preset_and_settings(tmp_path):
    out = tmp_path / "prt_quick"
    sdf = tmp_path / "ball.json"       # a sphere: the fastest surface to sample and sphere trace
    sdf.write_text(json.dumps({"format": "inshade.geometry.sdf", "version": 1, "bound": {"center": [0, 0, 0], "radius": 1.0},
                               "root": {"type": "sphere", "radius": 0.5}}))
    argv = ["--preset", "quick", "--sdf", str(sdf), "--out", str(out),
            "--cache", str(tmp_path / "cache"), "--points", "300", "--dirs", "8", "--steps", "20",
            "--quality-views", "1", "--quality-size", "16", "--quality-dirs", "8", "--device", "cpu"]
    assert prt_train.main(argv) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    expected = {**prt_train.QUICK, "points": 300, "dirs": 8, "steps": 20, "quality_views": 1, "quality_size": 16,
                "quality_dirs": 8}
    assert metrics["preset"] == "quick" and metrics["settings"] == expected
    assert metrics["transfer"]["points"] == 300 and metrics["transfer"]["steps"] == 20
    assert "--preset=quick" in metrics["command"] and "--workers" not in metrics["command"]
    assert list((tmp_path / "cache").glob("*.shards")) == []      # the shard cache is gone once the data is
