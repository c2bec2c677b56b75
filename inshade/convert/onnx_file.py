"""Reading an ONNX file with the ``onnx`` package (the ``onnx`` extra): the model, checked for what
inshade reads (opsets 13 and newer, the standard operators only)."""
from __future__ import annotations

from pathlib import Path

from .lanes import ConvertError

MIN_OPSET = 13


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
