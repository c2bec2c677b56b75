"""onnxruntime as the reference an ONNX import is judged against: the model's outputs as rows, in
float32 or (for the parity check's float64 rule) in double precision."""
from __future__ import annotations

import numpy as np

from .lanes import ConvertError, Float64Unavailable
from .onnx_file import _onnx, load_model


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
