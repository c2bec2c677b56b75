"""The numeric envelope (inshade/envelope.py): shipped bundles sit inside it, hand-built bundles
that leave it are named. numpy only: no GL, no torch."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from inshade.bundle import Bundle, load
from inshade.envelope import (EXP_ARG, LOOKUP_GAIN, PERIODIC_ARG_COMPUTED, PERIODIC_ARG_INPUT, WARNING,
                              analyse, format_findings)

REPO = Path(__file__).resolve().parents[2]
SHIPPED = sorted(p.parent for p in (REPO / "trained").rglob("bundle.json"))
# di_sdf: its `primary` lookup array (24^3 triangle-baked cells) reads a coordinate computed by
# the `to_unit` dense; its gain (~69) is past LOOKUP_GAIN = 50, which is calibrated on a 64-input
# dense (to_unit has one weight per row, so the real discrepancy is smaller: a conservative warning).
# neural_appearance_*/decoder_3x64: interval arithmetic through three 64-wide layers bounds the expm1
# argument at ~230 over z in [-1, 1] (the latents lie in [-0.98, 0.71]); the decoders' real outputs,
# 200k random latents x directions, stay below log(1 + 63) = 4.2: a conservative warning.
# hash_grid_sdf: its `grid` reads the coordinate its frozen `to_unit` dense computes, x = 0.5 q + 0.5: a
# power-of-two scale and one rounded sum, the same bits in torch and GLSL, so the gain (~850 at level 14)
# multiplies no discrepancy (scene_sdf: max |glsl - torch| 2.4e-7 at 2048 random points): a conservative warning.
EXPECTED_WARNINGS = {"di_sdf": {"primary"}, "neural_appearance_ceramic/decoder_3x64": {"expm1"},
                     "neural_appearance_brushed_metal/decoder_3x64": {"expm1"}, "hash_grid_sdf": {"grid"}}


def _name(folder: Path) -> str:
    return str(folder.relative_to(REPO / "trained"))


def test_shipped_bundles_are_found():
    names = {_name(p) for p in SHIPPED}
    assert {"prt_neural_bunny/sdf", "prt_neural_bunny/transfer", "prt_mesh/transfer", "neural_image"} <= names


@pytest.mark.parametrize("folder", SHIPPED, ids=_name)
def test_shipped_bundles_inside_envelope(folder):
    env = analyse(load(folder))
    warned = {f.node for f in env.warnings}
    assert warned == EXPECTED_WARNINGS.get(_name(folder), set()), "\n".join(format_findings(env))
    lines = format_findings(env)
    assert lines and (warned or lines[0].startswith("inside the parity envelope"))


# --- hand-built bundles ---------------------------------------------------------------------

def _bundle(inputs, nodes, outputs, tensors, render=None) -> Bundle:
    meta = {"format": "inshade.bundle", "version": 1, "kind": "probe", "inputs": inputs, "nodes": nodes,
            "outputs": outputs}
    if render is not None:
        meta["render"] = render
    return Bundle(meta, {k: np.asarray(v, np.float32) for k, v in tensors.items()})


def _dense_act(act: str, w_scale: float, params=None, n_in=4, width=8, semantic="uv"):
    rng = np.random.default_rng(0)
    nodes = [{"id": "l0", "type": "dense", "inputs": ["x"], "params": {"out": width}},
             {"id": "big_act", "type": act, "inputs": ["l0"], "params": params or {}}]
    return _bundle([{"name": "x", "dim": n_in, "semantic": semantic}], nodes,
                   [{"name": "y", "node": "big_act"}],
                   {"l0.weight": rng.uniform(-w_scale, w_scale, (width, n_in)),
                    "l0.bias": rng.uniform(-0.1, 0.1, width)})


def test_sin_of_huge_weights_warns_with_node_named():
    env = analyse(_dense_act("sin", 1.0, {"omega0": 1000.0}))
    [w] = env.warnings
    assert w.level == WARNING and w.node == "big_act" and "sin argument" in w.quantity
    assert w.threshold == PERIODIC_ARG_COMPUTED and w.bound > 1000.0
    line = format_findings(env)[0]
    assert line.startswith("warning: big_act: sin argument") and f"{w.threshold:.4g}" in line


def test_siren_scale_sin_is_inside():
    # SIREN init: |W| <= sqrt(6 / n) / omega0, so the argument stays O(omega0 * |x|) small
    env = analyse(_dense_act("sin", math.sqrt(6 / 4) / 30.0, {"omega0": 30.0}))
    assert env.ok, format_findings(env)


def test_exp_of_large_argument_warns_with_node_named():
    env = analyse(_dense_act("exp", 60.0))   # 4 inputs in [0, 1]: some row reaches well past 80
    [w] = env.warnings
    assert w.node == "big_act" and w.quantity == "exp argument" and w.threshold == EXP_ARG and w.bound > EXP_ARG
    assert analyse(_dense_act("exp", 0.25 / 4)).ok


def test_saturating_activations_never_warn():
    for act in ("sigmoid", "tanh", "softplus"):
        assert analyse(_dense_act(act, 30.0)).ok, act


def test_frequency_of_input_past_2_7_pi_warns():
    def freq(n):
        return _bundle([{"name": "uv", "dim": 2, "semantic": "uv"}],
                       [{"id": "enc", "type": "frequency", "inputs": ["uv"], "params": {"n_freqs": n}}],
                       [{"name": "y", "node": "enc"}], {})
    assert analyse(freq(8)).ok          # 2^7 pi * 1: the edge of the envelope (neural_image)
    [w] = analyse(freq(9)).warnings
    assert w.node == "enc" and w.threshold == PERIODIC_ARG_INPUT and w.bound == pytest.approx(2 ** 8 * math.pi)


def test_frequency_of_computed_value_uses_the_computed_limit():
    rng = np.random.default_rng(1)
    b = _bundle([{"name": "uv", "dim": 2, "semantic": "uv"}],
                [{"id": "l0", "type": "dense", "inputs": ["uv"], "params": {"out": 2}},
                 {"id": "enc", "type": "frequency", "inputs": ["l0"], "params": {"n_freqs": 8}}],
                [{"name": "y", "node": "enc"}], {"l0.weight": rng.uniform(0.4, 0.5, (2, 2)), "l0.bias": np.zeros(2)})
    [w] = analyse(b).warnings
    assert w.node == "enc" and w.threshold == PERIODIC_ARG_COMPUTED


def test_dense_magnitude_past_2_24_warns():
    env = analyse(_dense_act("relu", 1e6))
    assert [f.node for f in env.warnings] == ["l0"] and "accumulation magnitude" in env.warnings[0].quantity


def test_steep_lookup_of_computed_coordinate_warns():
    rng = np.random.default_rng(2)
    cells = rng.uniform(0, 1, (256, 1))
    b = _bundle([{"name": "uv", "dim": 2, "semantic": "uv"}],
                [{"id": "pick", "type": "dense", "inputs": ["uv"], "params": {"out": 1}},
                 {"id": "lut", "type": "lookup_array", "inputs": ["pick"],
                  "params": {"resolution": [256], "channels": 1, "bits": 32}}],
                [{"name": "y", "node": "lut"}],
                {"pick.weight": [[0.5, 0.5]], "pick.bias": [0.0], "lut.cells": cells})
    [w] = analyse(b).warnings
    assert w.node == "lut" and w.threshold == LOOKUP_GAIN and w.bound > LOOKUP_GAIN


def test_input_ranges_and_assumptions():
    b = _dense_act("relu", 1.0, semantic="mystery")
    env = analyse(b)
    assert env.ranges == {"x": (-1.0, 1.0)}
    assert any(f.node == "x" and "assumed [-1, 1]" in f.why for f in env.notes)
    env = analyse(b, ranges={"x": (0.0, 2.0)})
    assert env.ranges == {"x": (0.0, 2.0)} and not env.notes
    with pytest.raises(ValueError, match="no input port"):
        analyse(b, ranges={"nope": (0, 1)})


def test_intervals_are_sound():
    """Random inputs never leave the propagated intervals (numpy forward pass, float64)."""
    rng = np.random.default_rng(3)
    b = _bundle([{"name": "p", "dim": 3, "semantic": "position"}],
                [{"id": "enc", "type": "frequency", "inputs": ["p"], "params": {"n_freqs": 3}},
                 {"id": "l0", "type": "dense", "inputs": ["enc"], "params": {"out": 5}},
                 {"id": "a0", "type": "leaky_relu", "inputs": ["l0"], "params": {"slope": -0.5}},
                 {"id": "a1", "type": "sin", "inputs": ["a0"], "params": {"omega0": 3.0}}],
                [{"name": "y", "node": "a1"}],
                {"l0.weight": rng.normal(size=(5, 21)), "l0.bias": rng.normal(size=5)},
                render={"transfer": {"center": [0, 0, 0], "radius": 1.0, "scale": 1.0, "degree": 4}})
    env = analyse(b)
    x = rng.uniform(-1, 1, (2000, 3))
    enc = np.concatenate([x] + [f(2.0 ** k * np.pi * x) for f in (np.sin, np.cos) for k in range(3)], 1)
    l0 = enc @ b.tensors["l0.weight"].T.astype(np.float64) + b.tensors["l0.bias"]
    a0 = np.maximum(l0, 0) - 0.5 * np.minimum(l0, 0)
    a1 = np.sin(3.0 * a0)
    for name, v in (("enc", enc), ("l0", l0), ("a0", a0), ("a1", a1)):
        lo, hi = env.intervals[name]
        assert (v >= lo - 1e-9).all() and (v <= hi + 1e-9).all(), name


# --- grid encodings and one_blob ---------------------------------------------------------------------

def _grid_bundle(kind: str, params: dict, table, *, dims: int = 2, semantic: str = "uv", through=None):
    """A grid node reading the input, or (through = (W, b)) a dense layer's output."""
    nodes, tensors, src = [], {"grid.table": table}, "x"
    if through is not None:
        nodes.append({"id": "pre", "type": "dense", "inputs": ["x"], "params": {"out": dims}})
        tensors["pre.weight"], tensors["pre.bias"] = through
        src = "pre"
    nodes.append({"id": "grid", "type": kind, "inputs": [src], "params": {**params, "precision": "f32"}})
    return _bundle([{"name": "x", "dim": dims, "semantic": semantic}], nodes, [{"name": "y", "node": "grid"}], tensors)


HASHED = {"levels": 3, "features": 2, "base_resolution": 16, "per_level_scale": 4.0, "log2_table_size": 8}


def test_grid_fused_position_is_a_note_past_the_rule():
    """Levels of scale 15 (dense), 63 and 255 (hashed, 256 rows each): where p = 255 x + 0.5 is fused
    it moves by ulp(255.5) = 2^-16, times the features' spread on each of the two axes."""
    table = np.random.default_rng(4).uniform(-1, 1, (768, 2))
    env = analyse(_grid_bundle("hash_grid", HASHED, table))
    assert env.ok, format_findings(env)
    [note] = [f for f in env.notes if f.node == "grid"]
    assert "fused position" in note.quantity and "(level 2)" in note.quantity and note.threshold == 1e-5
    t = table.astype(np.float32).astype(np.float64)[512:]
    want = 2 * float((t.max(0) - t.min(0)).max()) * 2.0 ** -16 / max(1.0, float(np.abs(t).max()))
    assert note.bound == pytest.approx(want, rel=1e-12)
    quiet = analyse(_grid_bundle("hash_grid", HASHED, table * 0.1))     # 6e-6: inside the rule
    assert not quiet.findings, format_findings(quiet)


def _periodic_table(rows: int, shuffle: bool):
    """Values smooth along the flat row index (every dense neighbour, wrap-around included, differs by
    little), or the same values shuffled (neighbours differ by up to the spread)."""
    t = np.sin(np.arange(rows) * 2 * np.pi / rows)[:, None]
    return np.random.default_rng(5).permutation(t) if shuffle else t


def test_grid_gain_of_a_computed_coordinate():
    """A dense layer feeding a 129^2 grid (scale 128, 16648 rows): a smooth dense level's gain is
    128 * (2 pi / 16648 + 2 pi 129 / 16648) ~ 6.3; shuffled, its neighbours differ by up to 2 and the
    gain nears 128 * 4 = 512, past GRID_GAIN; hashed, only the spread is known (512 as well)."""
    from inshade.envelope import GRID_GAIN

    through = (np.eye(2) * 0.5, np.full(2, 0.25))                     # coordinates in [0.25, 0.75]
    dense = {"levels": 1, "features": 1, "base_resolution": 129}
    assert analyse(_grid_bundle("dense_grid", dense, _periodic_table(16648, False), through=through)).ok
    [w] = analyse(_grid_bundle("dense_grid", dense, _periodic_table(16648, True), through=through)).warnings
    assert w.node == "grid" and "grid gain" in w.quantity and w.threshold == GRID_GAIN
    assert GRID_GAIN < w.bound <= 512.0
    hashed = {**dense, "log2_table_size": 14}                            # 129^2 > 2^14: hashed
    [w] = analyse(_grid_bundle("hash_grid", hashed, _periodic_table(1 << 14, False), through=through)).warnings
    assert w.bound == pytest.approx(128 * 2 * 2.0, rel=1e-6)
    # the same grid reading the input directly: both sides round p alike, no gain
    assert analyse(_grid_bundle("dense_grid", dense, _periodic_table(16648, True))).ok


def test_grid_intervals_and_wrap_note():
    table = np.random.default_rng(6).uniform(-1, 1, (768, 2))
    env = analyse(_grid_bundle("hash_grid", HASHED, table * 0.1, semantic="mystery"))
    lo, hi = env.intervals["grid"]
    t = (table * 0.1).astype(np.float32).astype(np.float64)
    np.testing.assert_array_equal(lo, np.concatenate([t[o:o + 256].min(0) for o in (0, 256, 512)]))
    np.testing.assert_array_equal(hi, np.concatenate([t[o:o + 256].max(0) for o in (0, 256, 512)]))
    assert env.ok and any(f.node == "grid" and "wrap" in f.why for f in env.notes)


def _blob(n_bins: int, computed: bool):
    nodes, tensors, src = [], {}, "x"
    if computed:
        nodes.append({"id": "pre", "type": "dense", "inputs": ["x"], "params": {"out": 1}})
        tensors = {"pre.weight": [[0.5, 0.5]], "pre.bias": [0.0]}
        src = "pre"
    nodes.append({"id": "blob", "type": "one_blob", "inputs": [src], "params": {"n_bins": n_bins}})
    return _bundle([{"name": "x", "dim": 2 if computed else 1, "semantic": "uv"}], nodes,
                   [{"name": "y", "node": "blob"}], tensors)


def test_one_blob_gain_of_a_computed_input():
    [w] = analyse(_blob(64, True)).warnings
    assert w.node == "blob" and "one_blob gain" in w.quantity and w.threshold == LOOKUP_GAIN and w.bound == 60.0
    assert analyse(_blob(32, True)).ok               # gain 30
    env = analyse(_blob(1024, False))                # an input: bit-identical, no limit
    assert env.ok and not env.findings
    lo, hi = env.intervals["blob"]
    assert lo.shape == (1024,) and (lo == 0).all() and (hi == 1).all()
