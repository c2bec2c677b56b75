"""Bundle format v1: `bundle.json` (the graph) + `weights.safetensors` (the tensors).

The bundle is the contract between training and runtime. Loading validates everything a
stranger's file could get wrong and answers with one `BundleError` that names the file and
the field. Tensors are read with safetensors only: a bundle can never run code.

Tensor names are derived, not declared: node `l0`'s slot `weight` is tensor `l0.weight`.
"""
from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .components import COMPONENTS, ComponentError, check_node, resolve_params

FORMAT = "inshade.bundle"
VERSION = 1
SUPPORTED_VERSIONS = (1,)
JSON_NAME = "bundle.json"
WEIGHTS_NAME = "weights.safetensors"
MAX_JSON_BYTES = 16 << 20
MAX_INPUT_DIM = 64
_ID = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,47}$")


class BundleError(ValueError):
    """Malformed bundle. `where` is the file, `field` the JSON path or tensor name."""

    def __init__(self, where, field: str, message: str):
        self.where, self.field, self.message = str(where), field, message
        super().__init__(f"{self.where}: {field}: {message}" if field else f"{self.where}: {message}")


@dataclass(frozen=True)
class Node:
    id: str
    type: str
    inputs: tuple[str, ...]
    params: dict
    in_dim: int
    out_dim: int

    def tensor_name(self, slot: str) -> str:
        return f"{self.id}.{slot}"


@dataclass(frozen=True)
class Port:
    name: str
    dim: int
    semantic: str
    node: str = ""


class Bundle:
    """A validated bundle in memory. Build with `Bundle(meta, tensors)` or `load(path)`."""

    def __init__(self, meta: dict, tensors: dict[str, np.ndarray], path: Path | None = None):
        self.path = Path(path) if path is not None else None
        where = self.path / JSON_NAME if self.path else "<bundle>"
        self.meta = meta
        self.inputs, self.nodes, self.outputs = _parse_graph(meta, where)
        self.tensors = dict(tensors)
        _check_tensors(self, self.path / WEIGHTS_NAME if self.path else "<weights>")

    # graph queries -------------------------------------------------------------------
    @property
    def kind(self) -> str:
        return self.meta["kind"]

    @property
    def name(self) -> str:
        return self.meta.get("name", self.kind)

    @property
    def in_dim(self) -> int:
        return sum(p.dim for p in self.inputs)

    @property
    def out_dim(self) -> int:
        return sum(p.dim for p in self.outputs)

    def output_lanes(self, name: str) -> tuple[int, int] | None:
        """(offset, width) of output `name` in the concatenated outputs, or None if absent."""
        offset = 0
        for p in self.outputs:
            if p.name == name:
                return offset, p.dim
            offset += p.dim
        return None

    def node(self, node_id: str) -> Node:
        return next(n for n in self.nodes if n.id == node_id)

    def tensor(self, node: Node, slot: str) -> np.ndarray:
        return self.tensors[node.tensor_name(slot)]

    def dims(self) -> dict[str, int]:
        """Width of every value in the graph: inputs and node outputs."""
        out = {p.name: p.dim for p in self.inputs}
        out.update({n.id: n.out_dim for n in self.nodes})
        return out

    def digest(self) -> str:
        """sha256 over the canonical JSON and the tensors: names what a render came from."""
        h = hashlib.sha256(canonical_json(self.meta).encode())
        for name in sorted(self.tensors):
            a = np.ascontiguousarray(self.tensors[name])
            h.update(f"{name}:{a.dtype.str}:{a.shape}".encode())
            h.update(a.tobytes())
        return h.hexdigest()

    # files --------------------------------------------------------------------------
    def save(self, folder) -> Path:
        from safetensors.numpy import save_file

        from inshade.files import atomic_files

        folder = Path(folder)
        with atomic_files(folder / JSON_NAME, folder / WEIGHTS_NAME) as (meta_tmp, weights_tmp):
            meta_tmp.write_text(canonical_json(self.meta))
            save_file({k: np.ascontiguousarray(v) for k, v in sorted(self.tensors.items())},
                      str(weights_tmp), metadata={"format": FORMAT})
        self.path = folder
        return folder


def canonical_json(meta: dict) -> str:
    return json.dumps(meta, indent=2, sort_keys=True, allow_nan=False) + "\n"


def load(path) -> Bundle:
    """Loads and validates a bundle folder (or its bundle.json)."""
    path = Path(path)
    if path.name == JSON_NAME:
        path = path.parent
    jpath, wpath = path / JSON_NAME, path / WEIGHTS_NAME
    if not path.is_dir():
        raise BundleError(path, "", "not a bundle folder (expected bundle.json + weights.safetensors)")
    if not jpath.is_file():
        raise BundleError(jpath, "", "missing")
    if jpath.stat().st_size > MAX_JSON_BYTES:
        raise BundleError(jpath, "", f"larger than {MAX_JSON_BYTES} bytes")
    try:
        meta = json.loads(jpath.read_text(encoding="utf-8"),
                          parse_constant=lambda c: (_ for _ in ()).throw(ValueError(f"{c} is not JSON")))
    except (ValueError, UnicodeDecodeError) as e:
        raise BundleError(jpath, "", f"not valid JSON ({e})") from None
    _parse_graph(meta, jpath)  # the graph's errors first: they explain the tensors' errors
    if not wpath.is_file():
        raise BundleError(wpath, "", "missing")
    tensors = _read_safetensors(wpath)
    return Bundle(meta, tensors, path)


def _read_safetensors(wpath: Path) -> dict[str, np.ndarray]:
    from safetensors import SafetensorError
    from safetensors.numpy import load_file

    size = wpath.stat().st_size
    with open(wpath, "rb") as f:
        head = f.read(8)
    if len(head) < 8:
        raise BundleError(wpath, "", "truncated: shorter than the 8-byte safetensors header length")
    header_len = int.from_bytes(head, "little")
    if header_len > min(size - 8, 100 << 20):
        raise BundleError(wpath, "", f"truncated or corrupt: header claims {header_len} bytes, file has {size}")
    try:
        return load_file(str(wpath))
    except (SafetensorError, ValueError, OSError) as e:
        raise BundleError(wpath, "", f"unreadable safetensors ({e})") from None


def _req(obj, key, kind, where, field):
    if not isinstance(obj, dict) or key not in obj:
        raise BundleError(where, field, "missing")
    v = obj[key]
    if kind is int and isinstance(v, bool) or not isinstance(v, kind):
        raise BundleError(where, field, f"must be {getattr(kind, '__name__', kind)}, got {type(v).__name__}")
    return v


def _parse_graph(meta, where):
    if not isinstance(meta, dict):
        raise BundleError(where, "", "top level must be an object")
    fmt = _req(meta, "format", str, where, "format")
    if fmt != FORMAT:
        raise BundleError(where, "format", f"expected '{FORMAT}', got '{fmt}'")
    version = _req(meta, "version", int, where, "version")
    if version not in SUPPORTED_VERSIONS:
        raise BundleError(where, "version", f"unsupported version {version} (this inshade reads {SUPPORTED_VERSIONS})")
    kind = _req(meta, "kind", str, where, "kind")
    if not _ID.match(kind):
        raise BundleError(where, "kind", f"invalid kind {kind!r}")
    known = {"format", "version", "kind", "name", "inputs", "nodes", "outputs", "provenance", "metrics", "render"}
    extra = sorted(set(meta) - known)
    if extra:
        raise BundleError(where, extra[0], "unknown top-level field")

    inputs, dims = [], {}
    for i, p in enumerate(_req(meta, "inputs", list, where, "inputs")):
        f = f"inputs[{i}]"
        name = _req(p, "name", str, where, f + ".name")
        dim = _req(p, "dim", int, where, f + ".dim")
        if not _ID.match(name) or name in dims:
            raise BundleError(where, f + ".name", f"invalid or repeated name {name!r}")
        if not 1 <= dim <= MAX_INPUT_DIM:
            raise BundleError(where, f + ".dim", f"must be 1..{MAX_INPUT_DIM}, got {dim}")
        inputs.append(Port(name, dim, str(p.get("semantic", "generic"))))
        dims[name] = dim
    if not inputs:
        raise BundleError(where, "inputs", "a bundle needs at least one input")

    nodes = []
    for i, n in enumerate(_req(meta, "nodes", list, where, "nodes")):
        f = f"nodes[{i}]"
        nid = _req(n, "id", str, where, f + ".id")
        ntype = _req(n, "type", str, where, f + ".type")
        srcs = _req(n, "inputs", list, where, f + ".inputs")
        if not _ID.match(nid) or nid in dims:
            raise BundleError(where, f + ".id", f"invalid or repeated id {nid!r}")
        if ntype not in COMPONENTS:
            raise BundleError(where, f + ".type", f"unknown component type: {ntype}")
        if not srcs:
            raise BundleError(where, f + ".inputs", "empty")
        for s in srcs:
            if s not in dims:
                raise BundleError(where, f + ".inputs", f"'{s}' is not an input or an earlier node")
        in_dim = sum(dims[s] for s in srcs)
        try:
            params = resolve_params(ntype, n.get("params", {}))
            out_dim = check_node(ntype, params, in_dim)
        except ComponentError as e:
            raise BundleError(where, f + ".params", str(e)) from None
        nodes.append(Node(nid, ntype, tuple(srcs), params, in_dim, out_dim))
        dims[nid] = out_dim

    outputs = []
    for i, p in enumerate(_req(meta, "outputs", list, where, "outputs")):
        f = f"outputs[{i}]"
        name = _req(p, "name", str, where, f + ".name")
        node = _req(p, "node", str, where, f + ".node")
        if node not in dims:
            raise BundleError(where, f + ".node", f"'{node}' is not a node or input")
        outputs.append(Port(name, dims[node], str(p.get("semantic", "generic")), node))
    if not outputs:
        raise BundleError(where, "outputs", "a bundle needs at least one output")
    return inputs, nodes, outputs


def _check_tensors(bundle: Bundle, where):
    expected = {}
    for n in bundle.nodes:
        for slot, spec in COMPONENTS[n.type].tensors(n.params, n.in_dim).items():
            expected[n.tensor_name(slot)] = spec
    have = set(bundle.tensors)
    missing, extra = sorted(set(expected) - have), sorted(have - set(expected))
    if missing:
        raise BundleError(where, missing[0], "missing tensor")
    if extra:
        raise BundleError(where, extra[0], "unexpected tensor (no node declares it)")
    for name, spec in expected.items():
        a = bundle.tensors[name]
        if not isinstance(a, np.ndarray):
            raise BundleError(where, name, "not an array")
        if a.dtype != np.dtype(spec.dtype):
            raise BundleError(where, name, f"dtype {a.dtype} but {spec.dtype} expected")
        if tuple(a.shape) != spec.shape:
            raise BundleError(where, name, f"shape {list(a.shape)} but {list(spec.shape)} expected")
        if a.dtype.kind == "f" and not np.isfinite(a).all():
            raise BundleError(where, name, "contains NaN or Inf")
