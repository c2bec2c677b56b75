"""An ONNX file -> bundle (``inshade convert model.onnx -o folder``), read with the ``onnx`` package
(the ``onnx`` extra) and lowered op by op (lowering.py); onnxruntime is the reference its GLSL is
checked against. Opsets 13 and newer; a static or symbolic batch axis (axis 0 of every input).

Nodes whose inputs are all constants (initializers, Constant, Shape of a computed value) are
evaluated by onnx's reference evaluator and stay constants, so the shape arithmetic exporters
emit around Reshape costs nothing.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.provenance import utc_now

from .lowering import (ConvertError, Feat, Float64Unavailable, IntFeat, Lowering, const_against, expand, grid_sample, permute, reshape, slice_axis,
                       squeeze, take, unsqueeze)

MIN_OPSET = 13
SYMBOLIC_BATCH = 97   # the batch size a symbolic batch axis stands for while shapes are computed
_FLOAT = 1            # TensorProto.FLOAT


def _onnx():
    try:
        import onnx
    except ImportError:
        raise ConvertError("reading ONNX needs the onnx package: pip install -e '.[onnx]'") from None
    return onnx


def load_model(path):
    """The ModelProto of ``path`` (or ``path`` itself when it is one), checked: ConvertError naming
    the file for one that is not a readable ONNX model or uses an opset below 13."""
    onnx = _onnx()
    if not isinstance(path, (str, Path)):
        model, where = path, "<model>"
    else:
        where = str(path)
        if not Path(path).is_file():
            raise ConvertError(f"{where}: no such file")
        try:
            model = onnx.load(str(path))
        except Exception as exc:   # protobuf raises DecodeError and others for a file that is not ONNX
            raise ConvertError(f"{where}: not an ONNX model ({type(exc).__name__}: {str(exc)[:120]})") from None
    opset = next((o.version for o in model.opset_import if o.domain in ("", "ai.onnx")), None)
    if opset is None:
        raise ConvertError(f"{where}: opset_import: no standard ONNX (ai.onnx) opset; only the standard operators "
                           "are lowered")
    if opset < MIN_OPSET:
        raise ConvertError(f"{where}: opset_import: opset {opset}; inshade reads opsets {MIN_OPSET} and newer "
                           "(onnx.version_converter can upgrade it)")
    others = sorted({n.domain for n in model.graph.node if n.domain not in ("", "ai.onnx")})
    if others:
        raise ConvertError(f"{where}: a node of domain {others[0]!r}: only the standard ONNX operators are lowered")
    return model, where, opset


@dataclass(frozen=True)
class Condition:
    op: str
    a: object
    b: object


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
        self.current = node
        if not any(isinstance(v, (Feat, Condition)) for v in ins):
            results = self._evaluate(node, ins, label)
        else:
            handler = HANDLERS.get(node.op_type)
            if handler is None:
                raise ConvertError(f"{label}: no shader lowering (see inshade convert --ops)")
            if self.pose.merged > 1 and node.op_type in LAYOUT_OPS:
                raise NotPosable(f"{label}: reads whole shapes, while several leading axes are the batch")
            try:
                if node.op_type not in INT_HANDLERS:   # an integer meets a float op: the float it was cast from
                    ins = [self.L.int_to_float(v) if isinstance(v, IntFeat) else v for v in ins]
                results = handler(self, ins, attrs)
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


def _dims_text(dims) -> str:
    return "[" + ", ".join("?" if n is None else str(n) for n in dims) + "]"


def _port_name(name: str) -> str:
    """An ONNX value name as a bundle port name (identifier, <= 48 characters)."""
    clean = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in name) or "x"
    return ("x_" + clean if not (clean[0].isalpha() or clean[0] == "_") else clean)[:48]


# --- handlers: (O, inputs, attributes) -> output(s) --------------------------------------------

def _unary(kind, **fixed):
    return lambda O, ins, a: O.L.unary(ins[0], kind, dict(fixed))


def _arith(op):
    def lower(O, ins, attrs):
        a, b = ins
        if isinstance(a, IntFeat) or isinstance(b, IntFeat):   # ONNX keeps integers integers
            if op == "div":
                raise ConvertError("Div of integers (integer division) is not lowered: Cast to float first")
            return O.L.int_arithmetic(op, a, b, O.batch)
        return O.L.arithmetic(op, a if isinstance(a, Feat) else np.asarray(a, np.float32),
                              b if isinstance(b, Feat) else np.asarray(b, np.float32), O.batch)
    return lower


def _gemm(O, ins, attrs):
    a, b = ins[0], ins[1]
    c = ins[2] if len(ins) > 2 else None
    if not isinstance(a, Feat) or isinstance(b, Feat) or isinstance(c, Feat):
        raise ConvertError("Gemm of a computed A with constant B and C is lowered")
    if attrs.get("transA", 0):
        a = permute(a, [1, 0])
    w = np.asarray(b, np.float32)
    w = w if attrs.get("transB", 0) else w.T
    alpha, beta = float(attrs.get("alpha", 1.0)), float(attrs.get("beta", 1.0))
    if alpha != 1.0:
        w = (w * np.float32(alpha)).astype(np.float32)
    bias = None if c is None else (np.asarray(c, np.float32) * np.float32(beta)).reshape(-1)
    if bias is not None and bias.size not in (1, w.shape[0]):
        raise ConvertError(f"Gemm: C of {bias.size} values for {w.shape[0]} outputs (a per-row C mixes the batch)")
    return O.L.dense(a, w, bias)


def _matmul(O, ins, attrs):
    a, b = ins
    if isinstance(a, Feat) and not isinstance(b, Feat):
        w = np.asarray(b, np.float32)
        if w.ndim == 1:
            return squeeze(O.L.dense(a, w.reshape(1, -1), None), -1)
        if w.ndim != 2:
            raise ConvertError(f"MatMul by a constant of rank {w.ndim}")
        return O.L.dense(a, w.T, None)
    if not isinstance(a, Feat) and isinstance(b, Feat) and b.rank == 2 and b.batch == 1:
        return O.L.dense(b, np.asarray(a, np.float32), None)
    raise ConvertError("MatMul of two computed values (only products with a constant are lowered)")


def _clip(O, ins, attrs):
    lo = ins[1] if len(ins) > 1 else attrs.get("min")
    hi = ins[2] if len(ins) > 2 else attrs.get("max")
    lo, hi = (None if v is None else float(np.asarray(O.const(v, f"Clip {k}")).reshape(()))
              for k, v in (("min", lo), ("max", hi)))
    return O.L.clamp(ins[0], lo, hi)


def _pow(O, ins, attrs):
    x, e = ins
    if isinstance(e, Feat):
        if isinstance(x, Feat):
            raise ConvertError("Pow of a computed base to a computed exponent (a constant base or exponent is "
                               "lowered)")
        return O.L.base_power(np.asarray(x, np.float32), e)
    return O.L.power(x, np.asarray(e, np.float32))


def _leaky_relu(O, ins, attrs):
    return O.L.unary(ins[0], "leaky_relu", {"slope": float(attrs.get("alpha", 0.01))})


def _elu(O, ins, attrs):
    return O.L.unary(ins[0], "elu", {"alpha": float(attrs.get("alpha", 1.0))})


def _selu(O, ins, attrs):
    out = O.L.unary(ins[0], "elu", {"alpha": float(attrs.get("alpha", 1.67326319217681884765625))})
    return O.L.affine(out, float(attrs.get("gamma", 1.05070102214813232421875)), 0.0)


def _gelu(O, ins, attrs):
    return O.L.unary(ins[0], "gelu", {"approximate": attrs.get("approximate", b"none").decode()
                                      if isinstance(attrs.get("approximate"), bytes) else attrs.get("approximate", "none")})


def _hard_sigmoid(O, ins, attrs):
    y = O.L.affine(ins[0], np.float32(attrs.get("alpha", 0.2)), np.float32(attrs.get("beta", 0.5)))
    return O.L.unary(y, "clamp", {"min": 0.0, "max": 1.0})


def _hard_swish(O, ins, attrs):
    return O.L.binary("mul", ins[0], _hard_sigmoid(O, ins, {"alpha": 1 / 6, "beta": 0.5}))


def _mish(O, ins, attrs):
    return O.L.binary("mul", ins[0], O.L.unary(O.L.unary(ins[0], "softplus"), "tanh"))


def _identity(O, ins, attrs):
    return ins[0]


def _dropout(O, ins, attrs):
    if len(ins) > 2 and ins[2] is not None and bool(np.asarray(O.const(ins[2], "training_mode"))):
        raise ConvertError("Dropout in training mode is random")
    return ins[0], None


def _int_op(op):
    def lower(O, ins, attrs):
        a, b = ins
        if not (isinstance(a, IntFeat) or isinstance(b, IntFeat)):
            raise ConvertError("an integer operation on values that are not integers")
        if op == "shl" and attrs.get("direction") != b"LEFT" and attrs.get("direction") != "LEFT":
            raise ConvertError("BitShift RIGHT needs the integer's high bits, which a 32-bit lane does not keep")
        return O.L.int_arithmetic(op, a, b, O.batch)
    return lower


def _cast(O, ins, attrs):
    if attrs.get("to") in INT_CASTS:
        return O.L.to_int(ins[0])
    if isinstance(ins[0], IntFeat) and attrs.get("to") in (1, 11):
        return O.L.int_to_float(ins[0])
    if attrs.get("to") not in (1, 11):   # float, double (a shader computes both in float32)
        name = O.helper.tensor_dtype_to_string(attrs.get("to")).removeprefix("TensorProto.")
        raise ConvertError(f"Cast to {name}: shader values are float32 (rounding to {name} is not lowered)")
    return ins[0]


def _compare(op):
    return lambda O, ins, attrs: Condition(op, ins[0], ins[1])


def _where(O, ins, attrs):
    cond, x, y = ins
    if isinstance(cond, Condition):
        return O.L.where(cond.op, cond.a, cond.b, x, y)
    if not isinstance(cond, Feat):
        return O.L.where("gt", np.asarray(cond, np.float32), np.float32(0.5), x, y)
    raise ConvertError("Where with a condition that is not a comparison (Greater, Less, ...) of values")


def _concat(O, ins, attrs):
    feats = [O.L.resolve(v) for v in ins if isinstance(v, Feat)]
    like = feats[0]
    if isinstance(like, IntFeat):
        parts = [O.L.int_operand(v, like, O.batch) for v in ins if isinstance(v, Feat) or np.size(v)]
        return like.moved(np.concatenate([p.lanes for p in parts], O.axis(like, attrs["axis"])))
    axis = O.axis(like, attrs["axis"])
    if axis == like.batch:
        raise ConvertError("concatenates along the batch axis")
    parts = []
    for v in ins:
        if isinstance(v, Feat):
            parts.append(O.L.resolve(v).lanes)
        elif np.size(v):
            parts.append(O.L.constant(like, const_against(np.asarray(v, np.float32), like, O.batch)).lanes)
    return Feat(np.concatenate(parts, axis), like.batch)


def _slice(O, ins, attrs):
    f = ins[0]
    starts, ends = O.ints(ins[1], "Slice starts"), O.ints(ins[2], "Slice ends")
    axes = O.ints(ins[3], "Slice axes") if len(ins) > 3 and ins[3] is not None else list(range(len(starts)))
    steps = O.ints(ins[4], "Slice steps") if len(ins) > 4 and ins[4] is not None else [1] * len(starts)
    for s, e, a, st in zip(starts, ends, axes, steps):
        a = O.axis(f, a)
        n = O.batch if a == f.batch else f.shape[a]
        s, e = _clip_index(s, n, st), _clip_index(e, n, st)
        if a == f.batch:
            if s == 0 and e >= n and st == 1:
                continue
            raise ConvertError("slices the batch axis (rows of the batch are pixels: each is computed alone)")
        f = slice_axis(f, a, s, e if e >= 0 else None, st, O.batch)
    return f


def _clip_index(i: int, n: int, step: int) -> int:
    """An ONNX Slice bound clamped as the spec says ([0, n] forwards, [-1, n - 1] backwards)."""
    i = i + n if i < 0 else i
    return int(min(max(i, 0), n)) if step > 0 else int(min(max(i, -1), n - 1))


def _split(O, ins, attrs):
    f = ins[0]
    axis = O.axis(f, attrs.get("axis", 0))
    if axis == f.batch:
        raise ConvertError("splits the batch axis")
    n = f.shape[axis]
    if len(ins) > 1 and ins[1] is not None:
        sizes = O.ints(ins[1], "Split split")
    elif "split" in attrs:
        sizes = [int(s) for s in attrs["split"]]
    else:
        parts = int(attrs.get("num_outputs", 0)) or len(O.current.output)
        size = -(-n // parts)
        sizes = [min(size, n - k * size) for k in range(parts)]
    bounds = np.cumsum([0, *sizes])
    return tuple(slice_axis(f, axis, int(a), int(b), 1, O.batch) for a, b in zip(bounds[:-1], bounds[1:]))


def _axes(O, ins, attrs, name):
    if len(ins) > 1 and ins[1] is not None:
        return O.ints(ins[1], f"{name} axes")
    return [int(a) for a in attrs.get("axes", [])]


def _squeeze(O, ins, attrs):
    axes = _axes(O, ins, attrs, "Squeeze")
    return squeeze(ins[0], axes or None)


def _unsqueeze(O, ins, attrs):
    f = ins[0]
    axes = _axes(O, ins, attrs, "Unsqueeze")
    rank = f.rank + len(axes)
    for a in sorted(x % rank for x in axes):
        f = unsqueeze(f, a)
    return f


def _reshape(O, ins, attrs):
    f = ins[0]
    target = O.ints(ins[1], "Reshape shape")
    full = O.full_shape(f)
    allowzero = int(attrs.get("allowzero", 0))
    shape = [full[i] if (t == 0 and not allowzero) else t for i, t in enumerate(target)]
    if -1 in shape:
        known = int(np.prod([s for s in shape if s != -1]))
        shape[shape.index(-1)] = int(np.prod(full)) // max(known, 1)
    return reshape(f, shape, O.batch)


def _flatten(O, ins, attrs):
    f = ins[0]
    full = O.full_shape(f)
    axis = int(attrs.get("axis", 1))
    axis = axis + f.rank if axis < 0 else axis   # ONNX: in [-r, r]
    return reshape(f, [int(np.prod(full[:axis])), int(np.prod(full[axis:]))], O.batch)


def _transpose(O, ins, attrs):
    f = ins[0]
    return permute(f, attrs.get("perm", list(reversed(range(f.rank)))))


def _gather(O, ins, attrs):
    f, idx = ins
    if isinstance(idx, IntFeat):
        if isinstance(f, Feat) or attrs.get("axis", 0) != 0:
            raise ConvertError("Gather at computed indices: a constant table along axis 0 is lowered")
        return O.L.gather(np.asarray(f, np.float32), idx)
    indices = np.asarray(O.const(idx, "Gather indices")).astype(np.int64)
    axis = O.axis(f, attrs.get("axis", 0))
    n = f.shape[axis]
    return take(f, axis, np.where(indices < 0, indices + n, indices))


def _gather_nd(O, ins, attrs):
    """GatherND of a constant table at computed indices [..., 1] (how torch.onnx writes table[idx])."""
    f, idx = ins
    if (not isinstance(idx, IntFeat) or isinstance(f, Feat) or attrs.get("batch_dims", 0) or idx.shape[-1] != 1
            or idx.batch == idx.rank - 1):
        raise ConvertError("GatherND: a constant table read at computed indices [..., 1] (batch_dims 0) is lowered")
    return O.L.gather(np.asarray(f, np.float32), squeeze(idx, [idx.rank - 1]))


def _expand(O, ins, attrs):
    f = ins[0]
    target = O.ints(ins[1], "Expand shape")
    full = O.full_shape(f)
    rank = max(len(target), f.rank)
    a = [1] * (rank - len(full)) + full
    b = [1] * (rank - len(target)) + target
    shape = [x if y == 1 else y for x, y in zip(a, b)]
    return expand(f, shape)


def _shape(O, ins, attrs):
    full = np.asarray(O.full_shape(ins[0]), np.int64)
    start, end = attrs.get("start", 0), attrs.get("end", None)
    return full[start:end]


def _layer_norm(O, ins, attrs):
    f = ins[0]
    axis = O.axis(f, attrs.get("axis", -1))
    scale = O.const(ins[1], "LayerNormalization Scale") if len(ins) > 1 and ins[1] is not None else None
    bias = O.const(ins[2], "LayerNormalization B") if len(ins) > 2 and ins[2] is not None else None
    return O.L.layer_norm(f, f.rank - axis, scale, bias, float(attrs.get("epsilon", 1e-5))), None, None


def _batch_norm(O, ins, attrs):
    if attrs.get("training_mode", 0):
        raise ConvertError("BatchNormalization in training mode normalises over the batch (it mixes pixels)")
    scale, bias, mean, var = (np.asarray(O.const(v, "BatchNormalization parameters"), np.float64) for v in ins[1:5])
    return O.L.batch_norm(ins[0], scale, bias, mean, var, float(attrs.get("epsilon", 1e-5)))


def _grid_sample(O, ins, attrs):
    grid, coords = ins[0], ins[1]
    if isinstance(grid, Feat) or not isinstance(coords, Feat):
        raise ConvertError("GridSample of a constant X at computed coordinates is lowered")
    mode = attrs.get("mode", b"bilinear")
    mode = mode.decode() if isinstance(mode, bytes) else mode
    padding = attrs.get("padding_mode", b"zeros")
    padding = padding.decode() if isinstance(padding, bytes) else padding
    if mode not in ("bilinear", "linear"):
        raise ConvertError(f"GridSample mode {mode!r}: bilinear is lowered")
    if padding not in ("zeros", "border"):
        raise ConvertError(f"GridSample padding_mode {padding!r}: 'zeros' and 'border' are lowered")
    return grid_sample(O.L, np.asarray(grid, np.float32), coords, padding == "zeros", bool(attrs.get("align_corners", 0)))


def _reduce(op):
    def lower(O, ins, attrs):
        f = ins[0]
        axes = _axes(O, ins, attrs, "Reduce")
        if not axes:
            if attrs.get("noop_with_empty_axes", 0):
                return f
            axes = list(range(f.rank + O.pose.merged - 1))
        return O.L.reduce(f, op, [O.axis(f, a) for a in axes], bool(attrs.get("keepdims", 1)))
    return lower


def _mod(O, ins, attrs):
    a, b = ins
    if isinstance(a, IntFeat) and not attrs.get("fmod", 0):
        return O.L.int_arithmetic("remainder", a, O.const(b, "Mod divisor"), O.batch)
    if isinstance(b, Feat) or not isinstance(a, Feat):
        raise ConvertError("Mod of a computed value by a constant divisor is lowered")
    if not attrs.get("fmod", 0):
        raise ConvertError("Mod with fmod = 0 is integer modulo; float values need fmod = 1")
    return O.L.modulo(a, np.asarray(b, np.float32), "fmod")


def _einsum(O, ins, attrs):
    """An Einsum of one computed value with constants: linear in it, so one dense layer."""
    feats = [i for i, v in enumerate(ins) if isinstance(v, Feat)]
    if len(feats) != 1:
        raise ConvertError("Einsum of several computed values (an Einsum of one value with constants is lowered)")
    k, equation = feats[0], attrs["equation"]
    equation = equation.decode() if isinstance(equation, bytes) else equation

    def apply(basis):
        return np.einsum(equation, *[basis if i == k else np.asarray(v, np.float64) for i, v in enumerate(ins)])
    return O.L.linear_map(ins[k], apply)


def _softmax(O, ins, attrs):
    return O.L.softmax(ins[0], O.axis(ins[0], attrs.get("axis", -1)))


HANDLERS = {
    "Gemm": _gemm, "MatMul": _matmul, "Add": _arith("add"), "Sub": _arith("sub"), "Mul": _arith("mul"),
    "Div": _arith("div"), "Relu": _unary("relu"), "LeakyRelu": _leaky_relu, "Sigmoid": _unary("sigmoid"),
    "Tanh": _unary("tanh"), "Softplus": _unary("softplus"), "Elu": _elu, "Selu": _selu, "Gelu": _gelu,
    "Erf": _unary("erf"), "Sin": _unary("sin"), "Cos": _unary("cos"), "Exp": _unary("exp"), "Abs": _unary("abs"),
    "Sqrt": _unary("sqrt"), "Reciprocal": _unary("reciprocal"), "Neg": lambda O, ins, a: O.L.affine(ins[0], -1.0, 0.0),
    "Clip": _clip, "Pow": _pow, "HardSigmoid": _hard_sigmoid, "HardSwish": _hard_swish, "Mish": _mish,
    "Identity": _identity, "Dropout": _dropout, "Cast": _cast,
    "Greater": _compare("gt"), "GreaterOrEqual": _compare("ge"), "Less": _compare("lt"),
    "LessOrEqual": _compare("le"), "Where": _where,
    "Concat": _concat, "Slice": _slice, "Split": _split, "Squeeze": _squeeze, "Unsqueeze": _unsqueeze,
    "Reshape": _reshape, "Flatten": _flatten, "Transpose": _transpose, "Gather": _gather, "Expand": _expand,
    "Shape": _shape, "LayerNormalization": _layer_norm, "BatchNormalization": _batch_norm,
    "GridSample": _grid_sample, "ReduceSum": _reduce("sum"), "ReduceMean": _reduce("mean"),
    "ReduceMax": _reduce("max"), "ReduceMin": _reduce("min"), "ReduceL2": _reduce("norm"), "Softmax": _softmax,
    "Einsum": _einsum, "Log": _unary("log"), "Floor": _unary("floor"), "Ceil": _unary("ceil"),
    "Round": _unary("round"), "Mod": _mod, "BitwiseXor": _int_op("xor"), "BitwiseAnd": _int_op("and"),
    "BitwiseOr": _int_op("or"), "BitShift": _int_op("shl"),
    "GatherND": _gather_nd,
}
INT_CASTS = (6, 7)   # Cast to INT32, INT64: integer lanes
# ops that take integer tensors as they are (layout, casts, integer arithmetic, table reads)
INT_HANDLERS = {"Add", "Sub", "Mul", "Div", "Cast", "Concat", "Slice", "Split", "Squeeze", "Unsqueeze", "Reshape",
                "Flatten", "Transpose", "Gather", "Expand", "Identity", "Mod", "BitwiseXor", "BitwiseAnd", "BitwiseOr",
                "BitShift", "Shape", "GatherND"}
# ops that name axes of the whole tensor (or need its full shape): not lowered under merged batch axes
LAYOUT_OPS = {"Einsum", "Squeeze", "Unsqueeze", "Reshape", "Flatten", "Transpose", "Expand", "Shape", "Gemm", "GridSample",
              "BatchNormalization"}


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
                  "date_utc": utc_now()}
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


def float64_model(model):
    """A copy of ``model`` computing in double precision: float32 initializers, constants, casts and
    value types widened (exactly: every float32 is a float64)."""
    onnx = _onnx()
    from onnx import TensorProto, numpy_helper

    wide = onnx.ModelProto()
    wide.CopyFrom(model)
    g = wide.graph

    def widen(t):
        if t.data_type == TensorProto.FLOAT:
            t.CopyFrom(numpy_helper.from_array(numpy_helper.to_array(t).astype(np.float64), t.name))

    for t in g.initializer:
        widen(t)
    for v in [*g.input, *g.output, *g.value_info]:
        if v.type.HasField("tensor_type") and v.type.tensor_type.elem_type == TensorProto.FLOAT:
            v.type.tensor_type.elem_type = TensorProto.DOUBLE
    for node in g.node:
        for a in node.attribute:
            if a.type == onnx.AttributeProto.TENSOR:
                widen(a.t)
            elif node.op_type == "Cast" and a.name == "to" and a.i == TensorProto.FLOAT:
                a.i = TensorProto.DOUBLE
    return wide


def run_onnxruntime(source, parts: list[np.ndarray], bundle=None, float64: bool = False) -> list[np.ndarray]:
    """The model's outputs as rows ([N, lanes] each) on ``parts`` (rows [N, lanes] per graph input,
    laid out as ``bundle``'s ports say) by onnxruntime (CPU), in chunks of the model's fixed batch
    size where it has one (the last chunk padded with copies of its first row); ``float64``: the
    model run in double precision (float64_model)."""
    try:
        import onnxruntime as ort
    except ImportError:
        raise ConvertError("checking against onnxruntime needs it: pip install -e '.[onnx]'") from None
    from inshade.port_layout import batch_axes, from_rows, port_shape, to_rows

    model, where, _ = load_model(source)
    options = ort.SessionOptions()
    options.log_severity_level = 3   # its notes on unused initializers are not the user's concern
    if float64:
        try:
            session = ort.InferenceSession(float64_model(model).SerializeToString(), options,
                                           providers=["CPUExecutionProvider"])
        except Exception as exc:   # onnxruntime's own error types: an op without a double kernel
            raise Float64Unavailable(f"onnxruntime in float64: {str(exc).splitlines()[0][:100]}") from None
    else:
        session = ort.InferenceSession(model.SerializeToString(), options, providers=["CPUExecutionProvider"])
    dtype = np.float64 if float64 else np.float32
    inputs = session.get_inputs()
    shapes = ([port_shape(p) for p in bundle.inputs] if bundle is not None
              else [[None, *np.shape(p)[1:]] for p in parts])
    declared = [inputs[0].shape[a] for a in batch_axes(shapes[0])]
    fixed = int(np.prod([d for d in declared if isinstance(d, int) and d > 0]))
    n = len(parts[0])
    symbolic = [i for i, d in enumerate(declared) if not (isinstance(d, int) and d > 0)]
    step = fixed * (-(-n // fixed) if symbolic else 1)
    sizes = tuple(step // fixed if i == (symbolic or [None])[0] else (1 if i in symbolic else d)
                  for i, d in enumerate(declared))
    chunks = []
    for start in range(0, n, step):
        feed = {}
        for inp, shape, p in zip(inputs, shapes, parts):
            rows = p[start:start + step]
            if len(rows) < step:
                rows = np.concatenate([rows, np.repeat(rows[:1], step - len(rows), 0)])
            feed[inp.name] = np.ascontiguousarray(from_rows(rows, shape, sizes), dtype)
        outs = session.run(None, feed)
        out_shapes = ([port_shape(p) for p in bundle.outputs] if bundle is not None
                      else [[None, *o.shape[1:]] for o in outs])
        chunks.append([to_rows(o, s, "onnxruntime output")[0][:min(step, n - start)]
                       for o, s in zip(outs, out_shapes)])
    return [np.concatenate([c[k] for c in chunks]) for k in range(len(chunks[0]))]
