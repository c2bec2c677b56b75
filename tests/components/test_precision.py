"""Dense weights at f16 and i8 (inshade/quantize.py): the bundle holds the values the precision gives,
the shader rebuilds exactly those from what it stores (float16 texture rows; int8 codes + 128 in an
RGBA8 texture, times the row scales), so every storage stays under the parity rule against the
quantized network's torch twin; the quantization's own error is reported beside it."""
from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

import inshade
from inshade.bundle import Bundle, BundleError
from inshade.codegen import generate
from inshade.components.unorm import decode
from inshade.convert.lowering import ConvertError
from inshade.quantize import I8_MAX, i8_codes, quantized, weight_bytes

from parity import (MLPSpec, assert_parity, build_mlp, glsl_eval, mlp_specs, parity_settings, spec_inputs,
                    torch_reference)

STORAGES = ("inline", "ubo", "texture")


@pytest.mark.parametrize("storage", STORAGES)
@pytest.mark.parametrize("precision", ["f16", "i8"])
@parity_settings(max_examples=6)
@given(data=st.data())
def test_every_storage_holds_the_rule_against_the_quantized_twin(gl, precision, storage, data):
    spec = data.draw(mlp_specs(max_width=48 if storage != "ubo" else 16, block_budget=120), label="spec")
    bundle = quantized(build_mlp(spec).export("mlp"), precision)
    x = spec_inputs(spec, 200)
    out = glsl_eval(gl, bundle, x, storage=storage)
    assert_parity(out, torch_reference(bundle, x), what=f"{precision} {storage} {spec}")


def _mlp(seed: int = 0, widths=(2, 48, 48, 3)):
    torch.manual_seed(seed)
    layers = []
    for a, b in zip(widths, widths[1:]):
        layers += [torch.nn.Linear(a, b), torch.nn.ReLU()]
    return torch.nn.Sequential(*layers[:-1], torch.nn.Sigmoid())


def test_the_bundle_holds_what_each_precision_stores():
    bundle = _export_bundle()
    half, eight = quantized(bundle, "f16"), quantized(bundle, "i8")
    for n in (n for n in half.nodes if n.type == "dense"):
        w = half.tensor(n, "weight")
        assert n.params["precision"] == "f16" and np.array_equal(w.astype(np.float16).astype(np.float32), w)
    for n in (n for n in eight.nodes if n.type == "dense"):
        w, s = eight.tensor(n, "weight"), eight.tensor(n, "weight_scale")
        q = i8_codes(w, s)
        assert np.abs(q).max() == I8_MAX   # symmetric: the row's largest weight takes the last code
        assert np.array_equal(q.astype(np.float32) * s[:, None], w)
    full = weight_bytes(bundle)
    assert weight_bytes(half) == full // 2 and weight_bytes(eight) < full / 3   # biases and scales are float32


def _export_bundle():
    """An MLP bundle 2 -> 48 -> 48 -> 3 (dense nodes l0, l1, l2)."""
    return build_mlp(MLPSpec([2], [48, 48], [("relu", {}), ("relu", {})], 3, ("sigmoid", {}), None,
                             [True, True, True], seed=5)).export("mlp")


def test_a_bundle_whose_numbers_are_not_its_precisions_is_refused():
    bundle = quantized(_export_bundle(), "i8")
    tensors = dict(bundle.tensors)
    tensors["l0.weight"] = tensors["l0.weight"].copy()
    tensors["l0.weight"][0, 0] *= 1.001
    with pytest.raises(BundleError, match=r"l0.weight: value .* is not an int8 code in \[-127, 127\] times its "
                                          r"row's scale .* \(the node's precision i8\)"):
        Bundle(bundle.meta, tensors)
    half = quantized(_export_bundle(), "f16")
    tensors = dict(half.tensors)
    tensors["l1.bias"] = tensors["l1.bias"] + np.float32(1e-6)
    with pytest.raises(BundleError, match="l1.bias: value .* is not representable as float16"):
        Bundle(half.meta, tensors)
    with pytest.raises(ValueError, match="precision 'f8': choose from f32, f16, i8"):
        quantized(bundle, "f8")


def test_textures_and_blocks_store_the_precisions_bytes():
    bundle = _export_bundle()
    sizes = {p: sum(r.texture_bytes for r in generate(quantized(bundle, p), storage="texture").plan.rows)
             for p in ("f32", "f16", "i8")}
    assert sizes["f16"] == sizes["f32"] // 2
    assert sizes["i8"] < sizes["f32"] // 3   # a byte a weight, and float32 biases and row scales
    blocks = {p: sum(r.uniform_bytes for r in generate(quantized(bundle, p), storage="ubo").plan.rows)
              for p in ("f32", "f16", "i8")}
    # the float32 biases (and i8's scales) sit beside the weights
    assert blocks["f16"] < 0.55 * blocks["f32"] and blocks["i8"] < 0.35 * blocks["f32"], blocks
    ubo = generate(quantized(bundle, "f16"), storage="ubo")
    assert "precision f16: float16 pairs in uvec4s" in ubo.plan.report()
    i8 = generate(quantized(bundle, "i8"), storage="texture")
    assert [(r.name, r.dtype) for r in i8.resources] == [("net_weights_i8", "u1"), ("net_weights_i8_rows", "f4")]
    unorm = generate(quantized(bundle, "i8"), storage="texture", options={"dense": {"i8_texels": "unorm"}})
    assert [r.dtype for r in unorm.resources] == ["f1", "f4"]   # an engine's image file
    assert "precision i8: int8 codes" in i8.plan.report()


def test_export_checks_the_twin_and_reports_the_quantization(tmp_path, capsys):
    saved = inshade.export(_mlp(), torch.rand(64, 2), tmp_path / "half", precision="f16")
    err = capsys.readouterr().err
    assert "max |glsl - twin| = " in err and "(rule 1e-05): ok" in err
    assert "quantization (f16, dense weights " in err and "max |twin - source| = " in err
    assert " dB on the example" in err
    record = saved.meta["provenance"]["precision"]
    assert record["requested"] == "f16" and record["bytes"] * 2 == record["fp32_bytes"] and record["psnr"] > 40
    with pytest.raises(ConvertError, match="precision: precision 'f7': choose from f32, f16, i8"):
        inshade.export(_mlp(), torch.rand(64, 2), tmp_path / "bad", precision="f7", quiet=True)


def test_max_error_picks_a_precision_per_layer_and_says_why(tmp_path, capsys):
    """A network whose middle layer has one weight far out of its rows' range: int8 codes flatten the
    rest of that row, so that layer keeps more bits while the others go to i8."""
    module = _mlp(3, (2, 32, 32, 32, 3))
    with torch.no_grad():
        module[2].weight[:, 0] = 6.0   # every row of the middle layer: one large weight, the rest small
    x = torch.rand(256, 2)
    bound = 2e-3
    saved = inshade.export(module, x, tmp_path / "mixed", max_error=bound)
    err = capsys.readouterr().err
    chosen = {n.id: n.params["precision"] for n in saved.nodes if n.type == "dense"}
    assert len(set(chosen.values())) > 1, (chosen, err)
    assert "precision per layer:" in err and f"bound {bound:g}" in err
    assert saved.meta["provenance"]["precision"]["max_abs"] <= bound


def test_codegen_precision_checks_the_code_and_reports_the_quantization(tmp_path, capsys):
    from inshade import cli

    _export_bundle().save(tmp_path / "mlp")
    assert cli.main(["codegen", str(tmp_path / "mlp"), "--precision", "i8", "--storage", "texture", "--check",
                     "-o", str(tmp_path / "net.glsl")]) == 0
    out = capsys.readouterr().out
    assert "precision i8: int8 codes (RGBA8UI" in out and "(rule 1e-05): ok" in out
    assert "quantization (i8, dense weights " in out and "max |twin - fp32 twin| = " in out


def test_a_table_at_f32_goes_to_its_f16_form(gl):
    """A hash grid stored at f32 (its own precision parameter): f16 stores it at f16, whose numbers the
    shader reads as the twin does."""
    import copy

    from inshade.bundle import load
    from inshade.scene.description import resolve_asset

    shipped = load(resolve_asset("hash_grid_image"))
    grid = next(n for n in shipped.nodes if n.type == "hash_grid")
    meta = copy.deepcopy(shipped.meta)
    next(n for n in meta["nodes"] if n["id"] == grid.id)["params"]["precision"] = "f32"
    tensors = dict(shipped.tensors)
    table = grid.tensor_name("table")
    tensors[table] = tensors[table] + np.random.default_rng(0).uniform(-1e-4, 1e-4, tensors[table].shape).astype(
        np.float32)   # float32 values float16 cannot hold
    q = quantized(Bundle(meta, tensors), "f16")
    assert q.node(grid.id).params["precision"] == "f16"
    t = q.tensors[table]
    assert np.array_equal(t.astype(np.float16).astype(np.float32), t) and not np.array_equal(t, tensors[table])
    x = np.random.default_rng(1).uniform(0, 1, (256, q.in_dim)).astype(np.float32)
    assert_parity(glsl_eval(gl, q, x, storage="texture"), torch_reference(q, x), what="f16")


def _table_networks():
    """One small network per table component at f32 (the table feeding a dense layer), and inputs."""
    from test_hash_grid import build_grid
    from test_latent_pyramid import pyramid_graph, pyramid_inputs
    from test_lookup_array import lut_graph, lut_inputs
    from test_sparse_voxels import voxel_graph

    from inshade.models import GraphModule

    def fed(kind, module, dims, node):
        g = GraphModule([("x", dims)])
        g.add(node, module, "x")
        g.dense("l0", node, 5)
        g.output("y", "l0")
        return g.export(kind)

    rng = np.random.default_rng(0)
    grid = dict(kind="hash", dims=3, levels=4, features=4, base_resolution=4, per_level_scale=2.0, precision="f32",
                log2_table_size=8, hash="coherent_prime", seed=3, mixed=True)
    dense = dict(grid, kind="dense", dims=2, features=2, levels=3)
    yield "hash_grid", fed("grid", build_grid(grid, 1.0), 3, "grid"), rng.uniform(0, 1, (256, 3))
    yield "dense_grid", fed("grid", build_grid(dense, 1.0), 2, "grid"), rng.uniform(0, 1, (256, 2))
    pyramid = dict(res=16, levels=3, channels=8, precision="f32", seed=1)
    yield "latent_pyramid", pyramid_graph(pyramid).export("latent"), pyramid_inputs(1, 256, 16, 3)
    voxels = dict(scale_min=1, scale_max=2, density=0.3, channels=8, precision="f32", uint=False, small=False, seed=2)
    bundle = voxel_graph(voxels).export("voxels")
    yield "sparse_voxels", bundle, rng.integers(0, bundle.node("vox").params["voxels"], (256, 1))
    lut = dict(res=[9, 7], channels=3, bits=32, nonlinearity="triangle", seed=4)   # values bounded by F
    yield "lookup_array", lut_graph(lut).export("lut"), lut_inputs(4, 256, 2, [9, 7])


@pytest.mark.parametrize("kind", ["hash_grid", "dense_grid", "latent_pyramid", "sparse_voxels", "lookup_array"])
def test_i8_gives_every_table_its_8_bit_form(gl, kind):
    """Under i8 a table takes its 8-bit codes with a range per lane (the values are not centred): the
    bundle holds uint8 codes, a quarter of the float32 bytes, each within half a step of the value it
    codes, which the shader decodes as the twin does (parity rule)."""
    name, bundle, x = next(t for t in _table_networks() if t[0] == kind)
    x = np.asarray(x, np.float32)
    q = quantized(bundle, "i8")
    node = next(n for n in q.nodes if n.type == kind)
    param, value = ("bits", 8) if kind == "lookup_array" else ("precision", "u8")
    assert node.params[param] == value
    slots = [s for s in q.tensors if s.startswith(node.id + ".") and q.tensors[s].dtype == np.uint8]
    assert slots and q.tensors[node.tensor_name("scale")].dtype == np.float32
    assert sum(q.tensors[s].nbytes for s in slots) * 4 == sum(bundle.tensors[s].nbytes for s in slots)
    scale, offset = q.tensors[node.tensor_name("scale")], q.tensors[node.tensor_name("offset")]
    for s in slots:   # every value within half a step of its lane's range
        error = np.abs(decode(q.tensors[s], scale, offset) - bundle.tensors[s])
        assert np.all(error <= scale / 510 * (1 + 1e-5) + 1e-7)
    assert_parity(glsl_eval(gl, q, x, storage="texture"), torch_reference(q, x), what=f"{kind} i8")


def test_i8_gives_mesh_features_their_u8_form(gl):
    """A shipped UV-free material at i8: its feature table takes the component's own 8-bit form (per-lane
    offset + scale: the values are not centred), its dense layers int8 codes; the shader reads them as
    the twin does."""
    from inshade.bundle import load
    from inshade.scene.description import load_scene, resolve_asset

    fp32 = load(load_scene(resolve_asset("uvfree_material_fruit_balanced")).networks[0].bundle)
    q = quantized(fp32, "i8")
    table = next(n for n in q.nodes if n.type == "mesh_features")
    assert table.params["precision"] == "u8" and q.tensor(table, "table").dtype == np.uint8
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.integers(0, table.params["faces"], (256, 1)), rng.dirichlet((1, 1, 1), 256)[:, :2],
                        rng.uniform(-1, 1, (256, q.in_dim - 3))], 1).astype(np.float32)
    assert_parity(glsl_eval(gl, q, x, storage="texture"), torch_reference(q, x), what="uvfree i8")


def test_an_unbounded_lookup_array_keeps_float_under_i8_unless_chosen():
    """Differentiable Indirection's cascaded arrays (no periodic function bounds them) stay float32 under
    a whole-network i8, as its authors keep them; a per-node precision codes one all the same."""
    from test_lookup_array import lut_graph

    bundle = lut_graph(dict(res=[9, 7], channels=3, bits=32, nonlinearity="none", seed=4)).export("lut")
    assert quantized(bundle, "i8").node("lut").params["bits"] == 32
    assert quantized(bundle, {"lut": "i8"}).node("lut").params["bits"] == 8


def test_max_error_chooses_for_the_tables_too(gl):
    """A hash grid (values in [-1, 1]) feeding a small layer: under a bound of 3e-3 the grid's u8 codes
    fit while the layer's int8 rows do not, so the table goes to 8 bits and the layer keeps float16; the
    plan names both, and the mixed bundle keeps the parity rule."""
    from inshade.components.grids.torch_twin import HashGrid
    from inshade.convert.precision import choose, twin
    from inshade.models import GraphModule

    torch.manual_seed(0)
    g = GraphModule([("x", 2)])
    g.add("grid", HashGrid(2, 4, 2, log2_table_size=10, base_resolution=4, precision="f32", init_scale=1.0,
                           seed=1), "x")
    g.output("y", g.dense("l0", "grid", 3))
    bundle = g.export("grid")
    x = np.random.default_rng(0).uniform(0, 1, (512, 2)).astype(np.float32)
    chosen, why = choose(bundle, twin(bundle), [x], 3e-3)
    assert chosen == {"grid": "i8", "l0": "f16"}, why
    assert why[0].startswith("grid (hash_grid, 2720 values): i8 (max error with i8 ")
    assert why[1].startswith("l0 (8 -> 3): f16 (max error with i8 ")
    q = quantized(bundle, chosen)
    assert q.node("grid").params["precision"] == "u8" and q.node("l0").params["precision"] == "f16"
    assert np.abs(torch_reference(q, x) - torch_reference(bundle, x)).max() <= 3e-3
    assert_parity(glsl_eval(gl, q, x, storage="texture"), torch_reference(q, x), what="mixed")
    with pytest.raises(ValueError, match="node nope: no such node in the bundle"):
        quantized(bundle, {"nope": "i8"})
