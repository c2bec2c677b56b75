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

REPO = Path(__file__).resolve().parents[1]
SHIPPED = sorted(p.parent for p in (REPO / "trained").rglob("bundle.json"))
# di_sdf: its `primary` lookup array (24^3 triangle-baked cells) reads a coordinate computed by
# the `to_unit` dense; its gain (~69) is past LOOKUP_GAIN = 50, which is calibrated on a 64-input
# dense (to_unit has one weight per row, so the real discrepancy is smaller: a conservative warning).
# neural_appearance_*/decoder_3x64: interval arithmetic through three 64-wide layers bounds the expm1
# argument at ~230 over z in [-1, 1] (the latents lie in [-0.98, 0.71]); the decoders' real outputs,
# 200k random latents x directions, stay below log(1 + 63) = 4.2: a conservative warning.
EXPECTED_WARNINGS = {"di_sdf": {"primary"}, "neural_appearance_ceramic/decoder_3x64": {"expm1"},
                     "neural_appearance_brushed_metal/decoder_3x64": {"expm1"}}


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
