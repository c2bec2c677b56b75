"""Integer lanes: an index a network computes (a cast, integer multiply / add / xor / shift, a
remainder by a power of two) and the learned table read at it, as one ``int_gather`` node. Its
torch twin (int64 reduced modulo 2^32) against GLSL's uint arithmetic through the driver, and the
networks that need it written as their packages write them: an Embedding indexed by a computed
integer and a multiresolution hash encoding in plain torch (nerfstudio's fallback), by both ways in,
against the ``hash_grid`` component's numbers."""
from __future__ import annotations

import numpy as np
import onnx
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st
from onnx import TensorProto, helper, numpy_helper

import inshade
from inshade.bundle import load
from inshade.components.feature_axis.torch_twin import IntGather
from inshade.components.grids.torch_twin import HashGrid
from inshade.convert.check import evaluate
from inshade.convert.export import convert_onnx as convert
from inshade.convert.lowering import ConvertError
from inshade.grid_layout import HASH_PRIMES, grid_levels
from inshade.models.graph import GraphModule

from parity import assert_parity, glsl_eval, parity_settings

pytestmark = pytest.mark.filterwarnings("ignore:The feature will be removed:DeprecationWarning",
                                        "ignore:You are using the legacy TorchScript-based ONNX export",
                                        "ignore:`isinstance\\(treespec, LeafSpec\\)` is deprecated:FutureWarning")

BINARY = ("add", "sub", "mul", "xor", "and", "or")


@st.composite
def programs(draw, lanes: int = 2):
    """Straight-line uint32 code over the input lanes, with wrapping products and big constants."""
    prog = [["lane", k] for k in range(lanes)]
    for _ in range(draw(st.integers(1, 10))):
        kind = draw(st.sampled_from(BINARY + ("const", "shl")))
        if kind == "const":
            prog.append(["const", draw(st.sampled_from([1, 3, 255, 2654435761, 805459861, 0xFFFFFFFF]))])
        elif kind == "shl":
            prog.append(["shl", draw(st.integers(0, len(prog) - 1)), draw(st.integers(0, 31))])
        else:
            prog.append([kind, draw(st.integers(0, len(prog) - 1)), draw(st.integers(0, len(prog) - 1))])
    rows = draw(st.sampled_from([16, 64, 1000]))
    mask = prog + [["const", (1 << (rows.bit_length() - 1)) - 1]]
    mask.append(["and", len(prog) - 1, len(prog)])   # in range for the last entry; the rest may fall outside
    return mask, [len(mask) - 1, len(prog) - 1], rows


@parity_settings(15)
@given(programs(), st.sampled_from([1, 3, 4, 8]), st.integers(0, 2 ** 16))
def test_int_gather_matches_torch_through_the_driver(gl, case, features, seed):
    program, indices, rows = case
    rng = np.random.default_rng(seed)
    table = rng.uniform(-1, 1, (rows, features)).astype(np.float32)
    g = GraphModule([("x", 2)])
    g.add("gather", IntGather(program, indices, rows, features, table=table), "x")
    g.output("y", "gather")
    bundle = g.export("imported", "int_gather_probe")
    x = rng.uniform(-300, 300, (64, 2)).astype(np.float32)
    x[:4] = [[0.0, -0.0], [-1.5, 2.5], [2 ** 30, -(2 ** 30)], [-7.99, 7.99]]   # signs, halves, big values
    with torch.no_grad():
        ref = g(torch.from_numpy(x)).numpy()
    out = glsl_eval(gl, bundle, x)
    np.testing.assert_array_equal(out, ref)   # exact: integer code and a texel fetch on both sides


class Lookup(torch.nn.Module):
    """An Embedding indexed by a computed integer, then a layer."""

    def __init__(self):
        super().__init__()
        self.table = torch.nn.Embedding(16, 3)
        self.layer = torch.nn.Linear(3, 2)

    def forward(self, x):
        return self.layer(self.table((x[:, 0] * 15.99).long()))


class PlainHashEncoding(torch.nn.Module):
    """A multiresolution hash encoding in plain torch, written the way nerfstudio's fallback writes
    it (floor, integer multiply by primes, xor, % table size, + level offset, table[index], the
    trilinear weights), with tiny-cuda-nn's vertex rule p = scale * x + 0.5."""

    def __init__(self, levels, table):
        super().__init__()
        self.table = torch.nn.Parameter(table)
        self.register_buffer("scales", torch.tensor([float(lv.scale) for lv in levels]))
        self.register_buffer("offsets", torch.tensor([lv.offset for lv in levels]))
        self.register_buffer("primes", torch.tensor(HASH_PRIMES["coherent_prime"]))
        self.size = levels[0].rows

    def hash(self, c):
        h = c * self.primes
        x = torch.bitwise_xor(h[..., 0], h[..., 1])
        x = torch.bitwise_xor(x, h[..., 2])
        return x % self.size + self.offsets

    def forward(self, x):
        p = x[..., None, :] * self.scales[:, None] + 0.5      # [N, levels, 3]
        g = torch.floor(p)
        f = p - g
        c = g.long()
        out = 0
        for corner in range(8):
            bits = [(corner >> d) & 1 for d in range(3)]
            w = 1
            for d in range(3):
                w = w * (f[..., d] if bits[d] else 1 - f[..., d])
            out = out + w[..., None] * self.table[self.hash(c + torch.tensor(bits))]
        return out.flatten(-2)


def _both_routes(module, x, tmp_path, dynamo: bool):
    inshade.export(module, x, tmp_path / "torch", quiet=True)
    path = tmp_path / "m.onnx"
    if dynamo:   # torch's TorchScript exporter has no bitwise_xor
        torch.onnx.export(module, (x,), str(path), dynamo=True, input_names=["x"], output_names=["y"],
                          dynamic_shapes={"x": {0: torch.export.Dim("n")}}, verbose=False)
    else:
        torch.onnx.export(module, (x,), str(path), dynamo=False, input_names=["x"], output_names=["y"],
                          dynamic_axes={"x": {0: "N"}, "y": {0: "N"}})
    convert(path, tmp_path / "onnx", example=x.numpy(), quiet=True)
    return {route: load(tmp_path / route) for route in ("torch", "onnx")}


def test_embedding_at_a_computed_index_matches_by_both_routes(gl, tmp_path):
    torch.manual_seed(0)
    module = Lookup().eval()
    x = torch.rand(256, 1)
    x[:3, 0] = torch.tensor([0.0, 0.5, 0.999])
    with torch.no_grad():
        ref = module(x).numpy()
    for route, bundle in _both_routes(module, x, tmp_path, dynamo=False).items():
        assert any(n.type == "int_gather" for n in bundle.nodes), route
        out, _, _ = evaluate(bundle, x.numpy())
        assert_parity(out, ref, what=f"embedding by the {route} route")


def test_plain_torch_hash_encoding_matches_hash_grid_by_both_routes(gl, tmp_path):
    levels = grid_levels(3, 4, 20, 1.5, 12)
    assert not any(lv.dense for lv in levels)   # every level hashed, as the plain encoding hashes
    torch.manual_seed(0)
    table = torch.rand(sum(lv.rows for lv in levels), 2) * 2 - 1
    module = PlainHashEncoding(levels, table).eval()
    grid = HashGrid(3, 4, 2, 12, 20, 1.5, precision="f32", table=table.numpy())
    x = torch.rand(512, 3)
    with torch.no_grad():
        ref = grid(x).numpy()
        np.testing.assert_array_equal(module(x).numpy(), ref)   # the same encoding
    for route, bundle in _both_routes(module, x, tmp_path, dynamo=True).items():
        out, _, _ = evaluate(bundle, x.numpy())
        assert_parity(out, ref, what=f"plain-torch hash encoding by the {route} route vs hash_grid")


def test_integer_refusals_name_the_reason(tmp_path):
    class NotPowerOfTwo(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.table = torch.nn.Parameter(torch.rand(1000, 2))

        def forward(self, x):
            return self.table[(x[:, 0] * 2654435761).long() % 1000]

    class HashAsFloat(torch.nn.Module):
        def forward(self, x):
            return (x.long() * 3).float() + x

    with pytest.raises(ConvertError, match=r"test_int_lanes\.py:\d+: .*remainder by \[1000\]: a 32-bit lane keeps "
                                           r"only the low bits, so only positive power-of-two divisors are exact"):
        inshade.export(NotPowerOfTwo(), torch.rand(8, 1), tmp_path / "a", quiet=True)
    with pytest.raises(ConvertError, match=r"an integer computed by a multiply is used as a float"):
        inshade.export(HashAsFloat(), torch.rand(8, 1), tmp_path / "b", quiet=True)
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_onnx_right_shift_is_refused_by_node(tmp_path):
    nodes = [helper.make_node("Cast", ["x"], ["i"], to=TensorProto.INT64),
             helper.make_node("BitShift", ["i", "s"], ["h"], direction="RIGHT"),
             helper.make_node("Gather", ["t", "h"], ["y"], axis=0)]
    graph = helper.make_graph(nodes, "g", [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["N"])],
                              [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["N", 2])],
                              [numpy_helper.from_array(np.array(1, np.int64), "s"),
                               numpy_helper.from_array(np.random.rand(8, 2).astype(np.float32), "t")])
    path = tmp_path / "shift.onnx"
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)]), path)
    with pytest.raises(ConvertError, match=r"node 'h' \(BitShift\): BitShift RIGHT needs the integer's high bits"):
        convert(path, tmp_path / "b", quiet=True)
