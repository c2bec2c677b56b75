"""tiny-cuda-nn models in: ``inshade convert config.json params`` (inshade/convert/tcnn.py).

What is compared with what (tiny-cuda-nn itself needs CUDA and is not run):

- layout, by hand: parameter counts, level resolutions / rows / offsets, paddings and the
  values padding lanes hold, the weight matrices' order and row-major layout; each expected
  number is derived in the test from tiny-cuda-nn's source (docs/tcnn.md cites it);
- the hash: inshade.grid_layout.vertex_index bit-identical to tests/tcnn_reference.py's
  grid_index for integer coordinates up to 2^16 per axis;
- the lowering: the bundle's torch twin against tests/tcnn_reference.py (a torch forward of
  tiny-cuda-nn written from its source, sharing no code with the lowering), for every encoding
  and network and every activation, under the bound ``bound_*`` below derives;
- the GLSL: against the bundle's torch twin through the driver, under the parity rule 1e-5;
- the command line, end to end, and its refusals (one line, exit status 2, nothing written).

The bound twin vs reference. The two compute the same function in float32 with different
roundings: tiny-cuda-nn fuses the grid position (fmaf(scale, x, 0.5)), inshade rounds scale * x
and + 0.5 separately (as GLSL 3.30 spells it); inshade's level scale comes from numpy's float32
log2 / exp2, tiny-cuda-nn's from the C library's log2f / exp2f (they differ by a few ulp of the
scale at fine levels); Frequency's cosine is sin(t + pi/2) in tiny-cuda-nn, cos(t) here; sums run
in other orders. Per encoding lane the bound is what those differences can move it by (see
``lane_bounds``); through the network it is carried layer by layer as |W| d + n 2^-23 |W| |h|
(the two dot products' rounding) times the activation's Lipschitz constant, plus 1e-6 * max(1,
|y|) for the last roundings.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

import tcnn_reference as ref
from inshade.bundle import load
from inshade.cli import main
from inshade.convert.lowering import ConvertError
from inshade.convert.tcnn import ACTIVATIONS, Builder, leaky_slope, to_bundle
from inshade.convert.tcnn_config import parse_model
from inshade.convert.tcnn_params import read_params
from inshade.grid_layout import HASH_PRIMES, GridLevel, grid_levels, level_scale, vertex_index
from inshade.models import GraphModule
from parity import check_parity

REPO = Path(__file__).resolve().parents[2]
U = 2.0 ** -24   # unit roundoff of float32
NERF_DENSITY = {   # instant-ngp's NeRF density network (configs/nerf/base.json, aabb scale 1)
    "n_input_dims": 3, "n_output_dims": 16,
    "encoding": {"otype": "HashGrid", "n_levels": 16, "n_features_per_level": 2, "log2_hashmap_size": 19,
                 "base_resolution": 16, "per_level_scale": 1.3819128799677},
    "network": {"otype": "FullyFusedMLP", "activation": "ReLU", "output_activation": "None", "n_neurons": 64,
                "n_hidden_layers": 1}}


# --- helpers --------------------------------------------------------------------------------

def random_params(config: dict, dtype: str = "float32", seed: int = 0, table_scale: float = 0.5,
                  weight_gain: float = 1.0) -> np.ndarray:
    """Xavier-uniform weight matrices (tiny-cuda-nn's initialisation) and U(-table_scale,
    table_scale) grid tables, rounded to ``dtype``."""
    model = ref.build(config)
    rng = np.random.default_rng(seed)
    parts = []
    if model["network"]:
        for rows, cols in model["network"]["shapes"]:
            limit = weight_gain * math.sqrt(6.0 / (rows + cols))
            parts.append(rng.uniform(-limit, limit, rows * cols))
    parts.append(rng.uniform(-table_scale, table_scale, model["encoding"]["n_params"]))
    return np.concatenate(parts).astype(dtype).astype(np.float32)


def twin(bundle, x: np.ndarray) -> np.ndarray:
    with torch.no_grad():
        return GraphModule.from_bundle(bundle)(torch.from_numpy(np.asarray(x, np.float32))).numpy()


def ulp(v) -> np.ndarray:
    return np.spacing(np.abs(np.asarray(v, np.float32))).astype(np.float64)


def lane_bounds(e: dict, x: np.ndarray, params: np.ndarray) -> np.ndarray:
    """Per row and lane [N, lanes], how far inshade's encoding may lie from tiny-cuda-nn's (the
    reference's encoding dict ``e``; ``params`` its parameters)."""
    n = len(x)
    kind = e["otype"]
    if kind == "composite":
        parts, at = [], 0
        for nested, begin in zip(e["nested"], e["begins"]):
            parts.append(lane_bounds(nested, x[:, begin:begin + nested["n"]], params[at:at + nested["n_params"]]))
            at += nested["n_params"]
        return np.concatenate(parts, 1)
    if kind in ("grid", "hashgrid", "densegrid"):
        # d p <= |scale_inshade - scale_tcnn| + 2 ulp(p) per axis (x <= 1); d feature <= sum over axes of
        # d p * 2 max|table of the level| (the multilinear weights' derivative), + the sums' roundings
        cols = []
        for level, (scale, _, rows, offset) in enumerate(e["table"]):
            ours = level_scale(level, e["per_level_scale"], e["base_resolution"])
            dp = abs(float(ours) - float(scale)) + 2 * float(ulp(float(scale) + 0.5))
            top = float(np.abs(params[offset * e["F"]:(offset + rows) * e["F"]]).max())
            cols += [e["n"] * dp * 2 * top + (1 << e["n"]) * 2 * float(ulp(top))] * e["F"]
        core = np.tile(cols, (n, 1))
    elif kind == "frequency":   # sin: the same argument; cos(t) vs sin(t + pi/2): one ulp of the argument
        cols = []
        for i in range(e["n"]):
            for f in range(e["F"]):
                arg = (2.0 ** f) * math.pi * np.abs(x[:, i]) + math.pi / 2
                cols += [np.full(n, 4 * U), ulp(arg) + 4 * U]
        core = np.stack(cols, 1)
    elif kind == "sphericalharmonics":   # polynomials of |terms| < 4 evaluated in another order
        core = np.full((n, e["out"]), 64 * U)
    elif kind == "identity":   # fused vs unfused x * scale + offset
        core = ulp(np.abs(x) * abs(e["scale"]) + abs(e["offset"])) * 2
    elif kind == "trianglewave":   # 1 - 2 tri(2 val) vs 4 |frac(val) - 1/2| - 1: one rounding of 1 - t
        core = np.full((n, e["out"]), 4 * U)
    elif kind == "oneblob":   # the same float32 formula; the twin clamps u (no value changes)
        core = np.full((n, e["out"]), 2e-6)
    else:
        core = np.zeros((n, e["out"]))
    pad = np.zeros((n, e["pad"]))
    return np.concatenate([pad, core] if e["pad_first"] else [core, pad], 1)


LIPSCHITZ = {"none": 1.0, "relu": 1.0, "leakyrelu": 1.0, "sine": 1.0, "tanh": 1.0, "sigmoid": 0.25, "silu": 1.1,
             "softplus": 1.0, "squareplus": 1.0}


def bound_model(config: dict, params: np.ndarray, x: np.ndarray, dtype: str) -> tuple[np.ndarray, np.ndarray]:
    """(the reference's output, the bound on |twin - reference|), both [N, n_output_dims]."""
    model = ref.build(config)
    trace = []
    out = ref.forward(config, params, x, dtype=dtype, trace=trace)
    mats = ref.matrices(model, params) if model["network"] else []
    enc_params = params[sum(m.size for m in mats):]
    d = lane_bounds(model["encoding"], x, enc_params)
    if not model["network"]:
        return out, d + 1e-6 * np.maximum(1.0, np.abs(out))
    h = trace[0].astype(np.float64)
    net = model["network"]
    for i, w in enumerate(mats):
        a = np.abs(w.astype(np.float64))
        pre = trace[i + 1].astype(np.float64)
        d_pre = d @ a.T + 2 * w.shape[1] * U * (np.abs(h) @ a.T)
        name = net["output_activation"] if i == len(mats) - 1 else net["activation"]
        lip = np.exp(pre + d_pre) if name == "exponential" else LIPSCHITZ[name]
        h = ref.activation(name, torch.from_numpy(pre.astype(np.float32)), dtype).numpy().astype(np.float64)
        d = lip * d_pre + 8 * ulp(h)
    d = d[:, :model["n_out"]]
    return out, d + 1e-6 * np.maximum(1.0, np.abs(out))


def assert_within(ours: np.ndarray, reference: np.ndarray, bound: np.ndarray, what: str) -> float:
    assert ours.shape == reference.shape, what
    err = np.abs(ours.astype(np.float64) - reference)
    worst = np.unravel_index(int(np.argmax(err / bound)), err.shape)
    assert np.all(err <= bound), (f"{what}: |twin - reference| {err[worst]:.3g} > bound {bound[worst]:.3g} at "
                                  f"{worst} (twin {ours[worst]!r}, reference {reference[worst]!r})")
    return float((err / bound).max())


def compare(config: dict, dtype: str = "float32", n: int = 300, seed: int = 1, **params_kw) -> float:
    params = random_params(config, dtype, seed, **params_kw)
    bundle, _ = to_bundle(config, params, dtype)
    x = np.random.default_rng(seed + 100).uniform(0, 1, (n, config["n_input_dims"])).astype(np.float32)
    x[:4] = [[0.0] * x.shape[1], [1.0] * x.shape[1], [0.5] * x.shape[1], [0.25] * x.shape[1]]
    reference, bound = bound_model(config, params, x, dtype)
    return assert_within(twin(bundle, x), reference, bound, json.dumps(config))


# --- layout, by hand --------------------------------------------------------------------------

def test_nerf_density_parameter_count():
    """Hash 16 levels x 2 features, 2^19 rows, base 16, per-level scale 1.3819128799677 (float32
    1.3819128): scale_l = 16 * 1.3819128^l - 1 = 15, 21.11, 29.55, 41.22, 57.35, 79.63, ...;
    resolution = ceil + 1 = 16, 23, 31, 43, 59, 81; rows = resolution^3 rounded up to 8, capped at
    2^19: 4096, 12168, 29792, 79512, 205384, then 524288 (81^3 = 531441 > 2^19) for levels 5..15.
    Table: (330952 + 11 * 524288) * 2 = 12196240. FullyFusedMLP: the 32 encoded lanes are already a
    multiple of 16; 64x32 + 16x64 = 3072. Network first: 12199312 in all."""
    rows = [4096, 12168, 29792, 79512, 205384] + [524288] * 11
    model = parse_model(NERF_DENSITY, "nerf")
    assert [lv.rows for lv in model.encoding.grid_levels] == rows
    assert [lv.resolution for lv in model.encoding.grid_levels][:6] == [16, 23, 31, 43, 59, 81]
    assert model.network.shapes == [(64, 32), (16, 64)]
    assert model.n_params() == ref.build(NERF_DENSITY)["n_params"] == 12199312
    assert [t[2] for t in ref.build(NERF_DENSITY)["encoding"]["table"]] == rows


@pytest.mark.parametrize("encoding, dims, expected", [
    # 2D hash, base 16, scale 2, 2^10 rows: scales 15, 31, 63; 16^2 = 256 and 32^2 = 1024 fit (dense
    # indexing), 64^2 = 4096 > 1024 is hashed into 1024 rows
    ({"otype": "HashGrid", "n_levels": 3, "log2_hashmap_size": 10, "base_resolution": 16, "per_level_scale": 2.0},
     2, [(16, 256, 0, True), (32, 1024, 256, True), (64, 1024, 1280, False)]),
    # 3D hash, base 4, scale 2, 2^8 rows: 4^3 = 64 fits; 8^3 = 512 and 16^3 = 4096 are hashed into 256
    ({"otype": "HashGrid", "n_levels": 3, "log2_hashmap_size": 8, "base_resolution": 4, "per_level_scale": 2.0},
     3, [(4, 64, 0, True), (8, 256, 64, False), (16, 256, 320, False)]),
    # Dense 2D, base 16, 5 levels, no per_level_scale: exp(log(256 / 16) / 4) = 2 (in float), so
    # resolutions 16 .. 256 and every level dense: 256, 1024, 4096, 16384, 65536 rows
    ({"otype": "DenseGrid", "n_levels": 5, "base_resolution": 16}, 2,
     [(16, 256, 0, True), (32, 1024, 256, True), (64, 4096, 1280, True), (128, 16384, 5376, True),
      (256, 65536, 21760, True)]),
    # 2D hash, base 3, scale 1.5, 2^6 rows: scales 2, 3.5, 5.75 -> resolutions 3, 5, 7; 9 -> 16 rows
    # (multiple of 8), 25 -> 32, 49 -> 56 > 2^6? no: 56 <= 64, all dense
    ({"otype": "Grid", "type": "Hash", "n_levels": 3, "log2_hashmap_size": 6, "base_resolution": 3,
      "per_level_scale": 1.5}, 2, [(3, 16, 0, True), (5, 32, 16, True), (7, 56, 48, True)]),
])
def test_level_resolutions_rows_and_offsets(encoding, dims, expected):
    cfg = {"n_input_dims": dims, "encoding": encoding}
    levels = parse_model(cfg, "c").encoding.grid_levels
    assert [(lv.resolution, lv.rows, lv.offset, lv.dense) for lv in levels] == expected
    table = ref.build(cfg)["encoding"]["table"]
    assert [(res, rows, off) for _, res, rows, off in table] == [e[:3] for e in expected]


@pytest.mark.parametrize("encoding, dims, out, pads", [
    # (computed lanes, [(pad count, value, first?)]): network alignment 16
    ({"otype": "Frequency", "n_frequencies": 4}, 3, 24, (8, 1.0, False)),           # 3 * 4 * 2 = 24 -> 32
    ({"otype": "SphericalHarmonics", "degree": 3}, 3, 9, (7, 1.0, True)),          # 9 -> 16, ones first
    ({"otype": "Identity"}, 3, 3, (13, 1.0, False)),                               # 3 -> 16
    ({"otype": "HashGrid", "n_levels": 3, "log2_hashmap_size": 8}, 3, 6, (10, 0.0, False)),   # 6 -> 16, zeros
    ({"otype": "TriangleWave", "n_frequencies": 4}, 2, 8, (8, 1.0, False)),
    ({"otype": "OneBlob", "n_bins": 4}, 3, 12, (4, 1.0, False)),
])
def test_padding_lanes(encoding, dims, out, pads):
    cfg = {"n_input_dims": dims, "n_output_dims": 1, "encoding": encoding,
           "network": {"otype": "CutlassMLP", "n_hidden_layers": 0}}
    enc = parse_model(cfg, "c").encoding
    assert (enc.out, enc.pad, enc.pad_value, enc.pad_first) == (out, *pads)
    e = ref.build(cfg)["encoding"]
    assert (e["out"], e["pad"], e["pad_value"], e["pad_first"]) == (out, *pads)


def test_composite_pads_each_part_to_the_next_ones_alignment():
    """Identity (1 lane) then a grid of 4 features per level: the identity is padded with 3 ones to
    lane 4 (the grid's required alignment), the grid gives 2 * 4 = 8 lanes: 12, padded to 16 with 4
    zeros on the grid (the last part). As an Encoding module (alignment 0) the 12 stay 12."""
    nested = [{"n_dims_to_encode": 1, "otype": "Identity"},
              {"otype": "HashGrid", "n_levels": 2, "n_features_per_level": 4, "log2_hashmap_size": 6}]
    net = parse_model({"n_input_dims": 3, "n_output_dims": 1, "encoding": {"otype": "Composite", "nested": nested},
                       "network": {"otype": "CutlassMLP", "n_hidden_layers": 0}}, "c").encoding
    assert [(n.out, n.pad) for n in net.nested] == [(1, 3), (8, 4)] and net.padded == 16
    alone = parse_model({"n_input_dims": 3, "encoding": {"otype": "Composite", "nested": nested}}, "c")
    assert [(n.out, n.pad) for n in alone.encoding.nested] == [(1, 3), (8, 0)] and alone.n_output_dims == 12


def test_weight_matrices_are_row_major_out_by_in_and_padding_lanes_hold_ones():
    """CutlassMLP without hidden layers: one matrix of 16 rows (3 outputs padded to 16) x 16 columns
    (2 inputs, Identity-padded with 14 ones). With params = 0, 1, 2, ..., W[r, c] = 16 r + c, so
    y_r = (16 r) a + (16 r + 1) b + sum_{c=2}^{15} (16 r + c) = 16 r a + (16 r + 1) b + 224 r + 119."""
    cfg = {"n_input_dims": 2, "n_output_dims": 3, "network": {"otype": "CutlassMLP", "n_hidden_layers": 0,
                                                               "output_activation": "None"}}
    params = np.arange(256, dtype=np.float32)
    bundle, _ = to_bundle(cfg, params, "float32")
    x = np.array([[0.25, 0.5], [1.0, 0.0], [0.0, 0.0]], np.float32)
    r = np.arange(3)
    expected = 16 * r * x[:, :1] + (16 * r + 1) * x[:, 1:] + 224 * r + 119
    np.testing.assert_allclose(twin(bundle, x), expected, rtol=1e-6)


def test_network_parameters_come_before_the_encodings():
    """NetworkWithInputEncoding: the network's 16 x 16 matrix first, then the grid's table. A table
    holding 0.75 everywhere interpolates to 0.75 in every lane (the corner weights sum to 1); a
    matrix picking lane 0 into output 0 and lane 5 into output 1 gives (0.75, 0.75), and the
    padding lanes (zeros for a grid) add nothing."""
    cfg = {"n_input_dims": 2, "n_output_dims": 2,
           "encoding": {"otype": "HashGrid", "n_levels": 3, "n_features_per_level": 2, "log2_hashmap_size": 6,
                        "base_resolution": 4},
           "network": {"otype": "CutlassMLP", "n_hidden_layers": 0}}
    model = parse_model(cfg, "c")
    w = np.zeros((16, 16), np.float32)
    w[0, 0] = w[1, 5] = 1.0
    w[:, 6:] = 7.0                       # on the 10 zero lanes: no effect
    table = np.full(model.encoding.n_params(), 0.75, np.float32)
    bundle, _ = to_bundle(cfg, np.concatenate([w.reshape(-1), table]), "float32")
    x = np.random.default_rng(0).uniform(0, 1, (20, 2)).astype(np.float32)
    np.testing.assert_allclose(twin(bundle, x), 0.75, rtol=1e-6)


# --- the hash ---------------------------------------------------------------------------------

@pytest.mark.parametrize("dims", [2, 3])
@pytest.mark.parametrize("hash_name", ["coherentprime", "prime", "reversedprime"])
def test_vertex_index_bit_identical_to_tiny_cuda_nn(dims, hash_name):
    """Integer coordinates up to 2^16 per axis: hashed levels (2^19 rows) and levels indexed
    densely (a resolution whose cube fits), both through inshade.grid_layout and the reference."""
    rng = np.random.default_rng(dims)
    coords = rng.integers(0, (1 << 16) + 1, (20000, dims))
    coords[:4] = [[0] * dims, [1 << 16] * dims, [(1 << 16) - 1] * dims, [12345] * dims]
    primes = HASH_PRIMES[{"coherentprime": "coherent_prime", "prime": "prime", "reversedprime": "reversed_prime"}[
        hash_name]]
    for resolution, rows in ((65537, 1 << 19), (1 << 14, 1 << 19), (40, 64000), (20, 8000)):
        dense = resolution ** dims <= rows
        level = GridLevel(np.float32(resolution - 1), resolution, rows, 0, dense)
        ours = vertex_index(coords, level, primes)
        theirs = ref.grid_index(coords, resolution, rows, "hash", hash_name)
        assert np.array_equal(ours, theirs), (resolution, rows)


# --- encodings against the reference ----------------------------------------------------------

GRID_2D = {"otype": "HashGrid", "n_levels": 5, "n_features_per_level": 2, "log2_hashmap_size": 9,
           "base_resolution": 4, "per_level_scale": 1.7}
GRID_3D = {"otype": "HashGrid", "n_levels": 4, "n_features_per_level": 4, "log2_hashmap_size": 10,
           "base_resolution": 5, "per_level_scale": 1.41}
DENSE_2D = {"otype": "DenseGrid", "n_levels": 3, "n_features_per_level": 1, "base_resolution": 8}
ENCODINGS = {   # name: (config, input lanes)
    "hash_2d": (GRID_2D, 2), "hash_3d": (GRID_3D, 3), "dense_2d": (DENSE_2D, 2),
    "dense_3d_prime": ({"otype": "Grid", "type": "Dense", "n_levels": 2, "base_resolution": 6,
                        "per_level_scale": 1.5, "hash": "Prime"}, 3),
    "identity": ({"otype": "Identity", "scale": 1.7, "offset": -0.3}, 3),
    "frequency": ({"otype": "Frequency", "n_frequencies": 5}, 3),
    "spherical_harmonics": ({"otype": "SphericalHarmonics", "degree": 5}, 3),
    "one_blob": ({"otype": "OneBlob", "n_bins": 8}, 2),
    "triangle_wave": ({"otype": "TriangleWave", "n_frequencies": 6}, 2),
    "composite": ({"otype": "Composite", "nested": [
        {"n_dims_to_encode": 3, "otype": "HashGrid", "n_levels": 3, "n_features_per_level": 2,
         "log2_hashmap_size": 8, "base_resolution": 4},
        {"n_dims_to_encode": 3, "otype": "SphericalHarmonics", "degree": 3},
        {"n_dims_to_encode": 1, "otype": "Empty"},
        {"otype": "TriangleWave", "n_frequencies": 3}]}, 8),
    "composite_begins": ({"otype": "Composite", "nested": [
        {"n_dims_to_encode": 2, "dims_to_encode_begin": 1, "otype": "Frequency", "n_frequencies": 2},
        {"n_dims_to_encode": 1, "dims_to_encode_begin": 0, "otype": "Identity", "scale": 2.0}]}, 3),
    "nrc": ({"otype": "NRC", "n_frequencies": 4, "n_bins": 4}, 10),
}


@pytest.mark.parametrize("name", sorted(ENCODINGS))
@pytest.mark.parametrize("dtype", ["float32", "float16"])
def test_encoding_matches_tiny_cuda_nn(name, dtype):
    """Encoding modules (tcnn.Encoding): the lanes one by one, pads included, under lane_bounds."""
    enc, dims = ENCODINGS[name]
    compare({"n_input_dims": dims, "encoding": enc}, dtype)


def test_spherical_harmonics_degrees_and_sign_conventions():
    """Every degree 1..5 on inputs in [0, 1]^3 (tiny-cuda-nn's (v + 1) / 2): inshade's
    spherical_harmonics (SH_TERMS) after x * 2 - 1 is sh_enc, lane for lane."""
    for degree in range(1, 6):
        compare({"n_input_dims": 3, "encoding": {"otype": "SphericalHarmonics", "degree": degree}}, n=500)


# --- models: every encoding x network -----------------------------------------------------------

NETWORKS = {
    "fully_fused": {"otype": "FullyFusedMLP", "n_neurons": 16, "n_hidden_layers": 2, "activation": "ReLU",
                    "output_activation": "None"},
    "cutlass": {"otype": "CutlassMLP", "n_neurons": 24, "n_hidden_layers": 1, "activation": "Tanh",
                "output_activation": "Sigmoid"},
    "cutlass_linear": {"otype": "CutlassMLP", "n_hidden_layers": 0},
}


@pytest.mark.parametrize("network", sorted(NETWORKS))
@pytest.mark.parametrize("name", sorted(ENCODINGS))
def test_model_matches_tiny_cuda_nn(name, network):
    enc, dims = ENCODINGS[name]
    dtype = "float16" if network == "fully_fused" else "float32"   # FullyFusedMLP is a half-precision network
    compare({"n_input_dims": dims, "n_output_dims": 3, "encoding": enc, "network": NETWORKS[network]}, dtype)


def test_network_without_encoding_is_an_mlp_on_the_raw_inputs():
    """A network-only config (tcnn.Network): Identity underneath, inputs padded with ones to 16."""
    compare({"n_input_dims": 5, "n_output_dims": 2, "network": NETWORKS["fully_fused"]}, "float16")
    compare({"n_input_dims": 17, "n_output_dims": 18, "network": NETWORKS["cutlass"]})


@pytest.mark.parametrize("act", ["None", "ReLU", "LeakyReLU", "SiLU", "Exponential", "Sine", "Sigmoid",
                                 "Squareplus", "Softplus", "Tanh"])
def test_every_activation_hidden_and_output(act):
    net = {"otype": "CutlassMLP", "n_neurons": 16, "n_hidden_layers": 2, "activation": act, "output_activation": act}
    for dtype in ("float32", "float16"):
        compare({"n_input_dims": 3, "n_output_dims": 4, "encoding": {"otype": "Frequency", "n_frequencies": 2},
                 "network": net}, dtype, weight_gain=0.5 if act == "Exponential" else 1.0)


# --- activations: the lowering is tiny-cuda-nn's function -------------------------------------

def activation_graph(names, dtype: str) -> GraphModule:
    """x (1 lane) -> one output per activation, each lowered as the converter lowers it."""
    b = Builder(parse_model({"n_input_dims": 1, "n_output_dims": 1, "network": {}}, "acts"))
    for name in names:
        b.g.output(f"y_{name}", ACTIVATIONS[name](b, "x", dtype, name))
    return b.g


TCNN_ACTIVATIONS = ["relu", "leakyrelu", "silu", "exponential", "sine", "sigmoid", "squareplus", "softplus", "tanh"]


@pytest.mark.parametrize("dtype", ["float32", "float16"])
def test_activation_lowerings_are_tiny_cuda_nns_functions(dtype):
    """common_device.h warp_activation in float32 (the reference) against the components the
    converter emits, on x in [-8, 8] (Exponential to 4): within 8 ulp of max(1, |y|)."""
    x = np.concatenate([np.linspace(-8, 8, 4001), [0.0, -0.0, 1e-30, -1e-30]]).astype(np.float32)[:, None]
    g = activation_graph(TCNN_ACTIVATIONS, dtype)
    for k, name in enumerate(TCNN_ACTIVATIONS):
        xs = np.minimum(x, 4.0) if name == "exponential" else x
        with torch.no_grad():
            ours = g(torch.from_numpy(xs)).numpy()[:, k]
        theirs = ref.activation(name, torch.from_numpy(xs), dtype).numpy()[:, 0]
        err = np.abs(ours.astype(np.float64) - theirs) / np.maximum(1.0, np.abs(theirs))
        assert err.max() <= 8 * U, (name, float(err.max()), float(xs[int(np.argmax(err)), 0]))


def test_leaky_relu_slope_is_the_networks_precision_and_softplus_overflow_differs():
    """LeakyReLU multiplies by (T)0.01f: 0.01000213623046875 in a half-precision network. Softplus
    as tiny-cuda-nn writes it, log(exp(10 x) + 1) / 10, overflows to inf above x = 8.8723 in
    float32; inshade's softplus (beta 10) stays finite there (x): the one place they differ."""
    assert leaky_slope("float16") == 0.01000213623046875 and leaky_slope("float32") == float(np.float32(0.01))
    x = torch.tensor([[8.8], [8.9], [20.0]])
    assert torch.isinf(ref.activation("softplus", x[1:])).all() and torch.isfinite(ref.activation("softplus", x[:1])).all()
    with torch.no_grad():
        ours = activation_graph(["softplus"], "float32")(x).numpy()[:, 0]
    np.testing.assert_allclose(ours, [8.8, 8.9, 20.0], rtol=1e-6)


# --- the GLSL, through the driver -------------------------------------------------------------

def test_glsl_of_every_activation_lowering(gl):
    g = activation_graph(TCNN_ACTIVATIONS, "float16")
    bundle = g.export("imported", "tcnn_activations")
    x = np.concatenate([np.linspace(-8, 4, 509), [0.0, 1e-3, -1e-3]]).astype(np.float32)[:, None]
    check_parity(gl, bundle, x)


@pytest.mark.parametrize("config, dtype", [
    ({"n_input_dims": 3, "n_output_dims": 4, "encoding": GRID_3D, "network": NETWORKS["fully_fused"]}, "float16"),
    ({"n_input_dims": 8, "n_output_dims": 3, "encoding": ENCODINGS["composite"][0],
      "network": {"otype": "CutlassMLP", "n_neurons": 16, "n_hidden_layers": 1, "activation": "Squareplus",
                  "output_activation": "Softplus"}}, "float32"),
    ({"n_input_dims": 3, "encoding": {"otype": "Composite", "nested": [
        {"n_dims_to_encode": 2, "otype": "DenseGrid", "n_levels": 2, "n_features_per_level": 4, "base_resolution": 4,
         "per_level_scale": 1.8},
        {"otype": "Frequency", "n_frequencies": 3}, ]}}, "float32"),
], ids=["hash3d_fully_fused", "composite_cutlass", "encoding_only"])
def test_glsl_matches_the_twin(gl, config, dtype):
    params = random_params(config, dtype, seed=3)
    bundle, _ = to_bundle(config, params, dtype)
    x = np.random.default_rng(4).uniform(0, 1, (512, config["n_input_dims"])).astype(np.float32)
    check_parity(gl, bundle, x)


# --- the command line ---------------------------------------------------------------------------

SMALL = {"n_input_dims": 3, "n_output_dims": 4,
         "encoding": {"otype": "Composite", "nested": [
             {"n_dims_to_encode": 2, "otype": "HashGrid", "n_levels": 4, "n_features_per_level": 2,
              "log2_hashmap_size": 8, "base_resolution": 4, "per_level_scale": 1.5},
             {"otype": "SphericalHarmonics", "degree": 1, "n_dims_to_encode": 0},
             {"otype": "Frequency", "n_frequencies": 3}]},
         "network": {"otype": "FullyFusedMLP", "n_neurons": 16, "n_hidden_layers": 1, "activation": "ReLU",
                     "output_activation": "Sigmoid"},
         "loss": {"otype": "L2"}}


def _write(tmp_path: Path, config: dict, params: np.ndarray, name: str = "m") -> tuple[Path, Path]:
    cfg = tmp_path / f"{name}.json"
    cfg.write_text(json.dumps(config))
    p = tmp_path / f"{name}.npy"
    np.save(p, params)
    return cfg, p


def test_cli_convert_end_to_end(gl, tmp_path, capsys):
    params = random_params(SMALL, "float16").astype(np.float16)
    cfg, p = _write(tmp_path, {**SMALL, "comment": "kept aside"}, params)
    assert main(["convert", str(cfg), str(p), "-o", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "torch twin" in err and "tiny-cuda-nn needs CUDA" in err and "(rule 1e-05): ok" in err
    assert "ignores comment" in err
    bundle = load(tmp_path / "out")
    prov = bundle.meta["provenance"]
    assert (prov["source"], prov["model"], prov["params_dtype"], prov["params_count"]) == (
        "tiny-cuda-nn", "NetworkWithInputEncoding", "float16", params.size)
    assert prov["config"] == str(cfg) and prov["params"] == str(p) and prov["check"]["ok"]
    assert prov["ignored_keys"] == ["comment"] and bundle.meta["kind"] == "imported"
    assert prov["resolved"]["network"]["otype"] == "FullyFusedMLP"
    grid = next(n for n in bundle.nodes if n.type == "hash_grid")
    assert grid.params["precision"] == "f16"
    x = np.random.default_rng(0).uniform(0, 1, (200, 3)).astype(np.float32)
    reference, bound = bound_model(SMALL, params.astype(np.float32), x, "float16")
    assert_within(twin(bundle, x), reference, bound, "written bundle")


def test_cli_inputs_outputs_options_and_as_image(tmp_path):
    config = {"encoding": {"otype": "HashGrid", "n_levels": 3, "n_features_per_level": 2, "log2_hashmap_size": 8,
                           "base_resolution": 4}, "network": NETWORKS["cutlass"]}
    params = random_params({**config, "n_input_dims": 2, "n_output_dims": 3})
    cfg, p = _write(tmp_path, config, params)
    assert main(["convert", str(cfg), str(p), "-o", str(tmp_path / "img"), "--inputs", "2", "--outputs", "3",
                 "--as", "image", "--no-check"]) == 0
    bundle = load(tmp_path / "img")
    assert bundle.meta["render"]["program"] == "passes/field2d.frag" and bundle.out_dim == 3


def test_parameter_files(tmp_path):
    """.npy, .bin (fp16 by its length, fp32 by its length), .safetensors and .pt hold the same values."""
    from safetensors.numpy import save_file

    values = np.random.default_rng(0).uniform(-1, 1, 100).astype(np.float16)
    (tmp_path / "a.bin").write_bytes(values.astype("<f2").tobytes())
    (tmp_path / "b.bin").write_bytes(values.astype("<f4").tobytes())
    save_file({"params": values, "other": np.zeros(3, np.float32)}, str(tmp_path / "c.safetensors"))
    torch.save({"model": {"field.mlp.params": torch.from_numpy(values), "step": torch.tensor(7)}}, tmp_path / "d.pt")
    torch.save(torch.from_numpy(values.astype(np.float32)), tmp_path / "e.pth")
    np.save(tmp_path / "f.npy", values)
    expect = values.astype(np.float32)
    for name, dtype in (("a.bin", "float16"), ("b.bin", "float32"), ("c.safetensors", "float16"),
                        ("d.pt", "float16"), ("e.pth", "float32"), ("f.npy", "float16")):
        got, stored = read_params(tmp_path / name, 100)
        assert stored == dtype and np.array_equal(got, expect), name


# --- refusals: one line, exit status 2, nothing written ----------------------------------------

def _edit(config: dict, path: str, value) -> dict:
    out = json.loads(json.dumps(config))
    *keys, last = path.split(".")
    node = out
    for k in keys:
        node = node[int(k)] if isinstance(node, list) else node[k]
    if value is None:
        del node[last]
    else:
        node[last] = value
    return out


GRID_NET = {"n_input_dims": 3, "n_output_dims": 2, "encoding": dict(GRID_3D), "network": NETWORKS["fully_fused"]}
REFUSALS = {   # name: (config, params dtype, params count change, expected in the message)
    "wrong_count": (GRID_NET, "float16", -1, "needs 11424: network 768"),
    "encoding_otype": (_edit(GRID_NET, "encoding.otype", "Spline"), "float16", 0, "encoding.otype: 'Spline'"),
    "network_otype": (_edit(GRID_NET, "network.otype", "ResNet"), "float16", 0, "network.otype: 'ResNet'"),
    "tiled": (_edit(GRID_NET, "encoding.type", "Tiled"), "float16", 0, "encoding.type: Tiled grids"),
    "nearest": (_edit(GRID_NET, "encoding.interpolation", "Nearest"), "float16", 0, "encoding.interpolation"),
    "smoothstep": (_edit(GRID_NET, "encoding.interpolation", "Smoothstep"), "float16", 0, "encoding.interpolation"),
    "fixed_point": (_edit(GRID_NET, "encoding.fixed_point_pos", True), "float16", 0, "encoding.fixed_point_pos"),
    "grid_4d": ({**GRID_NET, "n_input_dims": 4}, "float16", 0, "a grid over 4 input lanes"),
    "rng_hash": (_edit(GRID_NET, "encoding.hash", "Rng"), "float16", 0, "encoding.hash"),
    "sh_degree": ({"n_input_dims": 3, "n_output_dims": 1, "encoding": {"otype": "SphericalHarmonics", "degree": 6},
                   "network": NETWORKS["cutlass_linear"]}, "float32", 0, "encoding.degree"),
    "neurons_fp16": (_edit(GRID_NET, "network.n_neurons", 48), "float16", 0, "network.n_neurons: 48"),
    "sine_fp16": (_edit(GRID_NET, "network.activation", "Sine"), "float16", 0, "network.activation: Sine"),
    "activation_name": (_edit(GRID_NET, "network.output_activation", "GELU"), "float16", 0,
                        "network.output_activation"),
    "reduction": ({"n_input_dims": 3, "encoding": {"otype": "Composite", "reduction": "Sum",
                                                   "nested": [{"otype": "Identity"}]}}, "float32", 0,
                  "encoding.reduction"),
    "no_input_dims": (_edit(GRID_NET, "n_input_dims", None), "float16", 0, "n_input_dims: missing"),
    "scale_below_one": (_edit(GRID_NET, "encoding.per_level_scale", 0.5), "float16", 0, "per_level_scale"),
    "dense_one_level": ({"n_input_dims": 2, "encoding": {"otype": "DenseGrid", "n_levels": 1}}, "float32", 0,
                        "encoding.per_level_scale: missing"),
    "float64": (GRID_NET, "float64", 0, "dtype float64"),
    "nan": (GRID_NET, "nan", 0, "NaN or Inf"),
}


def _params_for(config, dtype, change):
    model = ref.build(config) if "n_input_dims" in config else ref.build({**config, "n_input_dims": 3})
    n = model["n_params"] + change
    if dtype == "nan":
        out = np.zeros(n, np.float16)
        out[5] = np.nan
        return out
    return np.zeros(n, dtype)


@pytest.mark.parametrize("name", sorted(REFUSALS))
def test_refusals(tmp_path, capsys, name):
    config, dtype, change, expected = REFUSALS[name]
    try:
        params = _params_for(config, dtype, change)
    except (KeyError, ValueError, ZeroDivisionError, OverflowError):   # the reference has no such model either
        params = np.zeros(10, np.float32)
    cfg, p = _write(tmp_path, config, params)
    out = tmp_path / "out"
    assert main(["-q", "convert", str(cfg), str(p), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("inshade: error: "), err
    assert expected in err[0], err[0]
    assert not out.exists()


def test_refusals_of_the_files_themselves(tmp_path, capsys):
    cfg, p = _write(tmp_path, GRID_NET, _params_for(GRID_NET, "float16", 0))
    (tmp_path / "bad.json").write_text("{not json")
    (tmp_path / "x.bin").write_bytes(b"\0" * 10)
    (tmp_path / "x.onnx").write_bytes(b"")
    cases = [
        (["convert", str(tmp_path / "bad.json"), str(p)], "bad.json: not valid JSON"),
        (["convert", str(cfg), str(tmp_path / "x.bin")], "x.bin: 10 bytes; the config needs 11424 parameters"),
        (["convert", str(cfg)], "needs its PARAMS file"),
        (["convert", str(tmp_path / "x.onnx"), str(p)], "PARAMS is for tiny-cuda-nn models"),
        (["convert", str(cfg), str(p), "--inputs", "2"], "n_input_dims: 3, but --inputs says 2"),
        (["convert", str(cfg), str(tmp_path / "m.txt")], "unknown parameter file format '.txt'"),
    ]
    for argv, expected in cases:
        assert main(["-q", *argv, "-o", str(tmp_path / "out")]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and expected in err[0], (argv, err)
        assert not (tmp_path / "out").exists()


def test_refusal_through_the_executable(tmp_path):
    """The installed command path: a subprocess, one line on stderr, status 2, no traceback."""
    cfg, p = _write(tmp_path, GRID_NET, _params_for(GRID_NET, "float16", 3))
    r = subprocess.run([sys.executable, "-m", "inshade.cli", "-q", "convert", str(cfg), str(p), "-o",
                        str(tmp_path / "out")], capture_output=True, text=True, cwd=tmp_path, timeout=120,
                       env=dict(os.environ, PYTHONPATH=str(REPO)))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "11427 parameters" in lines[0] and "needs 11424" in lines[0], r.stderr
    assert not (tmp_path / "out").exists()


def test_convert_error_from_python_names_the_count():
    with pytest.raises(ConvertError, match=r"7 parameters; the config needs 12199312: network 3072"):
        to_bundle(NERF_DENSITY, np.zeros(7, np.float32), "float16")


def test_grid_layout_levels_are_tiny_cuda_nns_for_common_configs():
    """grid_layout (what the hash_grid component uses) against the reference's offset table for the
    per-level scales instant-ngp and nerfstudio ship: the same resolutions, rows and offsets."""
    for pls in (1.3819128799677, 1.447269237440378, 1.5, 2.0, 1.26):
        for dims in (2, 3):
            ours = grid_levels(dims, 16, 16, pls, 19, "hash")
            theirs = ref.grid_offsets(dims, 16, 16, np.float32(pls), 19, "hash")
            assert [(lv.resolution, lv.rows, lv.offset) for lv in ours] == [t[1:] for t in theirs], (pls, dims)
