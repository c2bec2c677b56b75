"""Thin geometry: the SDF shadow-ray schemes of techniques/prt/transfer.py and the
study / sampling helpers of techniques/prt/thin.py.

- the default scheme is the shipped estimator's (bit-identical), and thin.py's study traces exactly
  what ``sdf_transfer`` traces for every scheme (same directions, same numbers);
- a slot of 2.5 hit_eps between two plates: the default scheme (origin offset 4 hit_eps) starts
  its rays inside the upper plate and closes the slot; the "fine" scheme keeps it open, and its
  visibility matches a direct ray-plane computation of which directions leave through the slot's
  mouth (numpy, not the sphere tracer);
- near-occluder sampling puts more samples where another surface is close along the normal.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pytest
import torch

from inshade.geometry.sdf import parse_sdf
from inshade.techniques.prt import near_occluders, thin
from inshade.techniques.prt import transfer as T
from inshade.techniques.prt.transfer_directions import hemisphere_directions
from inshade.techniques.prt.transfer_inputs import TransferError
from inshade.techniques.prt.transfer_surface import sample_sdf_surface
from inshade.techniques.prt.twin import sdf_module

ROOT = Path(__file__).resolve().parents[3]

HIT = 1e-3
GAP = 2.5 * HIT
SLOT = {  # two 0.6 x 0.6 plates, the lower one's top at y = 0, the upper one's bottom at y = GAP,
    # the upper plate ends at x = 0.1 (the slot's mouth); a wall-free floor beyond it
    "format": "inshade.geometry.sdf", "version": 1, "bound": {"center": [0, 0, 0], "radius": 1.0},
    "trace": {"max_steps": 256, "step_scale": 0.9, "hit_eps": HIT, "normal_eps": HIT},
    "root": {"type": "union", "children": [
        {"type": "transform", "translate": [0.0, -0.05, 0.0], "child": {"type": "box", "size": [0.3, 0.05, 0.3]}},
        {"type": "transform", "translate": [-0.1, GAP + 0.05, 0.0], "child": {"type": "box", "size": [0.2, 0.05, 0.3]}}]},
}


@pytest.fixture(scope="module")
def mech_points():
    scene = parse_sdf({**SLOT})
    sdf = sdf_module(scene)
    p = torch.tensor([[-0.2, 0.0, 0.0], [0.06, 0.0, 0.05], [0.2, 0.0, 0.1]], dtype=torch.float32)
    n = torch.tensor([[0.0, 1.0, 0.0]] * 3)
    return sdf, p, n


@pytest.mark.parametrize("shadow", list(T.SHADOW_SCHEMES))
def test_sdf_transfer_is_the_studied_scheme(mech_points, shadow):
    sdf, p, n = mech_points
    got = T.sdf_transfer(sdf, p, n, n_dirs=64, seed=3, shadow=shadow)
    off, thr = T.SHADOW_SCHEMES[shadow]
    dirs = hemisphere_directions(n, 64, torch.Generator().manual_seed(3))
    ref, _, _ = thin.scheme_transfer(sdf, p, n, dirs, (off, thr, T.SHADOW_STEPS, 0.9, False))
    assert torch.equal(got, ref)


def test_default_scheme_is_the_shipped_estimator():
    assert T.DEFAULT_SHADOW == "offset4" and T.SHADOW_SCHEMES["offset4"] == (T.OFFSET_EPS, 1.0)
    with pytest.raises(TransferError, match="shadow: must be one of"):
        T.sdf_transfer(sdf_module(parse_sdf(SLOT)), torch.zeros(1, 3), torch.tensor([[0.0, 1.0, 0.0]]), shadow="x")


def test_fine_scheme_keeps_a_thin_slot_open(mech_points):
    """A point on the slot's floor 0.005 from its mouth: only directions towards +x that rise less
    than the gap over the run to the mouth leave the slot. The default scheme's origin (4 hit_eps
    up) lies inside the upper plate: everything is blocked."""
    sdf, _, _ = mech_points
    p = torch.tensor([[0.095, 0.0, 0.0]])
    n = torch.tensor([[0.0, 1.0, 0.0]])
    dirs = hemisphere_directions(n, 4096, torch.Generator().manual_seed(5))
    coarse = T.sdf_transfer(sdf, p, n, n_dirs=4096, seed=5)
    fine = T.sdf_transfer(sdf, p, n, n_dirs=4096, seed=5, shadow="fine")
    assert float(coarse[0, 0]) == 0.0
    # numpy ray-plane visibility from the fine scheme's origin (p + offset n)
    y0 = T.SHADOW_SCHEMES["fine"][0] * HIT
    d = dirs[0].double().numpy()
    run = 0.1 - 0.095
    t = np.where(d[:, 0] > 0, run / np.maximum(d[:, 0], 1e-12), np.inf)
    escapes = (d[:, 0] > 0) & (y0 + t * d[:, 1] < GAP)
    expected = escapes.mean() * np.pi * 0.28209479177387814       # band 0 of (pi / D) sum V y_0
    assert expected > 0.005
    # rays grazing the mouth's lip within the hit threshold may go either way
    assert abs(float(fine[0, 0]) - expected) <= 0.15 * expected


def test_near_occluder_sampling_prefers_contact_regions(mech_points):
    sdf, _, _ = mech_points
    delta = 0.03
    uni_p, uni_n = sample_sdf_surface(sdf, 3000, seed=1)
    near_p, near_n = near_occluders.sample_near_occluders(sdf, 3000, seed=1, boost=3.0, delta=delta)
    share = lambda p, n: float((near_occluders.occluder_proximity(sdf, p, n, delta) > 0.2).float().mean())  # noqa: E731
    assert share(near_p, near_n) > 1.5 * share(uni_p, uni_n) > 0
    with torch.no_grad():
        assert float(sdf(near_p).abs().max()) < HIT


def test_plants_sdf_is_the_shipped_geometry_and_has_thin_leaves():
    """trained/prt_plants/sdf.json is techniques/prt/plants.py's output (rebuildable), and its
    leaves are thin: along a leaf's normal the solid is under 30 hit_eps thick."""
    import json
    from pathlib import Path

    from inshade.techniques.prt.plants import LEAF, plants_sdf

    shipped = Path(__file__).resolve().parents[3] / "trained" / "prt_plants" / "sdf.json"
    assert json.loads(shipped.read_text()) == plants_sdf()
    assert 2 * LEAF[1] < 30 * HIT
    sdf = sdf_module(parse_sdf(plants_sdf()))
    p, n = sample_sdf_surface(sdf, 2000, seed=2, resolution=64)
    with torch.no_grad():
        # a probe 30 hit_eps behind the surface leaves the solid somewhere: the leaves
        behind = sdf(p - n * (30 * HIT))
    assert float((behind > 0).float().mean()) > 0.05


def test_build_dataset_traces_the_chosen_scheme(tmp_path):
    """The scheme reaches the bake's shards and the cache key."""
    sdf = sdf_module(parse_sdf(SLOT))
    fine = T.build_dataset(sdf, 200, 16, cache_dir=tmp_path, holdout=8, holdout_dirs=16, progress=False,
                           shadow="fine")
    default = T.build_dataset(sdf, 200, 16, cache_dir=tmp_path, holdout=8, holdout_dirs=16, progress=False)
    assert fine["key"] != default["key"]
    expect = T.sdf_transfer(sdf, fine["position"], fine["normal"], n_dirs=16, seed=0, shadow="fine")
    assert torch.equal(fine["transfer"], expect)
    assert torch.equal(default["transfer"], T.sdf_transfer(sdf, default["position"], default["normal"], n_dirs=16,
                                                           seed=0))
    with pytest.raises(TransferError, match="shadow: must be one of"):
        T.build_dataset(sdf, 10, 4, shadow="nope")


def test_build_dataset_adds_near_occluder_samples(tmp_path):
    """``near_points``: further training samples near occluders, cast like the uniform ones and
    appended to them; the uniform samples and the held-out set are those of the uniform dataset,
    the cache key differs, and a mesh is refused (the proximity is a distance query)."""
    import trimesh

    sdf = sdf_module(parse_sdf(SLOT))
    kw = dict(cache_dir=tmp_path, holdout=8, holdout_dirs=16, progress=False)
    uniform = T.build_dataset(sdf, 200, 16, **kw)
    near = T.build_dataset(sdf, 200, 16, near_points=100, **kw)
    assert near["key"] != uniform["key"] and (near["n_near"], uniform["n_near"]) == (100, 0)
    assert near["position"].shape == (300, 3) and near["transfer"].shape == (300, 16)
    assert torch.equal(near["position"][:200], uniform["position"])
    assert torch.equal(near["transfer"][:200], uniform["transfer"])
    for k in ("heldout_position", "heldout_transfer"):
        assert torch.equal(near[k], uniform[k])
    p_near, n_near = near["position"][200:], near["normal"][200:]
    assert torch.equal(near["transfer"][200:], T.sdf_transfer(sdf, p_near, n_near, n_dirs=16, seed=2))
    delta = T.NEAR_DELTA * float(sdf.scene.radius)
    share = lambda p, n: float((near_occluders.occluder_proximity(sdf, p, n, delta) > 0.2).float().mean())  # noqa: E731
    assert share(p_near, n_near) > share(uniform["position"], uniform["normal"])
    again = T.build_dataset(sdf, 200, 16, near_points=100, **kw)
    assert again["cached"] and torch.equal(again["position"], near["position"])
    with pytest.raises(TransferError, match="near_points: near-occluder samples need an SDF"):
        T.build_dataset(trimesh.creation.box(), 10, 4, near_points=5)


def test_near_points_is_recorded_only_where_a_recipe_uses_it():
    """recipes.py: ``near_points`` is an optional setting: prt_mechanical's recipe names it, the other
    recipes (and their metrics.json) do not, an explicit --near-points wins (0: none drawn)."""
    from inshade.techniques.prt import train as prt_train
    from inshade.techniques.prt.recipes import RECIPES
    from inshade.trainer import recorded

    def resolve(name, *given):
        sdf = str(ROOT / "trained/prt_creature/sdf.json")
        args = prt_train.add_arguments(argparse.ArgumentParser()).parse_args(["--sdf", sdf, "--out", f"/x/{name}",
                                                                              *given])
        return recorded(prt_train.TRAINER.resolve(args))

    s = resolve("prt_mechanical")
    assert s["recipe"] == "prt_mechanical" and s["near_points"] == RECIPES["prt_mechanical"]["near_points"] > 0
    s = resolve("prt_creature")
    assert s["recipe"] == "prt_creature" and "near_points" not in s
    assert resolve("prt_creature", "--near-points", "500")["near_points"] == 500
    assert resolve("prt_mechanical", "--near-points", "0")["near_points"] == 0
    # --recipe names the recipe whatever the folder is called
    s = resolve("my_asset", "--recipe", "prt_mechanical")
    assert s["near_points"] == 160000 and s["quality_dirs"] == 256
    assert resolve("my_asset")["recipe"] == "base"