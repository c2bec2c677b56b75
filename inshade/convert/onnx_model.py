"""An ONNX file -> bundle (``inshade convert model.onnx -o folder``), read with the ``onnx`` package
(the ``onnx`` extra; onnx_file.py) and walked node by node, each lowered by the lowering registered
for its op type (``@onnx_op`` in ops/onnx_*.py) onto components (lowering.py); onnxruntime is the reference its GLSL is
checked against. Opsets 13 and newer; a static or symbolic batch axis (axis 0 of every input).

Nodes whose inputs are all constants (initializers, Constant, Shape of a computed value) are
evaluated by onnx's reference evaluator and stay constants, so the shape arithmetic exporters
emit around Reshape costs nothing.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.components import registry as component_registry
from inshade.provenance import recorded_at

from .lowering import ConvertError, Feat, IntFeat, Lowering
from .onnx_file import _onnx, load_model
from .onnx_reference import run_onnxruntime  # noqa: F401 (the reference, imported from here by its callers)
from .ops import onnx_arithmetic, onnx_elementwise, onnx_layers, onnx_shapes  # noqa: F401 (they fill ONNX_OPS)
from .ops.common import Condition
from .registry import ONNX_OPS

component_registry.load("lowering")     # the component folders' own lowerings

HANDLERS = ONNX_OPS   # the ONNX op types inshade convert lowers, by name
SYMBOLIC_BATCH = 97   # the batch size a symbolic batch axis stands for while shapes are computed
_FLOAT = 1            # TensorProto.FLOAT


@dataclass(frozen=True)
class InputSpec:
    name: str
    dims: list          # the tensor's shape: ints, None where symbolic


@dataclass(frozen=True)
class Pose:
    """Which axes of the inputs are the batch: ``merged`` leading axes folded into one batch axis
    (every op then acts on the last axes only), or the axis ``from_end`` places from the end alone
    (the other leading axes are part of each row)."""
    merged: int = 1
    from_end: int = 2

    def text(self) -> str:
        return (f"the {self.merged} leading axes as the batch" if self.merged > 1
                else f"axis -{self.from_end} as the batch")


class NotPosable(ConvertError):
    """The graph needs more of its tensors' axes than this pose leaves it (another pose may do)."""


class OnnxLowering:
    def __init__(self, model, where: str, opset: int, pose: Pose = Pose()):
        onnx = _onnx()
        from onnx import numpy_helper

        self.model, self.where, self.opset, self.pose = model, where, opset, pose
        self.graph = model.graph
        self.L = Lowering()
        self.env: dict[str, object] = {i.name: numpy_helper.to_array(i) for i in self.graph.initializer}
        self.helper, self.numpy_helper = onnx.helper, numpy_helper
        self.batch = SYMBOLIC_BATCH

    def input_specs(self) -> list[InputSpec]:
        """Every graph input that is not an initializer: a float32 tensor with a known rank."""
        out = []
        for inp in self.graph.input:
            if inp.name in self.env:
                continue
            field = f"{self.where}: graph.input {inp.name!r}"
            kind = inp.type.WhichOneof("value")
            if kind != "tensor_type":
                what = {"sequence_type": "a sequence", "optional_type": "an optional", "map_type": "a map",
                        "sparse_tensor_type": "a sparse tensor"}.get(kind, f"of type {kind}")
                raise ConvertError(f"{field}: {what}; inputs must be float32 tensors")
            t = inp.type.tensor_type
            if t.elem_type != _FLOAT:
                name = self.helper.tensor_dtype_to_string(t.elem_type).removeprefix("TensorProto.")
                raise ConvertError(f"{field}: element type {name}; inputs must be float32")
            if not t.HasField("shape"):
                raise ConvertError(f"{field}: no shape; inputs need a known rank and a fixed last axis")
            dims = [int(d.dim_value) if d.HasField("dim_value") else None for d in t.shape.dim]
            if not dims:
                raise ConvertError(f"{field}: a scalar; inputs need a batch axis ([batch, features], [1, N, F], "
                                   "[H, W, F])")
            if 0 in dims:
                raise ConvertError(f"{field}: shape {_dims_text(dims)} holds no values (an empty tensor)")
            out.append(InputSpec(inp.name, dims))
        self._weights_as_inputs(out)
        return out

    def _weights_as_inputs(self, specs: list[InputSpec]) -> None:
        """A MatMul / Gemm whose weight operand is a graph input: the shader's weights are constants."""
        names = {s.name for s in specs}
        for node in self.graph.node:
            if node.op_type in ("Gemm", "MatMul") and len(node.input) > 1:
                for slot, name in list(enumerate(node.input))[1:]:
                    if name in names:
                        what = "B" if slot == 1 else "C"
                        raise ConvertError(f"{self.where}: node {node.name or node.output[0]!r} ({node.op_type}): "
                                           f"its {what} is graph.input {name!r}; the weights must be initializers "
                                           "(constants), as a trained network's are")

    def _feeds(self, specs: list[InputSpec]) -> list[tuple[InputSpec, Feat]]:
        """Each input as a Feat under ``self.pose``; sets ``self.batch``."""
        pose, sizes, feeds = self.pose, set(), []
        for spec in specs:
            dims, field = spec.dims, f"{self.where}: graph.input {spec.name!r}"
            if pose.merged > 1:
                if len(dims) != pose.merged + 1:
                    raise NotPosable(f"{field}: shape {_dims_text(dims)}: the inputs' leading axes differ")
                lead = dims[:-1]
                sizes.add(None if None in lead else int(np.prod(lead)))
                shape, lanes = [*[None] * pose.merged, dims[-1]], np.zeros((1, dims[-1]))
            else:
                if len(dims) < pose.from_end:
                    raise NotPosable(f"{field}: shape {_dims_text(dims)} has no axis -{pose.from_end} to be the batch "
                                     "with the other inputs' (inputs broadcast against each other on their batch axes)")
                b = len(dims) - pose.from_end
                sizes.add(dims[b])
                shape = [None if a == b else n for a, n in enumerate(dims)]
                if any(n is None for a, n in enumerate(dims) if a != b):
                    raise NotPosable(f"{field}: shape {_dims_text(dims)}: a symbolic axis besides the batch (each "
                                     "row's lanes must be fixed)")
                lanes = np.zeros([1 if a == b else n for a, n in enumerate(dims)])
            dim = int(np.prod([n for n in shape if n is not None]))
            try:
                f = self.L.input(_port_name(spec.name), dim, shape=shape)
            except ConvertError as exc:
                raise NotPosable(f"{self.where}: graph.{exc}") from None
            feeds.append((spec, Feat(f.lanes.reshape(lanes.shape), 0 if pose.merged > 1 else
                                     len(dims) - pose.from_end)))
        fixed = sorted(n for n in sizes if n is not None)
        if len(fixed) > 1:
            raise NotPosable(f"{self.where}: graph.input: the batch axes differ in size ({fixed}) under "
                             f"{pose.text()}")
        if fixed:
            self.batch = fixed[0]
        return feeds

    def run(self) -> list[tuple[str, Feat]]:
        specs = self.input_specs()
        if not specs:
            raise ConvertError(f"{self.where}: graph.input: none that is not an initializer (a shader network "
                               "computes from its inputs)")
        for spec, f in self._feeds(specs):
            self.env[spec.name] = f
        for node in self.graph.node:
            self._node(node)
        outs = []
        for o in self.graph.output:
            v = self.env.get(o.name)
            if isinstance(v, Condition):
                raise ConvertError(f"{self.where}: graph.output {o.name!r} is a boolean (a comparison); shader "
                                   "outputs are float32: choose values with Where, or Cast it to float")
            if not isinstance(v, Feat):
                producer = next((n for n in self.graph.node if o.name in n.output), None)
                if producer is not None and v is None:
                    raise ConvertError(f"{self.where}: node {producer.name or producer.output[0]!r} "
                                       f"({producer.op_type}): output {o.name!r} is not computed (inshade computes "
                                       "the node's main output only); leave it out of graph.output")
                raise ConvertError(f"{self.where}: graph.output {o.name!r} is a constant (it does not depend on "
                                   "the input)")
            outs.append((o.name, v))
        return outs

    def axis(self, f: Feat, a: int, rank_change: int = 0) -> int:
        """The Feat axis of the source's axis ``a`` of ``f`` (whose rank is ``rank_change`` more in
        the op's output, for Unsqueeze); under merged leading axes, one of them is refused."""
        merged = self.pose.merged - 1
        rank = f.rank + merged + rank_change
        a = int(a) % rank if -rank <= int(a) < rank else int(a)
        if not merged:
            return a
        if a <= merged:
            raise NotPosable(f"axis {a} is one of the leading axes taken as the batch")
        return a - merged

    def _node(self, node) -> None:
        ins = [self.env[n] if n else None for n in node.input]
        attrs = {a.name: self.helper.get_attribute_value(a) for a in node.attribute}
        label = f"{self.where}: node {node.name or node.output[0]!r} ({node.op_type})"
        if not any(isinstance(v, (Feat, Condition)) for v in ins):
            results = self._evaluate(node, ins, label)
        else:
            entry = ONNX_OPS.entry(node.op_type)
            if entry is None:
                raise ConvertError(f"{label}: no shader lowering (see inshade convert --ops)")
            if self.pose.merged > 1 and entry.option("whole_shape"):
                raise NotPosable(f"{label}: reads whole shapes, while several leading axes are the batch")
            try:
                if not entry.option("takes_ints"):   # an integer meets a float op: the float it was cast from
                    ins = [self.L.int_to_float(v) if isinstance(v, IntFeat) else v for v in ins]
                results = entry.lower(self, node, *ins, **attrs)
            except ConvertError as exc:
                raise type(exc)(f"{label}: {exc}") from None
            results = results if isinstance(results, tuple) else (results,)
        for name, value in zip(node.output, results):
            if name:
                self.env[name] = value
    def _evaluate(self, node, ins, label):
        """A node of constants, by onnx's reference evaluator (Constant nodes directly)."""
        if node.op_type == "Constant":
            value = next(iter(node.attribute))
            v = self.helper.get_attribute_value(value)
            return (self.numpy_helper.to_array(v) if hasattr(v, "dims") else np.asarray(v),)
        from onnx.reference import ReferenceEvaluator

        h = self.helper
        feeds = {f"i{k}": np.asarray(v) for k, v in enumerate(ins) if v is not None}
        inputs = [h.make_tensor_value_info(f"i{k}", h.np_dtype_to_tensor_dtype(np.asarray(v).dtype), None)
                  for k, v in enumerate(ins) if v is not None]
        outputs = [h.make_tensor_value_info(f"o{k}", 0, None) for k in range(len(node.output))]
        copy = h.make_node(node.op_type, [f"i{k}" if v is not None else "" for k, v in enumerate(ins)],
                           [o.name for o in outputs], **{a.name: h.get_attribute_value(a) for a in node.attribute})
        graph = h.make_graph([copy], "constant", inputs, outputs)
        model = h.make_model(graph, opset_imports=list(self.model.opset_import))
        try:
            return tuple(ReferenceEvaluator(model).run(None, feeds))
        except Exception as exc:
            raise ConvertError(f"{label}: evaluating it on constants failed ({type(exc).__name__}: "
                               f"{str(exc)[:120]})") from None

    # helpers for handlers
    def full_shape(self, f: Feat) -> list[int]:
        return [self.batch if a == f.batch else n for a, n in enumerate(f.shape)]

    def const(self, v, what: str) -> np.ndarray:
        if isinstance(v, (Feat, Condition)):
            raise ConvertError(f"{what} must be a constant")
        return np.asarray(v)

    def ints(self, v, what: str) -> list[int]:
        return [int(i) for i in np.asarray(self.const(v, what)).reshape(-1)]


    @staticmethod
    def array(v) -> np.ndarray:
        """A constant as float32 numpy."""
        return np.asarray(v, np.float32)

def _dims_text(dims) -> str:
    return "[" + ", ".join("?" if n is None else str(n) for n in dims) + "]"


def _port_name(name: str) -> str:
    """An ONNX value name as a bundle port name (identifier, <= 48 characters)."""
    clean = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in name) or "x"
    return ("x_" + clean if not (clean[0].isalpha() or clean[0] == "_") else clean)[:48]


# --- the command ---------------------------------------------------------------------------

def to_bundle(source, *, name: str | None = None):
    """(bundle, model, lowering) of an ONNX file or ModelProto. Inputs of rank 3 and more are posed
    in turn (poses()); the first pose the whole graph lowers under is kept."""
    model, where, opset = load_model(source)
    specs = OnnxLowering(model, where, opset).input_specs()
    first = None
    for pose in poses(specs):
        lowering = OnnxLowering(model, where, opset, pose)
        try:
            outs = lowering.run()
            for out_name, f in outs:
                try:
                    lowering.L.output(_port_name(out_name), f, batch_axes=pose.merged)
                except ConvertError as exc:
                    raise ConvertError(f"{where}: graph.output {out_name!r}: {exc}") from None
            break
        except ConvertError as exc:
            if first is None or isinstance(first, NotPosable) and not isinstance(exc, NotPosable):
                first = exc
    else:
        raise ConvertError(str(first)) from None
    onnx = _onnx()
    provenance = {"source": "onnx", "file": where, "opset": opset, "producer": model.producer_name or "",
                  "onnx": onnx.__version__,
                  **recorded_at()}
    default = Path(where).stem if where != "<model>" else (model.graph.name or "model")
    bundle = lowering.L.bundle("imported", name or _port_name(default), provenance)
    return bundle, model, lowering


def poses(specs: list[InputSpec]):
    """The ways to read the inputs' leading axes as the batch, most rows first: all of them merged
    (when every input has the same leading axes), then each one alone, the largest first."""
    ranks = {len(s.dims) for s in specs}
    if not specs or ranks == {2} and all(s.dims[-1] is not None for s in specs):
        yield Pose()
        return
    if len(ranks) == 1 and len({tuple(s.dims[:-1]) for s in specs}) == 1:
        yield Pose(merged=ranks.pop() - 1)
    widest = max(specs, key=lambda s: len(s.dims)).dims
    yield from (Pose(from_end=k) for k in sorted(range(2, len(widest) + 1), key=lambda k: -(widest[-k] or 1 << 30)))
    yield Pose(from_end=1)   # the last axis as the batch: rows of the other axes (a vector: one lane a row)
