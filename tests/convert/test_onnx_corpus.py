"""ONNX's own backend node-test corpus, made by the ``onnx`` package's case generators (no files
downloaded): every case either converts and its GLSL matches onnxruntime through the driver (the
check ``inshade convert`` runs, on the case's own inputs plus random rows in their range), or is
refused with one line that names the node or graph field and a reason from a fixed list. A crash,
a wrong number or an unlisted reason fails the test.

The generators feed some parameters (axes, shapes, clip bounds, int64 indices) as graph inputs;
a trained network holds those as initializers, so each input the case gives that is not a float
tensor with a batch axis is frozen into an initializer with the case's value before converting."""
from __future__ import annotations

import re
import warnings

import numpy as np
import onnx
import pytest
from onnx import numpy_helper

from inshade.convert.check import RULE
from inshade.convert.lowering import ConvertError
from inshade.convert.export import convert_onnx as convert
from inshade.convert.onnx_model import to_bundle
from inshade.port_layout import port_shape, to_rows

# Where a refusal points (after the model's name): a node, or a field of the graph.
WHERE = re.compile(r"^(<model>: (node '[^']*' \(\w+\): |graph\.(input|output)\b|opset_import: |a node of domain )"
                   r"|outputs: )")
# Why: every reason an importer gives, as a pattern of the line's rest.
REASONS = {
    "no lowering": r"no shader lowering \(see inshade convert --ops\)",
    "element type": r"element type \w+; inputs must be float32",
    "not a tensor": r"(a sequence|an optional|a map|a sparse tensor); inputs must be float32 tensors",
    "no batch axis": r"a scalar; inputs need a batch axis|has no axis -\d+ to be the batch",
    "batch sizes": r"the batch axes differ in size|the inputs' leading axes differ|a symbolic axis besides the batch",
    "row too wide": r"lanes wide .*an input takes at most \d+",
    "mixes the batch": r"(over|along) the batch axis|(splits|slices|indexes|flips|repeats) the batch axis|"
                       r"merges or splits the batch axis|reads whole shapes, while several leading axes",
    "weights are inputs": r"its [BC] is graph\.input '[^']*'; the weights must be initializers|"
                          r"\w+ (Scale|B) must be a constant|GridSample of a constant X",
    "computed by computed": r"(MatMul|Pow) of (two computed values|a computed base to a computed exponent)|"
                            r"of a computed value by a constant divisor is lowered|fmod = 0 is integer modulo",
    "random": r"in training mode is random|in training mode normalises over the batch",
    "base": r"raised to a computed power: positive finite bases are lowered",
    "float32 only": r"Cast to \w+: shader values are float32",
    "constant output": r"graph\.output '[^']*' is (a constant|a boolean)",
    "optional output": r"output '[^']*' is not computed",
    "empty": r"no elements \(an empty slice or split\)",
    "no inputs": r"graph\.input: none that is not an initializer|holds no values \(an empty tensor\)",
    "opset": r"opset_import: (opset \d+; inshade reads opsets|no standard ONNX)",
    "domain": r"a node of domain '[^']*': only the standard ONNX operators",
    "outputs too wide": r"outputs: \d+ lanes in all; a pass writes at most",
    "integer lanes": r"GatherND: a constant table read at computed indices|Gather at computed indices: a constant|"
                     r"Div of integers|BitShift RIGHT needs|integer remainder by .* power-of-two divisors|"
                     r"an integer computed by .* is used as a float|combines an integer with|"
                     r"an integer operation on values that are not integers",
}


def _cases():
    from onnx.backend.test.case import node

    with warnings.catch_warnings():   # the generators' own casts overflow on purpose
        warnings.simplefilter("ignore")
        return node.collect_testcases()


def _array(a) -> np.ndarray:
    return numpy_helper.to_array(a) if isinstance(a, onnx.TensorProto) else np.asarray(a)


def freeze_parameters(case) -> onnx.ModelProto:
    """The case's model with every given input that is not a float32 tensor of rank >= 1 (or that
    is a scalar) turned into an initializer holding the case's value."""
    model = onnx.ModelProto()
    model.CopyFrom(case.model)
    given = dict(zip((i.name for i in model.graph.input), case.data_sets[0][0]))
    keep = []
    for inp in model.graph.input:
        t = inp.type.tensor_type if inp.type.HasField("tensor_type") else None
        value = given.get(inp.name)
        if t is not None and value is not None and (t.elem_type != onnx.TensorProto.FLOAT or len(t.shape.dim) == 0):
            model.graph.initializer.append(numpy_helper.from_array(_array(value), inp.name))
        else:
            keep.append(inp)
    del model.graph.input[:]
    model.graph.input.extend(keep)
    return model


def run_case(case, tmp_path) -> tuple[str, str]:
    """('match', '') or ('refused', the line)."""
    model = freeze_parameters(case)
    try:
        bundle, _, _ = to_bundle(model)
        given = dict(zip((i.name for i in case.model.graph.input), case.data_sets[0][0]))
        rows = [to_rows(_array(given[i.name]), port_shape(p), p.name)[0]
                for i, p in zip((i for i in model.graph.input if i.name in given), bundle.inputs)]
        convert(model, tmp_path / case.name, example=np.concatenate(rows, 1), quiet=True)
    except ConvertError as exc:
        return "refused", str(exc)
    return "match", ""


def test_backend_node_corpus(gl, tmp_path):
    results = {c.name: run_case(c, tmp_path) for c in _cases()}
    wrong = {n: m for n, (s, m) in results.items() if s == "refused" and f"(rule {RULE:g}): FAILED" in m}
    assert not wrong, f"GLSL differs from onnxruntime: {wrong}"
    unplaced = {n: m for n, (s, m) in results.items() if s == "refused" and not WHERE.match(m)}
    assert not unplaced, f"refusals that name no node or field: {unplaced}"
    unlisted = {n: m for n, (s, m) in results.items()
                if s == "refused" and not any(re.search(r, m) for r in REASONS.values())}
    assert not unlisted, f"refusals for a reason not in the list: {unlisted}"
    matched = {n for n, (s, _) in results.items() if s == "match"}
    # cases refused for their shape alone before inputs of any rank were taken: they match now
    reposed = {"test_abs", "test_add_bcast", "test_relu", "test_softmax_axis_1", "test_softmax_axis_0",
               "test_concat_3d_axis_1", "test_transpose_all_permutations_3", "test_split_equal_parts_2d",
               "test_gelu_tanh_2", "test_mvn_expanded", "test_clip_default_inbounds", "test_flatten_axis3"}
    assert reposed <= matched, sorted(reposed - matched)
    print(f"\nONNX node corpus: {len(results)} cases, {len(matched)} match, {len(results) - len(matched)} refused")
    assert len(matched) >= 150


@pytest.mark.parametrize("text", ["<model>: node 'n' (TopK): no shader lowering (see inshade convert --ops)",
                                  "<model>: graph.input 'x': element type INT64; inputs must be float32"])
def test_reason_list_reads_real_lines(text):
    assert WHERE.match(text) and any(re.search(r, text) for r in REASONS.values())
