"""ONNX in: graphs built by hand with onnx.helper, in the spellings other exporters use (Gemm with
transB = 0 and alpha / beta, MatMul + Add, Clip with inputs, the Gelu op and the Erf pattern,
Split by input and by num_outputs, Reduce* axes as attribute and as input, LayerNormalization,
GridSample of opsets 16 and 20, a Shape -> Gather -> Concat -> Reshape chain, static and symbolic
batch axes), converted and checked against onnxruntime through the driver; and the command line:
``inshade convert`` / ``eval`` / ``codegen model.onnx``, refusals in one line with nothing written."""
from __future__ import annotations

import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper, numpy_helper

from inshade.bundle import load
from inshade.cli import main
from inshade.convert.check import check_inputs, evaluate, source_outputs
from inshade.convert.export import convert_onnx as convert

from parity import assert_parity

RNG = np.random.default_rng(0)


def _init(name, a):
    return numpy_helper.from_array(np.asarray(a, np.float32 if np.asarray(a).dtype.kind == "f" else np.int64), name)


def _model(nodes, inputs, outputs, inits=(), opset=13, batch="N"):
    ins = [helper.make_tensor_value_info(n, TensorProto.FLOAT, [batch, d]) for n, d in inputs]
    outs = [helper.make_tensor_value_info(n, TensorProto.FLOAT, [batch, None]) for n in outputs]
    graph = helper.make_graph(nodes, "g", ins, outs, list(inits))
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", opset)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    return model


def _w(*shape, scale=0.5):
    return (RNG.uniform(-1, 1, shape) * scale).astype(np.float32)


def gemm_spellings():
    return _model([
        helper.make_node("Gemm", ["x", "W", "C"], ["h"], alpha=0.5, beta=2.0, transB=0),
        helper.make_node("MatMul", ["h", "W2"], ["m"]), helper.make_node("Add", ["b2", "m"], ["a"]),
        helper.make_node("Relu", ["a"], ["r"]),
        helper.make_node("Clip", ["r", "lo", "hi"], ["c"]), helper.make_node("Clip", ["a", "", "hi"], ["c2"]),
        helper.make_node("Concat", ["c", "c2"], ["y"], axis=1)],
        [("x", 3)], ["y"], [_init("W", _w(3, 8)), _init("C", _w(1, 8)), _init("W2", _w(8, 5)), _init("b2", _w(5)),
                            _init("lo", np.float32(0.1)), _init("hi", np.float32(0.6))], batch=8)


def gelu_spellings():
    s2 = np.float32(np.sqrt(2.0))
    return _model([
        helper.make_node("Gemm", ["x", "W", "b"], ["h"], transB=1),
        helper.make_node("Gelu", ["h"], ["g1"]), helper.make_node("Gelu", ["h"], ["g2"], approximate="tanh"),
        helper.make_node("Div", ["h", "s2"], ["d"]), helper.make_node("Erf", ["d"], ["e"]),
        helper.make_node("Add", ["e", "one"], ["e1"]), helper.make_node("Mul", ["h", "e1"], ["m"]),
        helper.make_node("Mul", ["m", "half"], ["g3"]),
        helper.make_node("Concat", ["g1", "g2", "g3"], ["y"], axis=-1)],
        [("x", 4)], ["y"], [_init("W", _w(6, 4)), _init("b", _w(6)), _init("s2", s2), _init("one", np.float32(1)),
                            _init("half", np.float32(0.5))], opset=20)


def split_reduce_13():
    return _model([
        helper.make_node("Split", ["x", "sizes"], ["a", "b"], axis=1),
        helper.make_node("ReduceMean", ["a"], ["m"], axes=[1], keepdims=1),
        helper.make_node("ReduceSum", ["b", "ax"], ["s"], keepdims=1),
        helper.make_node("ReduceL2", ["x"], ["n"], axes=[-1], keepdims=0),
        helper.make_node("Unsqueeze", ["n", "ax"], ["n2"]),
        helper.make_node("ReduceMax", ["x"], ["mx"], axes=[1]),
        helper.make_node("Sub", ["x", "mx"], ["xs"]),
        helper.make_node("Softmax", ["xs"], ["sm"], axis=1),
        helper.make_node("Concat", ["m", "s", "n2", "sm"], ["y"], axis=1)],
        [("x", 5)], ["y"], [_init("sizes", np.array([2, 3])), _init("ax", np.array([1]))])


def split_reduce_18():
    return _model([
        helper.make_node("Split", ["x"], ["a", "b", "c"], axis=1, num_outputs=3),
        helper.make_node("ReduceMean", ["x", "ax"], ["m"], keepdims=1),
        helper.make_node("ReduceMin", ["x", "ax"], ["mn"], keepdims=1),
        helper.make_node("Mul", ["a", "c"], ["ac"]), helper.make_node("Div", ["b", "two"], ["bd"]),
        helper.make_node("Concat", ["ac", "bd", "m", "mn"], ["y"], axis=1)],
        [("x", 6)], ["y"], [_init("ax", np.array([1])), _init("two", np.float32(2))], opset=18)


def layernorm_17():
    return _model([
        helper.make_node("MatMul", ["x", "W"], ["h"]),
        helper.make_node("LayerNormalization", ["h", "scale"], ["y"], axis=-1, epsilon=1e-5)],
        [("x", 3)], ["y"], [_init("W", _w(3, 8, scale=1.0)), _init("scale", _w(8, scale=2.0))], opset=17)


def gridsample(opset, mode, padding, align):
    grid = RNG.normal(0, 0.5, (1, 4, 6, 7)).astype(np.float32)
    return _model([
        helper.make_node("Mul", ["x", "two"], ["x2"]), helper.make_node("Sub", ["x2", "one"], ["g"]),
        helper.make_node("Reshape", ["g", "shape"], ["gr"]),
        helper.make_node("GridSample", ["grid", "gr"], ["s"], mode=mode, padding_mode=padding, align_corners=align),
        helper.make_node("Reshape", ["s", "back"], ["s2"]),
        helper.make_node("Transpose", ["s2"], ["y"], perm=[1, 0])],
        [("x", 2)], ["y"], [_init("grid", grid), _init("two", np.float32(2.2)), _init("one", np.float32(1.1)),
                            _init("shape", np.array([1, 1, -1, 2])), _init("back", np.array([4, -1]))], opset=opset)


def layout_chain():
    return _model([
        helper.make_node("Shape", ["x"], ["shp"]),
        helper.make_node("Gather", ["shp", "zero_s"], ["batch"], axis=0),
        helper.make_node("Unsqueeze", ["batch", "zero"], ["b1"]),
        helper.make_node("Concat", ["b1", "dims"], ["target"], axis=0),
        helper.make_node("Reshape", ["x", "target"], ["x3"]),          # [N, 2, 3]
        helper.make_node("Transpose", ["x3"], ["xt"], perm=[0, 2, 1]),  # [N, 3, 2]
        helper.make_node("Flatten", ["xt"], ["xf"], axis=1),
        helper.make_node("Slice", ["xf", "st", "en", "axs", "steps"], ["rev"]),
        helper.make_node("Gather", ["xf", "idx"], ["pick"], axis=1),
        helper.make_node("Unsqueeze", ["pick", "two"], ["pk3"]),
        helper.make_node("Squeeze", ["pk3", "two"], ["pk"]),
        helper.make_node("Expand", ["bias", "eshape"], ["bias2"]),
        helper.make_node("Constant", [], ["c"], value=numpy_helper.from_array(np.float32([[0.5, -0.5]]))),
        helper.make_node("Identity", ["c"], ["ci"]),
        helper.make_node("Add", ["pk", "ci"], ["pkc"]),
        helper.make_node("Concat", ["rev", "pkc"], ["cat"], axis=1),
        helper.make_node("Cast", ["cat"], ["cc"], to=TensorProto.FLOAT),
        helper.make_node("Greater", ["cc", "zerof"], ["gt"]),
        helper.make_node("LeakyRelu", ["cc"], ["lr"], alpha=0.2), helper.make_node("Elu", ["cc"], ["el"]),
        helper.make_node("Where", ["gt", "lr", "el"], ["w"]),
        helper.make_node("Sin", ["w"], ["s"]), helper.make_node("Cos", ["w"], ["co"]),
        helper.make_node("Abs", ["co"], ["ab"]), helper.make_node("Sqrt", ["ab"], ["sq"]),
        helper.make_node("Add", ["sq", "one"], ["sq1"]), helper.make_node("Reciprocal", ["sq1"], ["rc"]),
        helper.make_node("Neg", ["s"], ["ng"]), helper.make_node("Pow", ["ng", "twof"], ["pw"]),
        helper.make_node("Selu", ["pw"], ["se"]), helper.make_node("HardSigmoid", ["rc"], ["hs"]),
        helper.make_node("Exp", ["hs"], ["ex"]),
        helper.make_node("Add", ["ex", "bias2"], ["exb"]),
        helper.make_node("Concat", ["se", "exb"], ["y"], axis=1)],
        [("x", 6)], ["y"], [_init("zero", np.array([0])), _init("zero_s", np.array(0)), _init("dims", np.array([2, 3])),
                            _init("st", np.array([-1])), _init("en", np.array([-100])), _init("axs", np.array([1])),
                            _init("steps", np.array([-2])), _init("idx", np.array([-1, 0])), _init("two", np.array([2])),
                            _init("bias", np.float32([0.25])), _init("eshape", np.array([1, 5])),
                            _init("zerof", np.float32(0)), _init("one", np.float32(1)), _init("twof", np.float32(2))])


def two_inputs():
    return _model([
        helper.make_node("Gemm", ["p", "W", "b"], ["h"], transB=1), helper.make_node("Tanh", ["h"], ["t"]),
        helper.make_node("Concat", ["t", "d"], ["td"], axis=1), helper.make_node("Gemm", ["td", "W2"], ["o"], transB=1),
        helper.make_node("Sigmoid", ["o"], ["rgb"]), helper.make_node("Softplus", ["o"], ["sigma"]),
        helper.make_node("Slice", ["sigma", "s0", "s1", "s2"], ["density"])],
        [("p", 3), ("d", 3)], ["rgb", "density"],
        [_init("W", _w(8, 3)), _init("b", _w(8)), _init("W2", _w(4, 11)), _init("s0", np.array([3])),
         _init("s1", np.array([4])), _init("s2", np.array([1]))])


GRAPHS = {
    "gemm_clip_static_batch": gemm_spellings, "gelu_op_and_erf_pattern": gelu_spellings,
    "split_reduce_opset13": split_reduce_13, "split_reduce_opset18": split_reduce_18, "layernorm_opset17": layernorm_17,
    "gridsample16_border_align": lambda: gridsample(16, "bilinear", "border", 1),
    "gridsample20_zeros": lambda: gridsample(20, "linear", "zeros", 0),
    "layout_chain": layout_chain, "two_inputs": two_inputs,
}


@pytest.mark.parametrize("name", sorted(GRAPHS))
def test_hand_built_graph_matches_onnxruntime(gl, name, tmp_path):
    model = GRAPHS[name]()
    path = tmp_path / f"{name}.onnx"
    onnx.save(model, path)
    in_dim = sum(i.type.tensor_type.shape.dim[1].dim_value for i in model.graph.input)
    example = RNG.uniform(-1, 1, (16, in_dim)).astype(np.float32)
    bundle = convert(path, tmp_path / "b", example=example, quiet=True)
    assert bundle.meta["provenance"]["check"]["ok"]
    x = check_inputs(example, seed=3)
    bounds = np.cumsum([0, *(p.dim for p in bundle.inputs)])
    parts = [x[:, a:b] for a, b in zip(bounds[:-1], bounds[1:])]
    out, _, _ = evaluate(load(tmp_path / "b"), x)
    assert_parity(out, source_outputs(path, parts, None), what=name)


def test_cli_convert_eval_codegen(gl, tmp_path, capsys):
    path = tmp_path / "m.onnx"
    onnx.save(two_inputs(), path)
    assert main(["convert", str(path), "-o", str(tmp_path / "b")]) == 0
    err = capsys.readouterr().err
    assert "max |glsl - source| = " in err and "(rule 1e-05): ok" in err
    x = RNG.uniform(-1, 1, (33, 6)).astype(np.float32)
    np.save(tmp_path / "in.npy", x)
    assert main(["eval", str(tmp_path / "b"), str(tmp_path / "in.npy"), "-o", str(tmp_path / "out.npy")]) == 0
    out = np.load(tmp_path / "out.npy")
    assert_parity(out, source_outputs(path, [x[:, :3], x[:, 3:]], None), what="inshade eval")
    assert main(["codegen", str(path), "-o", str(tmp_path / "m.glsl")]) == 0
    assert "void net_eval(" in (tmp_path / "m.glsl").read_text()
    assert main(["convert", "--ops"]) == 0
    ops = capsys.readouterr().out
    assert "GridSample" in ops and "grid_sampler" in ops and "layer_norm" in ops


def _refused(tmp_path, capsys, argv, pattern):
    import re

    out = tmp_path / "never"
    code = main([*argv, "-o", str(out)])
    lines = capsys.readouterr().err.strip().splitlines()
    lines = [line for line in lines if not line.startswith("inshade: OpenGL context")]
    assert code == 2 and len(lines) == 1 and re.search(pattern, lines[0]), lines
    assert lines[0].startswith("inshade: error: ")
    assert not out.exists()


def _save(tmp_path, model, name="m.onnx"):
    path = tmp_path / name
    onnx.save(model, path)
    return str(path)


def test_refusals(tmp_path, capsys):
    topk = _model([helper.make_node("TopK", ["x", "k"], ["v", "i"], name="blocks.1/topk")], [("x", 4)], ["v"],
                  [_init("k", np.array([2]))])
    _refused(tmp_path, capsys, ["convert", _save(tmp_path, topk)],
             r"m\.onnx: node 'blocks\.1/topk' \(TopK\): no shader lowering \(see inshade convert --ops\)")
    over_batch = _model([helper.make_node("ReduceSum", ["x", "ax"], ["y"])], [("x", 4)], ["y"], [_init("ax", np.array([0]))])
    _refused(tmp_path, capsys, ["convert", _save(tmp_path, over_batch)], r"\(ReduceSum\): sum over the batch axis mixes")
    bn = _model([helper.make_node("BatchNormalization", ["x", "s", "b", "m", "v"], ["y"], training_mode=1)],
                [("x", 4)], ["y"], [_init(n, np.ones(4)) for n in "sbmv"], opset=15)
    _refused(tmp_path, capsys, ["convert", _save(tmp_path, bn)], r"BatchNormalization in training mode")
    wide = _model([helper.make_node("MatMul", ["x", "W"], ["y"])], [("x", 4)], ["y"], [_init("W", _w(4, 40))])
    _refused(tmp_path, capsys, ["convert", _save(tmp_path, wide)], r"outputs: 40 lanes in all; a pass writes at most 32")
    product = _model([helper.make_node("Transpose", ["x"], ["xt"]), helper.make_node("MatMul", ["x", "xt"], ["y"])],
                     [("x", 4)], ["y"])
    _refused(tmp_path, capsys, ["convert", _save(tmp_path, product)], r"\(MatMul\): MatMul of two computed values")
    old = _model([helper.make_node("Relu", ["x"], ["y"])], [("x", 4)], ["y"], opset=13)
    old.opset_import[0].version = 11
    _refused(tmp_path, capsys, ["convert", _save(tmp_path, old)], r"m\.onnx: opset_import: opset 11; inshade reads opsets 13")
    (tmp_path / "junk.onnx").write_bytes(b"\x00not a model" * 10)
    _refused(tmp_path, capsys, ["convert", str(tmp_path / "junk.onnx")], r"junk\.onnx: not an ONNX model")
    ints = helper.make_model(helper.make_graph([helper.make_node("Identity", ["x"], ["y"])], "g",
                                               [helper.make_tensor_value_info("x", TensorProto.INT64, ["N", 4])],
                                               [helper.make_tensor_value_info("y", TensorProto.INT64, ["N", 4])]),
                             opset_imports=[helper.make_opsetid("", 13)])
    _refused(tmp_path, capsys, ["convert", _save(tmp_path, ints)], r"graph\.input 'x': element type INT64")
    _refused(tmp_path, capsys, ["convert", str(tmp_path / "model.pt")], r"model\.pt: unknown model format '\.pt'")
