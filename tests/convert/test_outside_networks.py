"""Networks written the way other people's packages write them, through both ways in: the torch
route (``inshade.export``) and the ONNX route (``torch.onnx.export``, then ``inshade convert``),
each checked through the driver; and the inputs and graphs that used to crash or name the wrong
thing (non-finite example values, per-lane Pow exponents, Clip with min > max, exporters' [1, N, F]
inputs). Integer lanes (an Embedding indexed by a computed integer, a hash encoding) are in
test_int_lanes.py."""
from __future__ import annotations

import numpy as np
import onnx
import pytest
import torch
import torch.nn.functional as F
from onnx import TensorProto, helper, numpy_helper

import inshade
from inshade.bundle import load
from inshade.cli import main
from inshade.convert.check import check_inputs
from inshade.convert.lowering import ConvertError
from inshade.convert.export import convert_onnx as convert
from inshade.convert.onnx_model import run_onnxruntime

from parity import assert_parity

# torch's TorchScript ONNX exporter (dynamo=False, as these packages' users call it) warns on every
# export about a logging helper of its own: nothing the test or inshade can act on.
pytestmark = pytest.mark.filterwarnings("ignore:The feature will be removed:DeprecationWarning")


class NerfDirections(torch.nn.Module):
    """nerf-pytorch's view directions: normalised with torch.linalg.norm, then a layer."""

    def __init__(self):
        super().__init__()
        self.layer = torch.nn.Linear(6, 8)

    def forward(self, x):
        d = x[:, 3:] / torch.linalg.norm(x[:, 3:], dim=-1, keepdim=True)
        return torch.relu(self.layer(torch.cat([x[:, :3], d], -1)))


class Normalized(torch.nn.Module):
    def __init__(self):
        super().__init__()
        self.layer = torch.nn.Linear(6, 4)

    def forward(self, x):
        return F.normalize(self.layer(x), dim=-1)


class OnnxActivations(torch.nn.Module):
    """The activations ONNX names (Selu, Mish, HardSigmoid, HardSwish) written in torch."""

    def forward(self, x):
        return torch.cat([torch.selu(x), F.mish(x), F.hardsigmoid(x), F.hardswish(x)], -1)


class EinsumHeads(torch.nn.Module):
    """Linear maps written as einsums: a layer ('bi,oi->bo'), per-head weights ('hoi,bi->bho'),
    a sum over features ('bi->b')."""

    def __init__(self):
        super().__init__()
        self.w = torch.nn.Parameter(torch.randn(5, 6) / 3)
        self.heads = torch.nn.Parameter(torch.randn(2, 3, 5) / 3)

    def forward(self, x):
        h = torch.tanh(torch.einsum("bi,oi->bo", x, self.w))
        per_head = torch.einsum("hoi,bi->bho", self.heads, h).reshape(-1, 6)
        return torch.cat([per_head, torch.einsum("bi->b", h)[:, None]], -1)


ZOO = {"nerf_directions": NerfDirections, "normalize": Normalized, "onnx_activations": OnnxActivations,
       "einsum_heads": EinsumHeads}


@pytest.mark.parametrize("name", sorted(ZOO))
@pytest.mark.filterwarnings("ignore:You are using the legacy TorchScript-based ONNX export")
def test_both_routes_match(gl, name, tmp_path):
    torch.manual_seed(0)
    module = ZOO[name]().eval()
    x = torch.rand(32, 6) * 2 - 1
    inshade.export(module, x, tmp_path / "torch", quiet=True)
    path = tmp_path / f"{name}.onnx"
    torch.onnx.export(module, (x,), str(path), dynamo=False, input_names=["x"], output_names=["y"],
                      dynamic_axes={"x": {0: "N"}, "y": {0: "N"}})
    convert(path, tmp_path / "onnx", example=x.numpy(), quiet=True)
    rows = check_inputs(x.numpy(), seed=5)
    with torch.no_grad():
        ref = module(torch.from_numpy(rows)).numpy()
    from inshade.convert.check import evaluate

    for route in ("torch", "onnx"):
        out, _, _ = evaluate(load(tmp_path / route), rows)
        assert_parity(out, ref, what=f"{name} by the {route} route")


def _model(nodes, inputs, outputs, inits=(), opset=17):
    graph = helper.make_graph(nodes, "g", inputs, outputs, list(inits))
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", opset)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    return model


def _float(name, shape):
    return helper.make_tensor_value_info(name, TensorProto.FLOAT, shape)


def test_non_finite_example_rows_are_left_out(gl, tmp_path, capsys):
    model = _model([helper.make_node("Relu", ["x"], ["y"])], [_float("x", ["N", 4])], [_float("y", ["N", 4])])
    example = np.float32([[0.5, np.nan, np.inf, -np.inf], [0.25, -1, 2, 3], [-0.5, 1, 1, 1]])
    bundle = convert(model, tmp_path / "b", example=example)
    assert "example: 1 of 3 rows hold NaN or infinities; left out of the check" in capsys.readouterr().err
    assert bundle.meta["provenance"]["check"]["ok"] and bundle.meta["provenance"]["check"]["example_rows_left_out"] == 1
    rows = check_inputs(example)
    assert len(rows) == 2 + 1024 and np.isfinite(rows).all()
    assert rows[:, 1].min() >= -1 and rows[:, 1].max() <= 1


def test_per_lane_pow_and_inverted_clip_match_onnxruntime(gl, tmp_path):
    model = _model([helper.make_node("Pow", ["x", "e"], ["p"]),
                    helper.make_node("Clip", ["x", "lo", "hi"], ["c"]),
                    helper.make_node("Concat", ["p", "c"], ["y"], axis=-1)],
                   [_float("x", ["N", 3])], [_float("y", ["N", 6])],
                   [numpy_helper.from_array(np.float32([1, 2, 3]), "e"), numpy_helper.from_array(np.float32(2), "lo"),
                    numpy_helper.from_array(np.float32(1), "hi")])
    x = np.random.default_rng(1).uniform(-2, 2, (64, 3)).astype(np.float32)
    convert(model, tmp_path / "b", example=x, quiet=True)
    from inshade.convert.check import evaluate

    out, _, _ = evaluate(load(tmp_path / "b"), x)
    ref = run_onnxruntime(model, [x])[0]
    assert_parity(out, ref, what="Pow [1, 2, 3] and Clip(2, 1)")
    assert np.all(ref[:, 3:] == 1.0)


@pytest.mark.parametrize("shape,batch", [([1, "N", 3], [None, None, 3]), (["H", "W", 3], [None, None, 3]),
                                         (["N", 1, 3], [None, None, 3])])
def test_exporters_shapes_keep_their_layout(gl, tmp_path, shape, batch):
    """An MLP over the last axis of [1, N, F], [H, W, F] and [N, 1, F] inputs: the leading axes are
    the batch, and `inshade eval` shapes its outputs back the same way."""
    rng = np.random.default_rng(2)
    model = _model([helper.make_node("MatMul", ["x", "W"], ["h"]), helper.make_node("Tanh", ["h"], ["y"])],
                   [_float("x", shape)], [_float("y", [*shape[:-1], 5])],
                   [numpy_helper.from_array(rng.uniform(-1, 1, (3, 5)).astype(np.float32), "W")])
    path = tmp_path / "m.onnx"
    onnx.save(model, path)
    assert main(["convert", str(path), "-o", str(tmp_path / "b"), "--quiet"]) == 0
    bundle = load(tmp_path / "b")
    assert [bundle.inputs[0].dim, bundle.outputs[0].dim] == [3, 5]
    assert bundle.meta["inputs"][0]["shape"] == batch
    full = rng.uniform(-1, 1, [4 if d in ("N", "H") else 6 if d == "W" else d for d in shape]).astype(np.float32)
    np.save(tmp_path / "in.npy", full)
    assert main(["eval", str(tmp_path / "b"), str(tmp_path / "in.npy"), "-o", str(tmp_path / "out.npy"), "--quiet"]) == 0
    out = np.load(tmp_path / "out.npy")
    import onnxruntime as ort

    ref = ort.InferenceSession(model.SerializeToString(), providers=["CPUExecutionProvider"]).run(None, {"x": full})[0]
    assert out.shape == ref.shape
    assert_parity(out, ref, what=f"{shape} through inshade eval")


class LastAxisNet(torch.nn.Module):
    """Written for [..., F] tensors as exporters pass them: normalise along dim 2, a layer, and the
    input concatenated back along the last axis."""

    def __init__(self):
        super().__init__()
        self.layer = torch.nn.Linear(3, 4)

    def forward(self, x):
        return torch.cat([torch.tanh(self.layer(F.normalize(x, dim=2))), x[..., :1]], dim=2)


@pytest.mark.parametrize("example", [(1, 40, 3), (5, 6, 3), (40, 1, 3)])
def test_torch_route_takes_leading_axes_as_the_batch(gl, tmp_path, example):
    """The torch route poses [1, N, F], [H, W, F] and [N, 1, F] examples as the ONNX route does:
    the leading axes are the batch; `inshade eval` takes and gives arrays of that rank."""
    torch.manual_seed(3)
    net = LastAxisNet().eval()
    inshade.export(net, torch.rand(example) * 2 - 1, tmp_path / "b", quiet=True)
    bundle = load(tmp_path / "b")
    assert bundle.meta["inputs"][0]["shape"] == [None, None, 3]
    assert bundle.meta["outputs"][0]["shape"] == [None, None, 5]
    full = np.random.default_rng(4).uniform(-1, 1, (4, 7, 3)).astype(np.float32)
    np.save(tmp_path / "in.npy", full)
    assert main(["eval", str(tmp_path / "b"), str(tmp_path / "in.npy"), "-o", str(tmp_path / "out.npy"), "--quiet"]) == 0
    out = np.load(tmp_path / "out.npy")
    with torch.no_grad():
        ref = net(torch.from_numpy(full)).numpy()
    assert out.shape == ref.shape == (4, 7, 5)
    assert_parity(out, ref, what=f"torch route, example {list(example)}")


def test_torch_route_refuses_inputs_of_different_batch_axes(tmp_path):
    with pytest.raises(ConvertError, match=r"example_input: shapes \[2, 3, 3\], \[2, 4, 3\]: every input needs"):
        inshade.export(torch.nn.Bilinear(3, 3, 2), (torch.rand(2, 3, 3), torch.rand(2, 4, 3)), tmp_path / "b")
    assert not (tmp_path / "b").exists()


class SineLayer(torch.nn.Module):
    """INR_collection's SIREN layer: sin(omega0 (W x + b)), the first layer's weights in
    [-1/in, 1/in], the others in [-sqrt(6/in)/omega0, sqrt(6/in)/omega0]."""

    def __init__(self, n_in, n_out, first, omega0=30.0):
        super().__init__()
        self.omega0, self.linear = omega0, torch.nn.Linear(n_in, n_out)
        bound = 1 / n_in if first else (6 / n_in) ** 0.5 / omega0
        with torch.no_grad():
            self.linear.weight.uniform_(-bound, bound)

    def forward(self, x):
        return torch.sin(self.omega0 * self.linear(x))


def trained_siren() -> torch.nn.Module:
    """2 -> 64 x 3 -> 3, omega0 = 30, its hidden weights grown 8x as training grows them: sin
    arguments reach the tens to hundreds, where fp32 itself is ~1e-5 from the exact answer."""
    torch.manual_seed(0)
    net = torch.nn.Sequential(SineLayer(2, 64, True), SineLayer(64, 64, False), SineLayer(64, 64, False),
                              torch.nn.Linear(64, 3))
    with torch.no_grad():
        for layer in list(net)[1:3]:
            layer.linear.weight.mul_(8.0)
    return net.eval()


@pytest.mark.filterwarnings("ignore:You are using the legacy TorchScript-based ONNX export")
def test_siren_exports_under_the_conditioning_rule(gl, tmp_path, capsys):
    """Both routes accept the SIREN: where the 1e-5 rule against fp32 torch fails, the shader is no
    farther from the float64 answer than twice torch's own fp32 distance from it."""
    net, x = trained_siren(), torch.rand(64, 2) * 2 - 1
    bundle = inshade.export(net, x, tmp_path / "torch")
    line = capsys.readouterr().err.strip().splitlines()[-1]
    check = bundle.meta["provenance"]["check"]
    assert check["ok"] and check["max_scaled"] > 1e-5 and check["by_conditioning"], line
    assert check["glsl_f64"] <= 2 * check["source_f64"]
    assert "|glsl - f64| = " in line and line.endswith("ok (conditioning)")
    path = tmp_path / "siren.onnx"
    torch.onnx.export(net, (x,), str(path), dynamo=False, input_names=["xy"], output_names=["rgb"],
                      dynamic_axes={"xy": {0: "N"}, "rgb": {0: "N"}})
    assert convert(path, tmp_path / "onnx", example=x.numpy(), quiet=True).meta["provenance"]["check"]["ok"]


def test_conditioning_rule_still_refuses_a_wrong_shader(gl, tmp_path):
    """A weight off by 1e-3 is farther from the float64 answer than fp32 explains: refused."""
    from inshade.convert.check import check

    net, x = trained_siren(), torch.rand(64, 2) * 2 - 1
    bundle = inshade.export(net, x, tmp_path / "b", quiet=True)
    name = next(k for k in bundle.tensors if k.endswith(".weight"))
    bundle.tensors[name] = bundle.tensors[name] + np.float32(1e-3)
    result = check(net, bundle, check_inputs(x.numpy()))
    assert not result.ok and result.glsl_f64 > 2 * result.source_f64
    assert "FAILED" in result.line() and "|glsl - f64|" in result.line()


class PeriodicOps(torch.nn.Module):
    """What coordinate networks compute besides layers: logarithms, rounding, periodic wraps,
    polar angles, constant-exponent and constant-base powers."""

    def __init__(self):
        super().__init__()
        self.layer = torch.nn.Linear(2, 3)

    def forward(self, x):
        h = self.layer(x) * 3
        first = torch.cat([torch.log(h.abs() + 0.5), torch.log2(x.abs() + 1), torch.floor(h), torch.ceil(h),
                           torch.round(h), torch.frac(h), torch.fmod(h, 0.7)], -1)
        return torch.cat([first, h % 0.7, torch.atan2(h, x[:, :1]), (x.abs() + 0.1) ** 1.5, 2 ** h[:, :2]], -1)


def test_coordinate_network_ops_export(gl, tmp_path):
    torch.manual_seed(3)
    bundle = inshade.export(PeriodicOps().eval(), torch.rand(32, 2) * 2 - 1, tmp_path / "b", quiet=True)
    types = {n.type for n in bundle.nodes}
    assert {"log", "log2", "floor", "ceil", "round", "frac", "fmod", "remainder", "atan2", "power", "exp"} <= types
    assert bundle.meta["provenance"]["check"]["ok"]


def test_onnx_rounding_and_mod_match_onnxruntime(gl, tmp_path):
    nodes = [helper.make_node(op, ["x"], [op.lower()]) for op in ("Floor", "Ceil", "Round")]
    nodes += [helper.make_node("Abs", ["x"], ["ax"]), helper.make_node("Log", ["ax"], ["log"]),
              helper.make_node("Mod", ["x", "d"], ["mod"], fmod=1),
              helper.make_node("Concat", ["floor", "ceil", "round", "log", "mod"], ["y"], axis=-1)]
    model = _model(nodes, [_float("x", ["N", 4])], [_float("y", ["N", 20])],
                   [numpy_helper.from_array(np.float32(0.75), "d")])
    # integers, halves (round to even), multiples of the divisor, and points between
    x = np.float32([[-2.5, -1.5, -0.5, 0.5], [1.5, 2.5, -0.75, 0.75], [1.5, -2.25, 3.0, -3.0],
                    *np.random.default_rng(4).uniform(-4, 4, (61, 4))]).astype(np.float32)
    convert(model, tmp_path / "b", example=x, quiet=True)
    from inshade.convert.check import evaluate

    out, _, _ = evaluate(load(tmp_path / "b"), x)
    assert_parity(out, run_onnxruntime(model, [x])[0], what="Floor, Ceil, Round, Log, Mod")
