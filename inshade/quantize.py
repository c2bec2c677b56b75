"""Weight precisions: how a layer's numbers are stored where the shader reads them, and the bundle
that holds exactly the numbers the shader will compute with.

- ``f32``: as trained.
- ``f16``: weights and biases rounded to float16 (RGBA16F texture rows): half the bytes.
- ``i8``: each output row's weights as int8 codes in [-127, 127] times the row's float32 scale
  (symmetric: scale = max |w| / 127), biases float32: a quarter of the bytes. The shader rebuilds
  ``float(q) * scale``, one float32 product, as the bundle's float32 weight holds it.

``quantized(bundle, precision)`` is that bundle: its float32 tensors are the dequantized values, so
the torch twin computes what the shader computes and the parity rule holds against it; the error
against the source is the quantization's own (``inshade.convert.check`` reports both). The tables of
components with a ``precision`` parameter of their own (hash and dense grids, latent pyramids, sparse
voxels, mesh features) go from f32 to float16; under i8 every table takes its 8-bit form (u8, or a
lookup array's 8 bits: codes with a per-lane offset + scale, components/unorm.py; the values are
not centred, so a symmetric code would waste half its range), but for unbounded lookup arrays
(KEPT_UNDER_I8).
"""
from __future__ import annotations

import copy

import numpy as np

from inshade.components.spec import I8_MAX, i8_codes   # the check of an i8 bundle's codes, beside the spec
from inshade.components.unorm import as_codes

__all__ = ["I8_MAX", "PRECISIONS", "QUANTIZED_TYPES", "i8_codes", "lower_tables", "quantized", "row_scales",
           "table_nodes", "weight_bytes"]

PRECISIONS = ("f32", "f16", "i8")
# the parameter kinds that take a precision (node type -> the tensors it rounds)
QUANTIZED_TYPES = ("dense",)
_U8 = ("precision", "u8", ("f32", "f16"))
# table components' 8-bit forms, which i8 gives them: type -> ((the parameter, its 8-bit value, the
# values it is converted from), the slots coded)
EIGHT_BIT_FORMS = {"mesh_features": (_U8, lambda p: ["table"]), "hash_grid": (_U8, lambda p: ["table"]),
                   "dense_grid": (_U8, lambda p: ["table"]), "sparse_voxels": (_U8, lambda p: ["latents"]),
                   "latent_pyramid": (_U8, lambda p: [f"level{k}" for k in range(p["levels"])]),
                   "lookup_array": (("bits", 8, (32,)), lambda p: ["cells"])}
# the tables a precision of the whole network (``quantized(b, "i8")``) leaves as they are: a lookup
# array whose values no periodic function bounds (Differentiable Indirection's cascaded arrays, which
# its authors keep in float: quantising them is "cumbersome and ineffective"); a per-node precision
# or --max-error can still code them
KEPT_UNDER_I8 = {"lookup_array": lambda p: p.get("baked", "none") == "none"}


def row_scales(weight: np.ndarray) -> np.ndarray:
    """float32 [out]: max |w| / 127 per row (1 for a row of zeros, whose codes are all 0)."""
    peak = np.abs(np.asarray(weight, np.float32)).max(axis=1)
    return np.where(peak > 0, peak / np.float32(I8_MAX), np.float32(1.0)).astype(np.float32)


def _rounded(node_params: dict, tensors: dict, name, precision: str) -> None:
    weight = np.asarray(tensors[name("weight")], np.float32)
    if precision == "f16":
        tensors[name("weight")] = weight.astype(np.float16).astype(np.float32)
        if node_params.get("bias", True):
            tensors[name("bias")] = np.asarray(tensors[name("bias")], np.float32).astype(np.float16).astype(np.float32)
    elif precision == "i8":
        scale = row_scales(weight)
        q = np.clip(np.rint(weight / scale[:, None]), -I8_MAX, I8_MAX).astype(np.float32)
        tensors[name("weight")] = (q * scale[:, None]).astype(np.float32)
        tensors[name("weight_scale")] = scale
    node_params["precision"] = precision


def _half_table(node, tensors: dict, params: dict) -> None:
    """A table component at f32 stored at f16: its precision parameter, and the tensors that precision
    declares float16 values rounded to them."""
    from inshade.components import COMPONENTS

    params["precision"] = "f16"
    for slot, spec in COMPONENTS[node.type].tensors(params, node.in_dim).items():
        if spec.representable == "float16":
            name = node.tensor_name(slot)
            tensors[name] = np.asarray(tensors[name], np.float32).astype(np.float16).astype(np.float32)


def table_nodes(bundle) -> list:
    """The nodes of other types than QUANTIZED_TYPES that store a table at f32 and have an f16 form."""
    from inshade.components import COMPONENTS

    out = []
    for n in bundle.nodes:
        param = COMPONENTS[n.type].params.get("precision")
        if (n.type not in QUANTIZED_TYPES and param is not None and n.params.get("precision") == "f32"
                and param.check is not None and param.check("f16")):
            out.append(n)
    return out


def _eight_bit_form(node):
    """(parameter, its 8-bit value, coded slots) where ``node``'s table can take its 8-bit form, else None."""
    (param, value, sources), slots = EIGHT_BIT_FORMS.get(node.type, ((None, None, ()), None))
    return (param, value, slots(node.params)) if node.params.get(param) in sources else None


def _to_eight_bit(node, tensors: dict, params: dict) -> None:
    """A table turned to its 8-bit form from its values as they are (in place)."""
    param, value, slots = _eight_bit_form(node)
    coded = {s: np.asarray(tensors[node.tensor_name(s)], np.float32) for s in slots}
    as_codes(coded, slots)
    tensors.update({node.tensor_name(k): v for k, v in coded.items()})
    params[param] = value


def lower_tables(bundle) -> list:
    """The table nodes a precision below f32 can store smaller: an 8-bit form, or f32 -> f16."""
    halves = {n.id for n in table_nodes(bundle)}
    return [n for n in bundle.nodes if n.id in halves or _eight_bit_form(n) is not None]


def _table_choices(bundle, precision) -> dict:
    """{table node id: precision} as ``quantized`` takes them: a precision for all, or a dict's own
    entries (a table a dict leaves out goes to f16 where any dense layer goes below f32)."""
    tables = lower_tables(bundle)
    if isinstance(precision, str):
        return {n.id: "f32" if precision == "i8" and KEPT_UNDER_I8.get(n.type, lambda p: False)(n.params)
                else precision for n in tables}
    dense_below = {v for k, v in precision.items() if bundle.node(k).type in QUANTIZED_TYPES} - {"f32"}
    return {n.id: precision.get(n.id, "f16" if dense_below else "f32") for n in tables}


def quantized(bundle, precision: str | dict, *, name: str | None = None):
    """``bundle`` with its dense layers stored at ``precision`` (one of PRECISIONS, or {node id:
    precision} for some layers and tables) and, below f32, its f32 tables at f16 (at i8 every table in
    its 8-bit form, from its values as they are): a new, validated Bundle whose numbers are the values
    those precisions give (a layer already at another precision is re-quantized from its current
    values)."""
    from inshade.bundle import Bundle

    per_node = precision if isinstance(precision, dict) else {
        n.id: precision for n in bundle.nodes if n.type in QUANTIZED_TYPES}
    bad = sorted(set(per_node.values()) - set(PRECISIONS))
    if bad:
        raise ValueError(f"precision {bad[0]!r}: choose from {', '.join(PRECISIONS)}")
    unknown = sorted(set(per_node) - {n.id for n in bundle.nodes})
    if unknown:
        raise ValueError(f"node {unknown[0]}: no such node in the bundle")
    tables = _table_choices(bundle, precision)
    meta = copy.deepcopy(bundle.meta)
    tensors = dict(bundle.tensors)
    by_id = {n["id"]: n for n in meta["nodes"]}
    halves = {n.id for n in table_nodes(bundle)}
    for node in bundle.nodes:
        params = by_id[node.id].setdefault("params", {})
        if node.id in tables:
            if tables[node.id] == "i8" and _eight_bit_form(node) is not None:
                _to_eight_bit(node, tensors, params)
            elif tables[node.id] != "f32" and node.id in halves:
                _half_table(node, tensors, {**node.params, **params})
                params["precision"] = "f16"
            continue
        if node.id not in per_node or node.type in EIGHT_BIT_FORMS:   # a table stored at its lowest already
            continue
        if node.type not in QUANTIZED_TYPES:
            raise ValueError(f"node {node.id}: a {node.type} takes no precision (types that do: "
                             f"{', '.join(QUANTIZED_TYPES)} and the tables)")
        tensors.pop(node.tensor_name("weight_scale"), None)
        _rounded(params, tensors, node.tensor_name, per_node[node.id])
    if name is not None:
        meta["name"] = name
    return Bundle(meta, tensors)


def weight_bytes(bundle) -> int:
    """Bytes of the dense layers' weights and biases at their precisions (the i8 scales counted)."""
    total = 0
    for n in bundle.nodes:
        if n.type not in QUANTIZED_TYPES:
            continue
        p = n.params.get("precision", "f32")
        w = bundle.tensor(n, "weight").size
        b = bundle.tensor(n, "bias").size if n.params["bias"] else 0
        total += {"f32": 4 * (w + b), "f16": 2 * (w + b), "i8": w + 4 * b + 4 * n.out_dim}[p]
    return total
