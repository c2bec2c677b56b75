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
from .components.spec import i8_codes
from .port_layout import check_shape

FORMAT = "inshade.bundle"
VERSION = 1
SUPPORTED_VERSIONS = (1,)
JSON_NAME = "bundle.json"
WEIGHTS_NAME = "weights.safetensors"
MAX_JSON_BYTES = 16 << 20
MAX_JSON_DEPTH = 64
MAX_WEIGHTS_BYTES = 4 << 30          # a weights file larger than this is refused before reading
MAX_SAFETENSORS_HEADER = 100 << 20
# safetensors dtype -> (numpy dtype as stored, itemsize); F16/BF16 are widened to float32 at load
# (exact: every half and bfloat16 value is a float32 value) and `Bundle.converted` records it.
SAFETENSORS_DTYPES = {"F64": ("<f8", 8), "F32": ("<f4", 4), "F16": ("<f2", 2), "BF16": ("<u2", 2),
                      "I64": ("<i8", 8), "I32": ("<i4", 4), "I16": ("<i2", 2), "I8": ("i1", 1),
                      "U64": ("<u8", 8), "U32": ("<u4", 4), "U16": ("<u2", 2), "U8": ("u1", 1),
                      "BOOL": ("?", 1)}
WIDENED = {"F16": "float16", "BF16": "bfloat16"}
MAX_INPUT_DIM = 64
# input lane types: "uint" inputs (e.g. a triangle id) reach GLSL as uint, torch carries them as
# float32 values that are exact integers, so they must stay below UINT_INPUT_RANGE
INPUT_DTYPES = ("float", "uint")
UINT_INPUT_RANGE = 1 << 24
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
    dtype: str = "float"   # inputs only: "uint" lanes are unsigned integers (GLSL uvec4; torch: exact floats < 2^24)
    shape: tuple | None = None   # the full tensor shape, None on the batch axes (port_layout.py); None: rows


class Bundle:
    """A validated bundle in memory. Build with `Bundle(meta, tensors)` or `load(path)`."""

    def __init__(self, meta: dict, tensors: dict[str, np.ndarray], path: Path | None = None,
                 converted: dict[str, str] | None = None):
        self.path = Path(path) if path is not None else None
        where = self.path / JSON_NAME if self.path else "<bundle>"
        self.meta = meta
        self.inputs, self.nodes, self.outputs = _parse_graph(meta, where)
        self.tensors = dict(tensors)
        # tensor name -> dtype it was stored as, for tensors widened to float32 at load (F16/BF16)
        self.converted = dict(converted or {})
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
    try:
        meta = read_json(jpath)
    except JSONFileError as e:
        raise BundleError(jpath, "", str(e)) from None
    _parse_graph(meta, jpath)  # the graph's errors first: they explain the tensors' errors
    if not wpath.is_file():
        raise BundleError(wpath, "", "missing")
    tensors, converted = _read_safetensors(wpath)
    return Bundle(meta, tensors, path, converted)


class JSONFileError(ValueError):
    """A JSON file that is not plain, unambiguous JSON (the message does not name the file)."""


def _no_duplicates(pairs):
    out = {}
    for k, v in pairs:
        if k in out:
            raise JSONFileError(f"key {k!r} appears twice in one object (ambiguous)")
        out[k] = v
    return out


def _no_constant(name):
    raise JSONFileError(f"{name} is not JSON (numbers must be finite)")


def _finite_float(text):
    v = float(text)
    if not np.isfinite(v):
        raise JSONFileError(f"number {text[:40]} is out of range (it would be {v})")
    return v


def parse_json_bytes(data: bytes, max_depth: int = MAX_JSON_DEPTH):
    """Strict JSON from bytes: UTF-8 without BOM, no duplicate keys, no NaN/Infinity, no numbers
    that overflow, at most `max_depth` levels of nesting. Raises JSONFileError("not valid JSON: ...")."""
    try:
        return _parse_json(data, max_depth)
    except JSONFileError as e:
        raise JSONFileError(f"not valid JSON: {e}") from None


def _parse_json(data: bytes, max_depth: int):
    if not data.strip():
        raise JSONFileError("empty file (expected a JSON object)")
    if data.startswith(b"\xef\xbb\xbf"):
        raise JSONFileError("starts with a UTF-8 byte order mark; save it as UTF-8 without BOM")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise JSONFileError(f"not UTF-8 text (byte 0x{data[e.start]:02x} at offset {e.start})") from None
    try:
        value = json.loads(text, object_pairs_hook=_no_duplicates, parse_constant=_no_constant,
                           parse_float=_finite_float)
    except JSONFileError:
        raise
    except json.JSONDecodeError as e:
        raise JSONFileError(f"{e.msg} at line {e.lineno} column {e.colno}") from None
    except RecursionError:
        raise JSONFileError(f"nested more than {max_depth} levels deep") from None
    except ValueError as e:   # e.g. an integer with thousands of digits
        raise JSONFileError(str(e).splitlines()[0][:120]) from None
    stack = [(value, 1)]
    while stack:   # iterative: deep nesting must not be what stops a later recursive walk
        item, depth = stack.pop()
        if isinstance(item, (dict, list)):
            if depth > max_depth:
                raise JSONFileError(f"nested more than {max_depth} levels deep")
            stack.extend((v, depth + 1) for v in (item.values() if isinstance(item, dict) else item))
    return value


def read_json(path, max_bytes: int = MAX_JSON_BYTES):
    """Strict JSON from a file (see parse_json_bytes); JSONFileError for a file that is not a
    regular readable file, is too large, or is not plain JSON."""
    path = Path(path)
    if path.is_dir():
        raise JSONFileError("is a folder, expected a JSON file")
    try:
        size = path.stat().st_size
        if size > max_bytes:
            raise JSONFileError(f"larger than {max_bytes} bytes")
        with open(path, "rb") as f:
            data = f.read(max_bytes + 1)
    except OSError as e:
        raise JSONFileError(f"cannot read ({e.strerror or e})") from None
    if len(data) > max_bytes:
        raise JSONFileError(f"larger than {max_bytes} bytes")
    return parse_json_bytes(data)


def _read_safetensors(wpath: Path) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Tensors of a safetensors file, read by this parser (numpy only, nothing executable): the
    header is checked whole (dtypes, shapes, offsets that tile the data exactly, sizes within the
    file) before any tensor memory is allocated. F16/BF16 tensors are widened to float32 (exact);
    returns (tensors, {name: stored dtype} of those)."""
    def bad(message, field=""):
        return BundleError(wpath, field, message)

    try:
        size = wpath.stat().st_size
        if size > MAX_WEIGHTS_BYTES:
            raise bad(f"larger than {MAX_WEIGHTS_BYTES} bytes")
        with open(wpath, "rb") as f:
            head = f.read(8)
            if len(head) < 8:
                raise bad("truncated: shorter than the 8-byte safetensors header length")
            header_len = int.from_bytes(head, "little")
            if header_len > min(size - 8, MAX_SAFETENSORS_HEADER):
                raise bad(f"truncated or corrupt: header claims {header_len} bytes, file has {size}")
            raw = f.read(header_len)
            if not raw.lstrip().startswith(b"{"):
                raise bad("unreadable safetensors (the header is not a JSON object; not a safetensors file?)")
            try:
                header = parse_json_bytes(raw)
            except JSONFileError as e:
                raise bad(f"unreadable safetensors (header: {e})") from None
            if not isinstance(header, dict):
                raise bad("unreadable safetensors (the header is not a JSON object)")
            data_len = size - 8 - header_len
            entries = []
            for name, spec in header.items():
                if name == "__metadata__":
                    if not isinstance(spec, dict) or not all(isinstance(v, str) for v in spec.values()):
                        raise bad("__metadata__ must map names to strings", "__metadata__")
                    continue
                if not isinstance(spec, dict) or set(spec) != {"dtype", "shape", "data_offsets"}:
                    raise bad("header entry must be {dtype, shape, data_offsets}", name)
                dtype, shape, offsets = spec["dtype"], spec["shape"], spec["data_offsets"]
                if dtype not in SAFETENSORS_DTYPES:
                    raise bad(f"unsupported dtype {dtype!r} (known: {', '.join(SAFETENSORS_DTYPES)})", name)
                if not (isinstance(shape, list) and len(shape) <= 8 and all(
                        isinstance(d, int) and not isinstance(d, bool) and 0 <= d < (1 << 40) for d in shape)):
                    raise bad(f"shape must be a list of at most 8 sizes >= 0, got {str(shape)[:80]}", name)
                if not (isinstance(offsets, list) and len(offsets) == 2 and all(
                        isinstance(o, int) and not isinstance(o, bool) for o in offsets)
                        and 0 <= offsets[0] <= offsets[1]):
                    raise bad(f"data_offsets must be [begin, end] with 0 <= begin <= end, got {str(offsets)[:80]}",
                              name)
                count = int(np.prod(shape, dtype=object)) if shape else 1
                itemsize = SAFETENSORS_DTYPES[dtype][1]
                if count * itemsize > data_len:
                    raise bad(f"claims {count} {dtype} values ({count * itemsize} bytes); the file holds "
                              f"{data_len} bytes of data (truncated or corrupt)", name)
                if offsets[1] - offsets[0] != count * itemsize:
                    raise bad(f"data_offsets span {offsets[1] - offsets[0]} bytes but shape {shape} of {dtype} "
                              f"is {count * itemsize}", name)
                entries.append((offsets[0], offsets[1], name, dtype, shape, count))
            entries.sort(key=lambda e: (e[0], e[1]))
            at = 0
            for begin, end, name, *_ in entries:
                if begin != at:
                    raise bad("data_offsets overlap or leave a gap (corrupt)" if begin < at else
                              "data_offsets leave a gap in the data (corrupt)", name)
                at = end
            if at != data_len:
                raise bad(f"truncated or corrupt: the header indexes {at} bytes of data, the file holds {data_len}")
            buffer = bytearray(data_len)
            if f.readinto(buffer) != data_len:
                raise bad("truncated while reading")
    except OSError as e:
        raise bad(f"cannot read ({e.strerror or e})") from None
    tensors, converted = {}, {}
    for begin, end, name, dtype, shape, count in entries:
        stored = np.dtype(SAFETENSORS_DTYPES[dtype][0])
        a = np.frombuffer(buffer, stored, count, begin).reshape(shape)
        if dtype == "BF16":
            a = (a.astype(np.uint32) << 16).view(np.float32)
        elif dtype == "F16":
            a = a.astype(np.float32)
        elif begin % stored.itemsize:
            a = a.copy()   # aligned
        if dtype in WIDENED:
            converted[name] = WIDENED[dtype]
        tensors[name] = a.astype(a.dtype.newbyteorder("="), copy=False)
    return tensors, converted


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
        dtype = p.get("dtype", "float")
        if dtype not in INPUT_DTYPES:
            raise BundleError(where, f + ".dtype", f"must be one of {', '.join(INPUT_DTYPES)}, got {dtype!r}")
        inputs.append(Port(name, dim, str(p.get("semantic", "generic")), dtype=dtype,
                           shape=_port_shape(p, dim, where, f)))
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
        if not _ID.match(name) or any(o.name == name for o in outputs):
            raise BundleError(where, f + ".name", f"invalid or repeated name {name!r} (outputs are found by name)")
        node = _req(p, "node", str, where, f + ".node")
        if node not in dims:
            raise BundleError(where, f + ".node", f"'{node}' is not a node or input")
        outputs.append(Port(name, dims[node], str(p.get("semantic", "generic")), node,
                            shape=_port_shape(p, dims[node], where, f)))
    if not outputs:
        raise BundleError(where, "outputs", "a bundle needs at least one output")
    return inputs, nodes, outputs


def _port_shape(p: dict, dim: int, where, field: str) -> tuple | None:
    if "shape" not in p:
        return None
    why = check_shape(p["shape"], dim)
    if why:
        raise BundleError(where, field + ".shape", why)
    return tuple(p["shape"])


def _check_tensors(bundle: Bundle, where):
    expected, scales = {}, {}
    for n in bundle.nodes:
        for slot, spec in COMPONENTS[n.type].tensors(n.params, n.in_dim).items():
            expected[n.tensor_name(slot)] = spec
            if spec.scaled_by is not None:
                scales[n.tensor_name(slot)] = n.tensor_name(spec.scaled_by)
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
        if a.dtype != np.dtype(spec.dtype) or name in bundle.converted and spec.dtype != "float32":
            raise BundleError(where, name, f"dtype {bundle.converted.get(name, a.dtype)} but {spec.dtype} expected")
        if tuple(a.shape) != spec.shape:
            raise BundleError(where, name, f"shape {list(a.shape)} but {list(spec.shape)} expected")
        if a.dtype.kind == "f" and not np.isfinite(a).all():
            raise BundleError(where, name, "contains NaN or Inf")
        if spec.representable is not None:
            rt = a.astype(spec.representable).astype(a.dtype)
            if not np.array_equal(rt, a):
                bad = tuple(int(i) for i in np.argwhere(rt != a)[0])
                raise BundleError(where, name, f"value {float(a[bad]):.9g} at {list(bad)} is not representable as "
                                               f"{spec.representable} (the node's precision)")
    for name, scale in scales.items():   # after the loop above: both tensors are well-formed
        try:
            i8_codes(bundle.tensors[name], bundle.tensors[scale])
        except ValueError as exc:
            raise BundleError(where, name, f"{exc} (the node's precision i8)") from None
