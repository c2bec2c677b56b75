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
not centred, so a symmetric code would waste half its range).
"""
from __future__ import annotations

import copy

import numpy as np

from inshade.components.spec import I8_MAX, i8_codes   # the check of an i8 bundle's codes, beside the spec
from inshade.components.unorm import as_codes

__all__ = ["I8_MAX", "PRECISIONS", "QUANTIZED_TYPES", "i8_codes", "quantized", "row_scales", "table_nodes",
           "weight_bytes"]

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


def _eight_bit_tables(bundle, tensors: dict, by_id: dict) -> set:
    """The tables with an 8-bit form turned to it, from their values as they are (in place in
    ``tensors`` and the nodes' params ``by_id``); returns the ids of the nodes converted."""
    done = set()
    for node in bundle.nodes:
        (param, value, sources), slots = EIGHT_BIT_FORMS.get(node.type, ((None, None, ()), None))
        if node.params.get(param) not in sources:
            continue
        coded = {s: np.asarray(tensors[node.tensor_name(s)], np.float32) for s in slots(node.params)}
        as_codes(coded, list(coded))
        tensors.update({node.tensor_name(k): v for k, v in coded.items()})
        by_id[node.id].setdefault("params", {})[param] = value
        done.add(node.id)
    return done


def quantized(bundle, precision: str | dict, *, name: str | None = None):
    """``bundle`` with its dense layers stored at ``precision`` (one of PRECISIONS, or {node id:
    precision} for some layers) and, below f32, its f32 tables at f16 (at i8 every table in its 8-bit
    form, from its values as they are): a new, validated Bundle whose
    numbers are the values those precisions give (a layer already at another precision is re-quantized
    from its current values)."""
    from inshade.bundle import Bundle

    per_node = precision if isinstance(precision, dict) else {
        n.id: precision for n in bundle.nodes if n.type in QUANTIZED_TYPES}
    bad = sorted(set(per_node.values()) - set(PRECISIONS))
    if bad:
        raise ValueError(f"precision {bad[0]!r}: choose from {', '.join(PRECISIONS)}")
    meta = copy.deepcopy(bundle.meta)
    tensors = dict(bundle.tensors)
    by_id = {n["id"]: n for n in meta["nodes"]}
    for node in bundle.nodes:
        if node.id not in per_node:
            continue
        if node.type not in QUANTIZED_TYPES:
            raise ValueError(f"node {node.id}: a {node.type} takes no precision (types that do: "
                             f"{', '.join(QUANTIZED_TYPES)})")
        params = by_id[node.id].setdefault("params", {})
        tensors.pop(node.tensor_name("weight_scale"), None)
        _rounded(params, tensors, node.tensor_name, per_node[node.id])
    coded = _eight_bit_tables(bundle, tensors, by_id) if precision == "i8" else set()
    if (set(per_node.values()) if isinstance(precision, dict) else {precision}) - {"f32"}:
        for node in table_nodes(bundle):
            if node.id not in coded:
                _half_table(node, tensors, {**node.params, **by_id[node.id].setdefault("params", {})})
                by_id[node.id]["params"]["precision"] = "f16"
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
