"""``inshade convert CONFIG.json PARAMS``: a tiny-cuda-nn model (its JSON config and the flat
parameter vector its torch bindings save) -> a bundle of inshade components, its GLSL checked
against the bundle's torch twin through the GL driver before anything is written.

tiny-cuda-nn needs CUDA, so it is not what the check runs: the lowering itself is tested against
a torch reimplementation of tiny-cuda-nn's forward written from its source
(tests/tcnn_reference.py, tests/convert/test_tcnn_convert.py). The rules, with the tiny-cuda-nn file and
function each comes from, are in docs/tcnn.md; the model description is tcnn_config.py.

Each encoding becomes the components computing the same function, in tiny-cuda-nn's lane order:

- Grid (Hash / Dense)   -> ``hash_grid`` / ``dense_grid`` (table precision f16 for fp16 params)
- Identity              -> ``affine`` (nothing at all for scale 1, offset 0)
- Frequency             -> ``frequency`` (sin and cos blocks; lanes reordered to tiny-cuda-nn's
                           per input, per frequency, sin then cos)
- SphericalHarmonics    -> ``affine`` (x * 2 - 1: [0, 1]^3 to [-1, 1]^3) -> ``spherical_harmonics``
- TriangleWave          -> ``select`` (each input once per frequency) -> ``affine`` (2^f x + f/2)
                           -> ``triangle_wave`` -> ``affine`` (1 - 2 t)
- OneBlob               -> ``one_blob``
- Composite             -> a ``select`` of each nested encoding's input lanes, the nested outputs
                           side by side
- the padding lanes     -> constants: folded into the first layer's bias (ones) or dropped (zeros)

The network's first layer takes the encoding's lanes in whatever order the components give them:
its weight columns are permuted to match (the same sum), so no lane is moved at run time.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from inshade.provenance import recorded_at

from .lowering import ConvertError
from .tcnn_config import Model, parse_model
from .tcnn_encodings import lanes_of, lower_encoding

__all__ = ["ACTIVATIONS", "Builder", "Cursor", "convert", "leaky_slope", "lower", "lower_encoding", "lower_network",
           "to_bundle"]

KIND = "imported"
K_ACT = 10.0                 # common_device.h: Softplus and Squareplus "zoom" factor
CHECK_ROWS = 64              # example rows of the default check, uniform in [0, 1]^n
TWIN_NOTE = ("the GLSL is checked against the bundle's torch twin: tiny-cuda-nn needs CUDA and does not run here "
             "(the lowering is tested against a torch reimplementation of tiny-cuda-nn's forward: docs/tcnn.md)")


class Builder:
    """A GraphModule grown node by node from (type, params, tensors), as a bundle describes them."""

    def __init__(self, model: Model):
        from inshade.models import GraphModule

        self.model = model
        self.g = GraphModule([("x", model.n_input_dims)])
        self.counts: dict[str, int] = {}

    def node(self, kind: str, params: dict, inputs: list[str], tensors: dict | None = None,
             where: str = "") -> str:
        from inshade.components import COMPONENTS, ComponentError
        from inshade.models import TORCH_COMPONENTS

        if kind not in COMPONENTS:
            raise self.model.ctx.error(where, f"needs inshade's {kind!r} component, which this install lacks")
        vid = f"{kind}{self.counts.get(kind, 0)}"
        self.counts[kind] = self.counts.get(kind, 0) + 1
        in_dim = sum(self.g.dim(s) for s in inputs)
        try:
            comp = TORCH_COMPONENTS[kind].from_node(params, in_dim, tensors or {})
            self.g.add(vid, comp, inputs)
        except ComponentError as exc:
            raise self.model.ctx.error(where, str(exc)) from None
        return vid

    def width(self, value: str) -> int:
        return self.g.dim(value)


class Cursor:
    """Reads the flat parameter vector in order."""

    def __init__(self, values: np.ndarray):
        self.values, self.at = values, 0

    def take(self, count: int, shape) -> np.ndarray:
        out = self.values[self.at:self.at + count].reshape(shape)
        self.at += count
        return out


# --- activations (common_device.h warp_activation), each as the components computing it ------

def leaky_slope(dtype: str) -> float:
    """LeakyReLU multiplies by (T)0.01f, T the network's precision: 0.01000213623046875 in fp16."""
    return float(np.float16(0.01)) if dtype == "float16" else float(np.float32(0.01))


def _elementwise(kind: str, **params):
    return lambda b, src, dtype, where: b.node(kind, dict(params), [src], where=where)


def _squareplus(b: Builder, src: str, dtype: str, where: str) -> str:
    """X = 10 x; 0.5 (X + sqrt(X X + 4)) / 10. The square is |X| |X| (the same value): a product
    of two non-negative lanes, so bounds propagated through the graph (inshade info's parity
    envelope) know the square root's argument is positive."""
    n = b.width(src)
    x = b.node("affine", {}, [src], {"scale": np.full(n, K_ACT), "offset": np.zeros(n)}, where)
    size = b.node("abs", {}, [x], where=where)
    square = b.node("mul", {}, [size, size], where=where)
    shifted = b.node("affine", {}, [square], {"scale": np.ones(n), "offset": np.full(n, 4.0)}, where)
    root = b.node("sqrt", {}, [shifted], where=where)
    total = b.node("add", {}, [x, root], where=where)
    return b.node("affine", {}, [total], {"scale": np.full(n, 0.5 / K_ACT), "offset": np.zeros(n)}, where)


ACTIVATIONS = {
    "none": lambda b, src, dtype, where: src,
    "relu": _elementwise("relu"),
    "leakyrelu": lambda b, src, dtype, where: b.node("leaky_relu", {"slope": leaky_slope(dtype)}, [src], where=where),
    "silu": _elementwise("silu"),
    "exponential": _elementwise("exp"),
    "sine": _elementwise("sin", omega0=1.0),
    "sigmoid": _elementwise("sigmoid"),
    "tanh": _elementwise("tanh"),
    "softplus": _elementwise("softplus", beta=K_ACT),     # log(exp(10 x) + 1) / 10
    "squareplus": _squareplus,
}


# --- the network ---------------------------------------------------------------------------

def _first_layer(b: Builder, weight: np.ndarray, lanes: list, where: str) -> str:
    """y = W e for e the encoding's lanes: the computed ones are the inputs of one dense node (its
    columns in the order the values hold them), the constant ones go into its bias."""
    values = list(dict.fromkeys(ref[0] for ref in lanes if isinstance(ref, tuple)))
    if not values:
        raise b.model.ctx.error("encoding", "computes nothing from the input (every lane is padding)")
    start = dict(zip(values, np.cumsum([0] + [b.width(v) for v in values[:-1]])))
    columns = np.zeros((weight.shape[0], sum(b.width(v) for v in values)), np.float64)
    bias = np.zeros(weight.shape[0], np.float64)
    for j, ref in enumerate(lanes):
        if isinstance(ref, tuple):
            columns[:, start[ref[0]] + ref[1]] += weight[:, j]
        else:
            bias += weight[:, j].astype(np.float64) * ref
    has_bias = bool(np.any(bias != 0.0))
    tensors = {"weight": columns.astype(np.float32), **({"bias": bias.astype(np.float32)} if has_bias else {})}
    return b.node("dense", {"out": int(weight.shape[0]), "bias": has_bias}, values, tensors, where)


def lower_network(b: Builder, lanes: list, params: Cursor, dtype: str) -> str:
    net = b.model.network
    shapes = net.shapes
    matrices = [params.take(rows * cols, (rows, cols)) for rows, cols in shapes]
    last = len(matrices) - 1
    value = None
    for i, w in enumerate(matrices):
        where = f"network (layer {i})"
        if i == last:
            w = w[:net.n_output_dims]   # the rows past n_output_dims are padding: the bindings slice them off
        if i == 0:
            value = _first_layer(b, w, lanes, where)
        else:
            value = b.node("dense", {"out": int(w.shape[0]), "bias": False}, [value], {"weight": w}, where)
        activation = net.output_activation if i == last else net.activation
        value = ACTIVATIONS[activation](b, value, dtype, where)
    return value


def _output(b: Builder, lanes: list) -> str:
    """An encoding's lanes as one value: a select over the values involved (and a constants node
    for padding lanes), or the single value itself when it is already in order."""
    values = list(dict.fromkeys(ref[0] for ref in lanes if isinstance(ref, tuple)))
    if not values:
        raise b.model.ctx.error("encoding", "computes nothing from the input (every lane is padding)")
    if len(values) == 1 and lanes == lanes_of(values[0], b.width(values[0])):
        return values[0]
    constants = [c for c in lanes if not isinstance(c, tuple)]
    sources = list(values)
    if constants:   # 0 * x + c: exactly c for every finite input
        first = b.node("select", {"lanes": [0] * len(constants)}, ["x"], where="encoding")
        sources.append(b.node("affine", {}, [first], {"scale": np.zeros(len(constants)),
                                                       "offset": np.asarray(constants)}, "encoding"))
    start = dict(zip(sources, np.cumsum([0] + [b.width(v) for v in sources[:-1]])))
    picks, k = [], 0
    for ref in lanes:
        if isinstance(ref, tuple):
            picks.append(int(start[ref[0]] + ref[1]))
        else:
            picks.append(int(start[sources[-1]] + k))
            k += 1
    return b.node("select", {"lanes": picks}, sources, where="encoding")


def lower(model: Model, params: np.ndarray, dtype: str):
    """The model with these parameters (float32 values, stored as ``dtype``) as a GraphModule:
    input "x" [n_input_dims], output "y" [n_output_dims]."""
    if params.size != model.n_params():
        raise ConvertError(f"{params.size} parameters; the config needs {model.n_params()}: {model.count_text()}")
    if model.network is not None:
        model.network.check_precision(model.ctx, dtype)
    b = Builder(model)
    cursor = Cursor(np.asarray(params, np.float32))
    if model.network is not None:
        network_params = Cursor(cursor.take(model.network.n_params(), (-1,)))   # the network's come first
        lanes = lower_encoding(b, model.encoding, "x", cursor, dtype)
        out = lower_network(b, lanes, network_params, dtype)
    else:
        out = _output(b, lower_encoding(b, model.encoding, "x", cursor, dtype))
    b.g.output("y", out)
    return b.g


def provenance(model: Model, config_path, params_path, dtype: str, count: int) -> dict:
    out = {"source": "tiny-cuda-nn", "model": model.kind, "config": str(config_path), "params": str(params_path),
           "params_dtype": dtype, "params_count": int(count), "resolved": model.resolved(),
           "checked_against": "the bundle's torch twin (tiny-cuda-nn needs CUDA; docs/tcnn.md)",
           **recorded_at()}
    if model.ctx.ignored:
        out["ignored_keys"] = list(model.ctx.ignored)
    return out


def to_bundle(config, params: np.ndarray, dtype: str, *, source: str = "config", n_input_dims=None,
              n_output_dims=None, name: str = "tcnn", config_path="", params_path=""):
    """(bundle, model) for a parsed config (a dict) and its parameter vector."""
    model = parse_model(config, source, n_input_dims, n_output_dims)
    graph = lower(model, params, dtype)
    bundle = graph.export(KIND, name, provenance=provenance(model, config_path or source, params_path, dtype,
                                                            params.size))
    return bundle, model


def convert(config_path, params_path, folder, *, n_input_dims: int | None = None, n_output_dims: int | None = None,
            params_key: str | None = None, name: str | None = None, as_: str | None = None, check: bool = True,
            force: bool = False, quiet: bool = False, example=None, semantics: dict | None = None,
            colour: str | None = None, targets=(), precision: str | dict = "f32", max_error: float | None = None):
    """A tiny-cuda-nn config (.json) and its parameter file -> a bundle folder (its dense weights at
    ``precision``, or within ``max_error``, as ``inshade.export``), its GLSL (and each of ``targets``' code)
    checked
    against the bundle's torch twin on ``example`` ([N, inputs], default uniform [0, 1]) plus
    random rows in its range."""
    from inshade import asset_folder
    from inshade.bundle import JSONFileError, read_json
    from inshade.models import GraphModule

    from .export import finish
    from .tcnn_params import read_params

    folder = Path(folder)
    asset_folder.claim(folder, folder.name, force=force, option="-o")
    config_path, params_path = Path(config_path), Path(params_path)
    try:
        config = read_json(config_path)
    except JSONFileError as exc:
        raise ConvertError(f"{config_path}: {exc}") from None
    model = parse_model(config, str(config_path), n_input_dims, n_output_dims)
    params, dtype = read_params(params_path, model.n_params(), params_key)
    if params.size != model.n_params():
        raise ConvertError(f"{params_path}: {params.size} parameters; {config_path} needs {model.n_params()}: "
                           f"{model.count_text()}")
    if model.ctx.ignored and not quiet:
        print(f"note: {config_path}: tiny-cuda-nn ignores {', '.join(model.ctx.ignored)}; so does inshade",
              file=sys.stderr)
    graph = lower(model, params, dtype)
    bundle = graph.export(KIND, name or config_path.stem,
                          provenance=provenance(model, config_path, params_path, dtype, params.size))
    if example is None:
        example = np.random.default_rng(0).uniform(0, 1, (CHECK_ROWS, bundle.in_dim)).astype(np.float32)
    example = np.asarray(example, np.float32)
    if example.ndim != 2 or example.shape[1] != bundle.in_dim:
        raise ConvertError(f"example: shape {list(example.shape)}; the model takes [N, {bundle.in_dim}]")
    if check and not quiet:
        print(TWIN_NOTE, file=sys.stderr)
    return finish(bundle, GraphModule.from_bundle(bundle), [example], folder, check=check, quiet=quiet,
                  as_=as_, semantics=semantics, colour=colour, targets=targets, precision=precision,
                  max_error=max_error)
