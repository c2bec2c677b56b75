"""Lowering a captured network onto bundle components (numpy only: shared by the torch and ONNX
importers).

An importer walks its graph once and calls these methods; what comes out is a ``Bundle``. Every
tensor the network computes is a ``Feat``: its shape with the batch axis held at size 1, and for
each element the *lane* that holds it. A lane is one float of a bundle value (an input port or a
node's output), numbered globally. Layout operations (view, permute, slice, cat, expand, ...)
only rearrange the lane array and emit nothing; a node is emitted only where a value is computed,
and a ``select`` node only where a computation needs lanes in an order no value has. Constants
(parameters, buffers, literals) stay numpy arrays until an operation combines them with a Feat:
then they become weights (dense), per-lane scales (affine) or cells (lookup arrays).

What a shader cannot do is refused with ``ConvertError`` before anything is written: the
importer adds the op, the module path and the user's source line to the message.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from inshade.bundle import FORMAT, MAX_INPUT_DIM, VERSION, Bundle
from inshade.components import COMPONENTS, MAX_GATHER_ROWS, MAX_WIDTH


MAX_DENSE_GROUPS = 64
UINT32_MASK = 0xFFFFFFFF
INT_COMMUTATIVE = ("add", "mul", "xor", "and", "or")
INT_ENTRY_ARGS = {"shl": (True, False), "lane": (False,), "const": (False,)}   # arguments naming entries
INT_OP_NAMES = {"mul": "a multiply", "add": "an add", "sub": "a subtraction", "xor": "a xor", "and": "an and",
                "or": "an or", "shl": "a shift", "const": "a constant"}
INTEGRAL_NODES = ("floor", "ceil", "trunc", "round")   # their outputs are whole numbers already   # a linear layer repeated over a row's other axes (each repeat is a node)


class Float64Unavailable(Exception):
    """A source cannot be evaluated in float64 (the message says why): the check then judges by the
    1e-5 rule alone."""


class ConvertError(ValueError):
    """A network (or a part of it) that cannot become a bundle; the message is one line."""


@dataclass(frozen=True)
class Feat:
    """A computed tensor: ``lanes`` has the tensor's shape with the batch axis (``batch``) at size 1;
    ``pending`` is a scalar multiply not yet emitted (sin / cos take it as their omega0)."""
    lanes: np.ndarray
    batch: int
    pending: float | None = None

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(self.lanes.shape)

    @property
    def rank(self) -> int:
        return self.lanes.ndim

    def moved(self, lanes: np.ndarray, batch: int | None = None) -> "Feat":
        """The same kind of tensor over rearranged lanes (layout operations)."""
        return replace(self, lanes=lanes, batch=self.batch if batch is None else batch)


@dataclass(frozen=True)
class IntFeat(Feat):
    """An integer tensor: ``lanes`` holds entries of the lowering's uint32 program
    (``Lowering.int_program``), not float lanes. Integers become bundle values only where a table
    is read at them (``gather``, one ``int_gather`` node) or a cast value is used as a float again."""


@dataclass
class Lowering:
    """Builds a bundle graph. ``lane_value[i]`` / ``lane_index[i]``: the value and lane of global
    lane i."""
    nodes: list = field(default_factory=list)
    tensors: dict = field(default_factory=dict)
    inputs: list = field(default_factory=list)
    outputs: list = field(default_factory=list)
    values: dict = field(default_factory=dict)       # value id -> (first global lane, width)
    int_program: list = field(default_factory=list)  # uint32 entries: ("lane", global lane), ("const", c), (op, a, b)
    _int_ids: dict = field(default_factory=dict)
    lane_value: list = field(default_factory=list)
    lane_index: list = field(default_factory=list)
    _counts: dict = field(default_factory=dict)

    # --- values --------------------------------------------------------------------------
    def _new_value(self, vid: str, width: int) -> np.ndarray:
        if width > MAX_WIDTH:
            raise ConvertError(f"a value {width} lanes wide; the widest a bundle takes is {MAX_WIDTH}")
        base = len(self.lane_value)
        self.values[vid] = (base, width)
        self.lane_value += [vid] * width
        self.lane_index += list(range(width))
        return np.arange(base, base + width)

    def _id(self, kind: str) -> str:
        k = self._counts.get(kind, 0)
        self._counts[kind] = k + 1
        return f"{kind}{k}"

    def input(self, name: str, dim: int, semantic: str = "generic", shape=None) -> Feat:
        """A bundle input of ``dim`` lanes; ``shape``: its full tensor shape, None on the batch axes
        (port_layout.py), when it is not plain rows."""
        if dim > MAX_INPUT_DIM:
            posed = f" (shape {_shape_text(shape)}: each row holds the non-batch axes)" if shape else ""
            raise ConvertError(f"input {name!r}: {dim} lanes wide{posed}; an input takes at most {MAX_INPUT_DIM}")
        port = {"name": name, "dim": int(dim), "semantic": semantic}
        if shape is not None and list(shape) != [None, dim]:
            port["shape"] = list(shape)
        self.inputs.append(port)
        return Feat(self._new_value(name, dim).reshape(1, dim), 0)

    def _sources(self, lanes: np.ndarray) -> list[str]:
        """The node inputs whose concatenation is exactly ``lanes`` (whole values in order), else
        one ``select`` node over the values involved."""
        lanes = np.asarray(lanes, np.int64).reshape(-1)
        out, i = [], 0
        while i < len(lanes):
            vid = self.lane_value[lanes[i]]
            base, width = self.values[vid]
            if lanes[i] != base or i + width > len(lanes) or not np.array_equal(lanes[i:i + width],
                                                                                np.arange(base, base + width)):
                break
            out.append(vid)
            i += width
        if i == len(lanes):
            return out
        involved = list(dict.fromkeys(self.lane_value[k] for k in lanes))
        offsets, at = {}, 0
        for vid in involved:
            offsets[vid] = at
            at += self.values[vid][1]
        picks = [offsets[self.lane_value[k]] + self.lane_index[k] for k in lanes]
        return [self._node("select", involved, {"lanes": picks}, len(picks))]

    def _node(self, kind: str, sources: list[str], params: dict, width: int, tensors: dict | None = None) -> str:
        vid = self._id(kind)
        self.nodes.append({"id": vid, "type": kind, "inputs": list(sources), "params": params})
        for slot, a in (tensors or {}).items():
            self.tensors[f"{vid}.{slot}"] = np.ascontiguousarray(a, np.float32)
        self._new_value(vid, width)
        return vid

    def _emit(self, kind: str, feat_lanes: np.ndarray, params: dict, width: int, tensors=None) -> np.ndarray:
        """A node over the given lanes (flattened); its output lanes."""
        if np.size(feat_lanes) == 0:
            raise ConvertError("computes from a tensor with no elements (an empty slice or split)")
        vid = self._node(kind, self._sources(feat_lanes), params, width, tensors)
        base, _ = self.values[vid]
        return np.arange(base, base + width)

    def resolve(self, f: Feat) -> Feat:
        """``f`` with its pending scalar multiply emitted."""
        if f.pending is None:
            return f
        return self._elementwise_affine(Feat(f.lanes, f.batch), np.float32(f.pending), np.float32(0.0))

    # --- elementwise -----------------------------------------------------------------------
    def unary(self, f: Feat, kind: str, params: dict | None = None) -> Feat:
        """An elementwise component, applied once to each distinct lane."""
        if kind in ("sin", "cos") and f.pending is not None and not params:
            params = {"omega0": float(f.pending)}
            f = Feat(f.lanes, f.batch)
        f = self.resolve(f)
        if kind == "identity":
            return f
        uniq, inverse = np.unique(f.lanes, return_inverse=True)
        out = self._emit(kind, uniq, dict(params or {}), len(uniq))
        return Feat(out[inverse].reshape(f.shape), f.batch)

    def scale(self, f: Feat, c: float) -> Feat:
        """f * c for a scalar c: kept pending (sin / cos fold it into omega0), emitted otherwise."""
        if f.pending is None:
            return Feat(f.lanes, f.batch, float(np.float32(c)))
        return Feat(self.resolve(f).lanes, f.batch, float(np.float32(c)))

    def affine(self, f: Feat, scale, offset) -> Feat:
        """f * scale + offset, scale and offset broadcast against f (they may widen it)."""
        return self._elementwise_affine(self.resolve(f), np.asarray(scale, np.float32), np.asarray(offset, np.float32))

    def _elementwise_affine(self, f: Feat, scale: np.ndarray, offset: np.ndarray) -> Feat:
        shape = self.broadcast_shape(f, scale.shape, offset.shape)
        lanes = np.broadcast_to(f.lanes, shape)
        s, o = (np.broadcast_to(_constant_in(a, f.batch, len(shape)), shape) for a in (scale, offset))
        if s.size and np.all(s == s.flat[0]) and np.all(o == o.flat[0]):   # uniform: once per distinct lane
            uniq, inverse = np.unique(lanes, return_inverse=True)
            out = self._emit("affine", uniq, {}, len(uniq),
                             {"scale": np.full(len(uniq), s.flat[0]), "offset": np.full(len(uniq), o.flat[0])})
            return Feat(out[inverse].reshape(shape), f.batch)
        out = self._emit("affine", lanes, {}, lanes.size, {"scale": s.reshape(-1), "offset": o.reshape(-1)})
        return Feat(out.reshape(shape), f.batch)

    def binary(self, op: str, a: Feat, b: Feat) -> Feat:
        """a op b of two computed tensors, broadcast against each other."""
        a, b = self.resolve(a), self.resolve(b)
        if a.batch != b.batch and a.rank == b.rank:
            raise ConvertError(f"{op} of two tensors whose batch axes differ ({a.batch} and {b.batch})")
        rank = max(a.rank, b.rank)
        batch = a.batch + rank - a.rank
        if b.batch + rank - b.rank != batch:
            raise ConvertError(f"{op}: the batch axes of the two operands do not line up")
        try:
            shape = np.broadcast_shapes(a.shape, b.shape)
        except ValueError:
            raise ConvertError(f"{op}: shapes {list(a.shape)} and {list(b.shape)} do not broadcast") from None
        la, lb = (np.broadcast_to(x.lanes.reshape((1,) * (rank - x.rank) + x.shape), shape).reshape(-1) for x in (a, b))
        out = self._emit(op, np.concatenate([la, lb]), {}, la.size)
        return Feat(out.reshape(shape), batch)

    def where(self, op: str, a, b, x, y) -> Feat:
        """(a op b) ? x : y, each a Feat or a constant, broadcast together."""
        feats = [self.resolve(v) for v in (a, b, x, y) if isinstance(v, Feat)]
        like = feats[0]
        parts = [self.resolve(v) if isinstance(v, Feat) else self.constant(like, v) for v in (a, b, x, y)]
        rank = max(p.rank for p in parts)
        shape = np.broadcast_shapes(*(p.shape for p in parts))
        lanes = [np.broadcast_to(p.lanes.reshape((1,) * (rank - p.rank) + p.shape), shape).reshape(-1) for p in parts]
        out = self._emit("where", np.concatenate(lanes), {"op": op}, lanes[0].size)
        return Feat(out.reshape(shape), like.batch + rank - like.rank)

    def arithmetic(self, op: str, a, b, batch_size: int) -> Feat:
        """a op b (add, sub, mul, div) of two computed tensors, or of one and a constant (numpy,
        broadcast; a constant as wide as the batch is one row). A scalar multiply is kept pending
        (sin / cos take it as their omega0); x / c is x * (1 / c), within an ulp of a division."""
        if isinstance(a, Feat) and isinstance(b, Feat):
            return self.binary(op, a, b)
        f, c = (a, b) if isinstance(a, Feat) else (b, a)
        c = const_against(np.asarray(c, np.float32), f, batch_size)
        if op == "mul" and c.size == 1 and c.ndim <= f.rank:
            return self.scale(f, float(c.reshape(())))
        if op == "mul":
            return self.affine(f, c, 0.0)
        if op == "add":
            return self.affine(f, 1.0, c)
        if op == "sub":
            return self.affine(f, 1.0, -c) if f is a else self.affine(f, -1.0, c)
        if f is a:
            return self.affine(f, np.float32(1.0) / c, 0.0)
        return self.affine(self.unary(f, "reciprocal"), c, 0.0)   # c / x

    def power(self, f: Feat, exponent) -> Feat:
        """f ** exponent for a constant exponent (a scalar, or one per lane broadcast against f):
        the exact forms where a shader has them, the ``power`` component otherwise."""
        exponent = np.asarray(exponent, np.float32)
        if exponent.size != 1:   # one power per distinct exponent, lanes picked from each
            shape = self.broadcast_shape(f, exponent.shape)
            per_lane = np.broadcast_to(_constant_in(exponent, f.batch, len(shape)), shape)
            lanes = np.broadcast_to(self.resolve(f).lanes, shape).copy()
            for e in np.unique(per_lane):
                lanes = np.where(per_lane == e, np.broadcast_to(self.power(f, e).lanes, shape), lanes)
            return Feat(lanes, f.batch)
        e = float(exponent.reshape(()))
        if not np.isfinite(e):
            raise ConvertError(f"power {e:g}: the exponent must be finite")
        table = {1.0: lambda: f, 2.0: lambda: self.binary("mul", f, f),
                 3.0: lambda: self.binary("mul", self.binary("mul", f, f), f), 0.5: lambda: self.unary(f, "sqrt"),
                 -1.0: lambda: self.unary(f, "reciprocal"),
                 -0.5: lambda: self.unary(self.unary(f, "sqrt"), "reciprocal")}
        if e in table:
            return table[e]()
        if e == 0.0:
            return self.constant(f, np.ones(f.shape, np.float32)[tuple(slice(0, 1) if a == f.batch else slice(None)
                                                                         for a in range(f.rank))])
        return self.unary(f, "power", {"exponent": e})

    def base_power(self, base, f: Feat) -> Feat:
        """base ** f for a constant base > 0 (a scalar or one per lane): exp(f ln base)."""
        base = np.asarray(base, np.float64)
        if not (np.all(base > 0) and np.isfinite(base).all()):
            raise ConvertError(f"a constant base {base.reshape(-1)[:4].tolist()} raised to a computed power: "
                               "positive finite bases are lowered")
        return self.unary(self.affine(f, np.log(base).astype(np.float32), np.float32(0.0)), "exp")

    def atan2(self, a, b, batch_size: int) -> Feat:
        """atan2(a, b), either operand a constant (broadcast, as wide as the batch at most one row)."""
        like = a if isinstance(a, Feat) else b
        a, b = (self.constant(like, const_against(np.asarray(v, np.float32), like, batch_size))
                if not isinstance(v, Feat) else v for v in (a, b))
        return self.binary("atan2", a, b)

    def modulo(self, f: Feat, divisor, kind: str) -> Feat:
        """fmod (the sign of f) or remainder (the sign of the divisor) by a constant scalar divisor."""
        divisor = np.asarray(divisor, np.float32)
        if divisor.size != 1:
            per_lane = np.unique(divisor)
            if per_lane.size != 1:
                raise ConvertError(f"{kind} by a divisor per lane: one constant divisor is lowered")
        d = float(divisor.reshape(-1)[0])
        if d == 0.0 or not np.isfinite(d):
            raise ConvertError(f"{kind} by {d:g}: a finite non-zero divisor is lowered")
        return self.unary(f, kind, {"divisor": d})

    def clamp(self, f: Feat, lo, hi) -> Feat:
        """min(max(f, lo), hi) for scalar bounds (None: absent); lo > hi gives hi everywhere, as torch
        and ONNX define it."""
        params = {k: float(v) for k, v in (("min", lo), ("max", hi)) if v is not None}
        if not params:
            return f
        if lo is not None and hi is not None and lo > hi:
            return self.unary(self.unary(f, "clamp", {"min": float(lo)}), "clamp", {"max": float(hi)})
        return self.unary(f, "clamp", params)

    def softmax(self, f: Feat, axis: int) -> Feat:
        """exp(x - max) / sum, over a feature axis, in the order torch and onnxruntime compute it."""
        axis = axis % f.rank
        if axis == f.batch:
            raise ConvertError("softmax over the batch axis mixes the batch (one pixel's value would depend on all "
                               "the others)")
        top = self.reduce(f, "max", [axis], True)
        e = self.unary(self.binary("sub", f, top), "exp")
        return self.binary("div", e, self.reduce(e, "sum", [axis], True))

    def batch_norm(self, f: Feat, weight, bias, mean, var, eps: float) -> Feat:
        """BatchNorm with running statistics (eval / inference) as a per-channel affine (axis 1)."""
        if f.rank < 2:
            raise ConvertError("BatchNorm of a tensor without a channel axis")
        inv = 1.0 / np.sqrt(np.asarray(var, np.float64) + eps)
        w = np.ones_like(inv) if weight is None else np.asarray(weight, np.float64)
        b = np.zeros_like(inv) if bias is None else np.asarray(bias, np.float64)
        shape = [1] * f.rank
        shape[1] = -1
        return self.affine(f, (w * inv).astype(np.float32).reshape(shape),
                           (b - np.asarray(mean, np.float64) * w * inv).astype(np.float32).reshape(shape))

    def constant(self, like: Feat, values) -> Feat:
        """A constant as lanes, shaped like ``like`` but for its own sizes (1 on the batch axis):
        0 * x + c of one lane x of ``like`` (finite inputs give exactly c)."""
        values = _constant_in(np.asarray(values, np.float32), like.batch, like.rank)
        lane = np.asarray(like.lanes).reshape(-1)[:1]
        src = np.broadcast_to(lane, values.size)
        out = self._emit("affine", src, {}, values.size, {"scale": np.zeros(values.size), "offset": values.reshape(-1)})
        return Feat(out.reshape(values.shape), like.batch)

    @staticmethod
    def broadcast_shape(f: Feat, *shapes) -> tuple:
        rank = max([f.rank, *(len(s) for s in shapes)])
        if rank != f.rank:
            raise ConvertError(f"a constant of rank {rank} widens a rank-{f.rank} tensor past its batch axis")
        try:
            return np.broadcast_shapes(f.shape, *shapes)
        except ValueError:
            raise ConvertError(f"shapes {list(f.shape)} and {[list(s) for s in shapes]} do not broadcast") from None

    # --- layers ----------------------------------------------------------------------------
    def dense(self, f: Feat, weight: np.ndarray, bias: np.ndarray | None) -> Feat:
        """y = x W^T + b over the last axis of a [B, in] tensor (or W x over [in, B], batch last)."""
        f = self.resolve(f)
        weight = np.asarray(weight, np.float32)
        if f.rank > 2 and f.batch != f.rank - 1:   # [..., features]: one layer per position of the other axes
            if weight.ndim != 2 or weight.shape[1] != f.shape[-1]:
                raise ConvertError(f"linear layer: weight {list(weight.shape)} does not take {f.shape[-1]} features")
            rows = f.lanes.reshape(-1, f.shape[-1])
            if len(rows) > MAX_DENSE_GROUPS:
                raise ConvertError(f"a linear layer over the last axis of {list(f.shape)}: {len(rows)} rows per pixel, "
                                   f"more than {MAX_DENSE_GROUPS} layers")
            outs = [self.dense(Feat(r.reshape(1, -1), 0), weight, bias).lanes.reshape(-1) for r in rows]
            return Feat(np.stack(outs).reshape(*f.shape[:-1], weight.shape[0]), f.batch)
        if f.rank != 2:
            raise ConvertError(f"a linear layer on a rank-{f.rank} tensor (shape {list(f.shape)}) with the batch "
                               "last: inshade lowers it on [..., features]")
        feature_axis = 1 - f.batch
        if weight.ndim != 2 or weight.shape[1] != f.shape[feature_axis]:
            raise ConvertError(f"linear layer: weight {list(weight.shape)} does not take "
                               f"{f.shape[feature_axis]} features")
        lanes = f.lanes.reshape(-1)
        tensors = {"weight": weight}
        if bias is not None:
            tensors["bias"] = np.broadcast_to(np.asarray(bias, np.float32), (weight.shape[0],))
        out = self._emit("dense", lanes, {"out": int(weight.shape[0]), "bias": bias is not None},
                         weight.shape[0], tensors)
        return Feat(out.reshape((1, -1) if f.batch == 0 else (-1, 1)), f.batch)

    def linear_map(self, f: Feat, apply) -> Feat:
        """A map linear in ``f`` (an einsum of f with constants) as one dense layer. ``apply`` takes
        an array shaped like f with any size on its batch axis and returns the map's result; the
        matrix is read off the one-hot basis, and the output's batch axis is the one whose size
        follows the input's."""
        f = self.resolve(f)
        row = [n for a, n in enumerate(f.shape) if a != f.batch]
        lanes = int(np.prod(row))

        def on_basis(extra: int) -> np.ndarray:
            basis = np.concatenate([np.eye(lanes), np.zeros((extra, lanes))]).reshape(lanes + extra, *row)
            return np.asarray(apply(np.moveaxis(basis, 0, f.batch)), np.float64)

        try:
            y, y1 = on_basis(0), on_basis(1)
        except (ValueError, RuntimeError) as exc:   # numpy's and torch's words for operands that do not fit
            raise ConvertError(f"cannot be read as a linear map of the input ({str(exc).splitlines()[0][:100]})") from None
        moved = [a for a in range(y.ndim) if y.shape[a] != y1.shape[a]]
        if len(moved) != 1:
            raise ConvertError("sums over the batch axis (one pixel's value would depend on the others)")
        b = moved[0]
        matrix = np.moveaxis(y, b, 0).reshape(lanes, -1).T
        out = self.dense(Feat(np.moveaxis(f.lanes, f.batch, 0).reshape(1, -1), 0), matrix.astype(np.float32), None)
        out_row = [n for a, n in enumerate(y.shape) if a != b]
        return Feat(np.expand_dims(out.lanes.reshape(out_row), b), b)

    def reduce(self, f: Feat, op: str, axes, keepdim: bool) -> Feat:
        f = self.resolve(f)
        axes = sorted({a % f.rank for a in axes})
        if f.batch in axes:
            raise ConvertError(f"{op} over the batch axis mixes the batch (one pixel's value would depend on others)")
        keep = [a for a in range(f.rank) if a not in axes]
        moved = np.transpose(f.lanes, keep + axes)
        groups = int(np.prod([f.shape[a] for a in keep]))
        out = self._emit("reduce", moved, {"op": op, "groups": groups}, groups)
        kept_shape = [f.shape[a] for a in keep]
        lanes = out.reshape(kept_shape)
        if keepdim:
            lanes = lanes.reshape([1 if a in axes else f.shape[a] for a in range(f.rank)])
            return Feat(lanes, f.batch)
        return Feat(lanes, keep.index(f.batch))

    def layer_norm(self, f: Feat, dims: int, weight, bias, eps: float) -> Feat:
        """LayerNorm over the last ``dims`` axes."""
        f = self.resolve(f)
        if f.batch >= f.rank - dims:
            raise ConvertError("layer_norm over the batch axis mixes the batch")
        size = int(np.prod(f.shape[f.rank - dims:]))
        groups = f.lanes.size // size
        tensors = {}
        if weight is not None or bias is not None:
            tensors["weight"] = np.ones(size) if weight is None else np.asarray(weight, np.float32).reshape(-1)
            tensors["bias"] = np.zeros(size) if bias is None else np.asarray(bias, np.float32).reshape(-1)
        out = self._emit("layer_norm", f.lanes, {"eps": float(eps), "groups": groups, "affine": bool(tensors)},
                         f.lanes.size, tensors)
        return Feat(out.reshape(f.shape), f.batch)

    def lookup(self, coords: Feat, cells: np.ndarray) -> np.ndarray:
        """One multilinear lookup per position of ``coords`` (its last axis the d coordinates in
        [0, 1], x fastest) into ``cells`` [N_{d-1}..N_0, C]; returns lanes [positions..., C] (batch
        axis kept at size 1)."""
        coords = self.resolve(coords)
        d, channels = coords.shape[-1], cells.shape[-1]
        resolution = [int(n) for n in reversed(cells.shape[:-1])]
        points = coords.lanes.reshape(-1, d)
        out = np.zeros((len(points), channels), np.int64)
        for p, lanes in enumerate(points):
            for c0 in range(0, channels, 64):   # a lookup array holds at most 64 channels
                part = cells[..., c0:c0 + 64]
                out[p, c0:c0 + part.shape[-1]] = self._emit(
                    "lookup_array", lanes, {"resolution": resolution, "channels": int(part.shape[-1]), "bits": 32,
                                            "baked": "none"}, part.shape[-1], {"cells": part})
        return out.reshape(*coords.shape[:-1], channels)

    # --- integer lanes ---------------------------------------------------------------------
    # An index a graph computes (a hash of grid vertices, an Embedding id) is uint32 code kept
    # aside until a table is read at it: one ``int_gather`` node then carries the code it needs.
    def _int_entry(self, op: str, *args: int) -> int:
        key = (op, *(int(a) for a in args))
        if op in INT_COMMUTATIVE and key[1] > key[2]:
            key = (op, key[2], key[1])
        k = self._int_ids.get(key)
        if k is None:
            k = self._int_ids[key] = len(self.int_program)
            self.int_program.append(key)
        return k

    def _int_entries(self, a: np.ndarray, make) -> np.ndarray:
        flat = [make(v) for v in np.asarray(a).reshape(-1)]
        return np.asarray(flat, np.int64).reshape(np.shape(a))

    def to_int(self, f: Feat) -> IntFeat:
        """A float tensor cast to an integer type (toward 0, as torch and ONNX cast)."""
        if isinstance(f, IntFeat):
            return f
        f = self.resolve(f)
        return IntFeat(self._int_entries(f.lanes, lambda g: self._int_entry("lane", g)), f.batch)

    def int_operand(self, x, like: IntFeat, batch_size: int) -> IntFeat:
        """An integer tensor, or a constant as integer entries (shaped against ``like``)."""
        if isinstance(x, IntFeat):
            return x
        if isinstance(x, Feat):
            raise ConvertError("combines an integer with a float tensor in an integer operation")
        c = np.asarray(x)
        if c.dtype.kind == "f" and not np.all(c == np.floor(c)):
            raise ConvertError("combines an integer with a non-integer constant in an integer operation")
        c = const_against(c.astype(np.int64), like, batch_size, np.int64)
        c = _constant_in(c, like.batch, max(like.rank, c.ndim)) if c.ndim else c.reshape(())
        return IntFeat(self._int_entries(c, lambda v: self._int_entry("const", int(v) & UINT32_MASK)),
                       like.batch + max(c.ndim - like.rank, 0))

    def int_arithmetic(self, op: str, a, b, batch_size: int) -> IntFeat:
        """a op b for add, sub, mul, xor, and, or, modulo 2^32; shl and remainder by constants (a
        remainder by a power of two keeps the low bits, which is all a 32-bit lane knows)."""
        like = a if isinstance(a, IntFeat) else b
        if op in ("shl", "remainder"):
            if isinstance(b, Feat) or not isinstance(a, IntFeat):
                raise ConvertError(f"{op} of an integer by a computed value (a constant {'shift' if op == 'shl' else 'divisor'} is lowered)")
            c = np.unique(np.asarray(b, np.int64))
            if op == "remainder":
                if not all(v > 0 and v & (v - 1) == 0 and v <= 1 << 32 for v in c):
                    raise ConvertError(f"integer remainder by {c.tolist()}: a 32-bit lane keeps only the low bits, so "
                                       "only positive power-of-two divisors are exact (a hash table's size)")
                return self.int_arithmetic("and", a, np.asarray(b, np.int64) - 1, batch_size)
            if not all(0 <= v for v in c):
                raise ConvertError(f"left shift by {c.tolist()}")
            if c.size != 1:
                raise ConvertError("left shift by per-element amounts (one constant shift is lowered)")
            shift = int(c[0])
            if shift >= 32:
                return self.int_arithmetic("mul", a, 0, batch_size)
            return a.moved(self._int_entries(a.lanes, lambda e: self._int_entry("shl", e, shift)))
        x, y = self.int_operand(a, like, batch_size), self.int_operand(b, like, batch_size)
        rank = max(x.rank, y.rank)
        batch = like.batch + rank - like.rank
        try:
            shape = np.broadcast_shapes(x.shape, y.shape)
        except ValueError:
            raise ConvertError(f"{op}: shapes {list(x.shape)} and {list(y.shape)} do not broadcast") from None
        lx, ly = (np.broadcast_to(v.lanes.reshape((1,) * (rank - v.rank) + v.shape), shape) for v in (x, y))
        out = [self._int_entry(op, i, j) for i, j in zip(lx.reshape(-1), ly.reshape(-1))]
        return IntFeat(np.asarray(out, np.int64).reshape(shape), batch)

    def int_to_float(self, f: IntFeat) -> Feat:
        """A cast integer used as a float again: the truncated float it came from (exact below 2^24)."""
        entries = [self.int_program[e] for e in f.lanes.reshape(-1)]
        if any(e[0] != "lane" for e in entries):
            op = next(e[0] for e in entries if e[0] != "lane")
            raise ConvertError(f"an integer computed by {INT_OP_NAMES.get(op, op)} is used as a float (a value cast "
                               "from a float converts back; computed integers index tables)")
        lanes = np.asarray([e[1] for e in entries], np.int64).reshape(f.shape)
        kinds = {self.lane_value[g] for g in lanes.reshape(-1)}
        integral = all(any(n["id"] == vid and n["type"] in INTEGRAL_NODES for n in self.nodes) for vid in kinds)
        out = Feat(lanes, f.batch)
        return out if integral else self.unary(out, "trunc")

    def gather(self, table: np.ndarray, index: IntFeat) -> Feat:
        """``table[index]`` along the table's first axis (nn.Embedding, x[idx], Gather axis 0):
        one ``int_gather`` node reading a row [F] per distinct index entry."""
        table = np.asarray(table, np.float32)
        if table.ndim not in (1, 2):
            raise ConvertError(f"indexes a table of shape {list(table.shape)} (a [rows] or [rows, features] table)")
        rows2 = table.reshape(table.shape[0], -1)
        if rows2.shape[0] > MAX_GATHER_ROWS:
            raise ConvertError(f"a table of {rows2.shape[0]} rows; an int_gather takes at most {MAX_GATHER_ROWS}")
        uniq, inverse = np.unique(index.lanes.reshape(-1), return_inverse=True)
        needed, stack = set(), list(uniq)
        while stack:
            e = int(stack.pop())
            if e in needed:
                continue
            needed.add(e)
            op, *args = self.int_program[e]
            stack += [a for a, named in zip(args, INT_ENTRY_ARGS.get(op, (True, True))) if named]
        order = sorted(needed)
        local = {e: k for k, e in enumerate(order)}
        lanes = sorted({self.int_program[e][1] for e in order if self.int_program[e][0] == "lane"})
        lane_at = {g: k for k, g in enumerate(lanes)}
        program = []
        for e in order:
            op, *args = self.int_program[e]
            if op == "lane":
                program.append(["lane", lane_at[args[0]]])
            elif op == "const":
                program.append(["const", args[0]])
            else:
                program.append([op, *(local[a] if named else a
                                      for a, named in zip(args, INT_ENTRY_ARGS.get(op, (True, True))))])
        if not lanes:
            raise ConvertError("indexes a table at constant positions only (no computed value reaches the index)")
        feats = rows2.shape[1]
        params = {"program": program, "indices": [local[int(e)] for e in uniq], "rows": int(rows2.shape[0]),
                  "features": int(feats)}
        out = self._emit("int_gather", np.asarray(lanes), params, len(uniq) * feats, {"table": rows2})
        got = out.reshape(len(uniq), feats)[inverse].reshape(*index.shape, *table.shape[1:])
        return Feat(got, index.batch)

    # --- outputs and the bundle ------------------------------------------------------------
    def output(self, name: str, f: Feat, semantic: str = "generic", batch_axes: int = 1, leading: int = 1) -> None:
        """An output port: its row is ``f`` with the batch axis taken out, the other axes in order;
        ``batch_axes``: how many axes of the source's tensor the batch axis stands for; ``leading``:
        the inputs' batch axes were [1, .., 1, batch] (a traced [H, W, F]), so an output that keeps
        them in front has them all as batch axes."""
        f = self.resolve(f)
        if any(o["name"] == name for o in self.outputs):
            raise ConvertError(f"output {name!r} is named twice")
        if f.lanes.size == 0:
            raise ConvertError(f"output {name!r} has no elements (an empty slice or split)")
        sources = self._sources(np.moveaxis(f.lanes, f.batch, 0).reshape(-1))
        if len(sources) == 1:
            vid = sources[0]
        else:   # several whole values side by side: one identity node concatenates them
            vid = self._node("identity", sources, {}, f.lanes.size)
        port = {"name": name, "node": vid, "semantic": semantic}
        shape = [*f.shape[:f.batch], *[None] * batch_axes, *f.shape[f.batch + 1:]]
        if leading > 1 and f.batch == leading - 1 and all(n == 1 for n in f.shape[:f.batch]):
            shape = [None] * leading + shape[leading:]
        if shape != [None, f.lanes.size]:
            port["shape"] = shape
        self.outputs.append(port)

    def bundle(self, kind: str, name: str, provenance: dict, render: dict | None = None) -> Bundle:
        used = self._live()
        meta = {"format": FORMAT, "version": VERSION, "kind": kind, "name": name, "inputs": self.inputs,
                "nodes": [n for n in self.nodes if n["id"] in used], "outputs": self.outputs,
                "provenance": provenance, "metrics": {}}
        if render:
            meta["render"] = render
        tensors = {k: v for k, v in self.tensors.items() if k.split(".")[0] in used}
        return Bundle(meta, tensors)

    def _live(self) -> set[str]:
        """Nodes an output depends on (a value computed and never used is dropped)."""
        by_id = {n["id"]: n for n in self.nodes}
        live, stack = set(), [o["node"] for o in self.outputs]
        while stack:
            vid = stack.pop()
            if vid in live or vid not in by_id:
                continue
            live.add(vid)
            stack += by_id[vid]["inputs"]
        return live


# --- layout: only the lane array changes (shared by the importers) -------------------------

def reshape(f: Feat, shape, batch_size: int) -> Feat:
    """``f`` viewed as ``shape`` (the full shape: ``batch_size`` on its batch axis). The batch
    axis must keep the elements before it, else rows would mix."""
    before = int(np.prod(f.shape[:f.batch]))
    picks = [a for a, n in enumerate(shape) if n == batch_size and int(np.prod(shape[:a])) == before]
    if not picks or len(picks) > 1 and batch_size != 1:
        raise ConvertError(f"reshape to {list(shape)} merges or splits the batch axis (one pixel's values "
                           "would mix with another's)")
    b = picks[0]
    lanes = f.lanes.reshape([1 if a == b else n for a, n in enumerate(shape)])
    return f.moved(lanes, b)


def permute(f: Feat, dims) -> Feat:
    dims = [d % f.rank for d in dims]
    return f.moved(np.transpose(f.lanes, dims), dims.index(f.batch))


def unsqueeze(f: Feat, dim: int) -> Feat:
    dim = dim % (f.rank + 1)
    return f.moved(np.expand_dims(f.lanes, dim), f.batch + (dim <= f.batch))


def squeeze(f: Feat, dims=None) -> Feat:
    """Size-1 axes removed (``dims``, or every one but the batch axis)."""
    if dims is None:
        dims = [a for a in range(f.rank) if f.shape[a] == 1 and a != f.batch]
    dims = [d % f.rank for d in ([dims] if isinstance(dims, int) else dims)]
    dims = [d for d in dims if f.shape[d] == 1 and d != f.batch]
    lanes = np.squeeze(f.lanes, tuple(dims)) if dims else f.lanes
    return f.moved(lanes, f.batch - sum(d < f.batch for d in dims))


def slice_axis(f: Feat, dim: int, start, end, step, batch_size: int) -> Feat:
    dim = dim % f.rank
    if dim == f.batch:
        if (start in (None, 0)) and (end is None or end >= batch_size) and step in (None, 1):
            return f
        raise ConvertError("slices the batch axis (rows of the batch are pixels: each is computed alone)")
    index = [slice(None)] * f.rank
    index[dim] = slice(start, end, step)
    return f.moved(f.lanes[tuple(index)])


def take(f: Feat, dim: int, index) -> Feat:
    """Elements at constant integer ``index`` (an int drops the axis) along a non-batch axis."""
    dim = dim % f.rank
    if dim == f.batch:
        raise ConvertError("indexes the batch axis (rows of the batch are pixels: each is computed alone)")
    lanes = np.take(f.lanes, index, axis=dim)
    return f.moved(lanes, f.batch - (dim < f.batch and np.ndim(index) == 0))


def expand(f: Feat, shape) -> Feat:
    """``f`` broadcast to the full ``shape`` (new leading axes allowed)."""
    lead = len(shape) - f.rank
    batch = f.batch + lead
    target = [1 if a == batch else n for a, n in enumerate(shape)]
    return f.moved(np.broadcast_to(f.lanes.reshape((1,) * lead + f.shape), target), batch)


def grid_cells(grid: np.ndarray, zeros: bool, align_corners: bool):
    """(cells [N_{d-1}..N_0, C], per-axis coordinate scale s) such that the lookup array at
    u = s g + 1/2 samples what grid_sample samples at g: the unnormalised coordinate is
    (g + 1) / 2 (N - 1) (align_corners) or ((g + 1) N - 1) / 2, clipped to [0, N - 1] (border);
    for zeros the cells get a ring of zeros and the coordinate shifts by one cell."""
    if grid.ndim not in (4, 5) or grid.shape[0] != 1:
        raise ConvertError(f"grid_sample: grid of shape {list(grid.shape)}; expected [1, C, H, W] or [1, C, D, H, W]")
    cells = np.moveaxis(grid[0], 0, -1).astype(np.float32)    # [(D,) H, W, C]
    d = cells.ndim - 1
    if zeros:
        cells = np.pad(cells, [(1, 1)] * d + [(0, 0)])
    scale = []
    for n in (grid.shape[-1 - k] for k in range(d)):          # N_0 = W, N_1 = H, N_2 = D
        if zeros:
            scale.append((n - 1) / (2 * (n + 1)) if align_corners else n / (2 * (n + 1)))
        else:
            scale.append(0.5 if align_corners else (n / (2 * (n - 1)) if n > 1 else 0.0))
    return cells, scale


def grid_sample(L: Lowering, grid: np.ndarray, coords: Feat, zeros: bool, align_corners: bool) -> Feat:
    """grid_sample (bilinear) of a constant grid [1, C, (D,) H, W] at computed coordinates
    [1, (Do,) Ho, Wo, d] whose batch axis is one of the spatial ones; out [1, C, (Do,) Ho, Wo]."""
    if coords.batch == 0:
        raise ConvertError("grid_sample with the batch on the grid's first axis: sample one shared grid with "
                           "coordinates shaped [1, ..., batch, ..., 2]")
    cells, scale = grid_cells(grid, zeros, align_corners)
    if coords.shape[-1] != len(scale):
        raise ConvertError(f"grid_sample: {coords.shape[-1]} coordinates for a {len(scale)}D grid")
    u = L.affine(coords, np.asarray(scale, np.float32), np.float32(0.5))
    lanes = np.moveaxis(L.lookup(u, cells), -1, 1)    # [1, (Do,) Ho, Wo, C] -> [1, C, (Do,) Ho, Wo]
    return Feat(lanes, coords.batch + 1)


def const_against(c, f: Feat, batch_size: int, dtype=np.float32) -> np.ndarray:
    """A constant combined with ``f``. Graphs often build one as wide as the batch (ones_like(x),
    torch.ones(x.shape[0], 1)): such a constant is one row, if every row is the same."""
    a = np.asarray(c, dtype)
    if a.ndim == f.rank and a.shape[f.batch] == batch_size and batch_size > 1:
        first = np.take(a, [0], axis=f.batch)
        if not np.array_equal(np.broadcast_to(first, a.shape), a):
            raise ConvertError("a constant that differs from row to row of the batch (one pixel's value would "
                               "depend on its index in the batch)")
        a = first
    return a


def _constant_in(a: np.ndarray, batch: int, rank: int) -> np.ndarray:
    """A constant broadcast against a rank-``rank`` tensor must not vary along its batch axis."""
    full = a.reshape((1,) * (rank - a.ndim) + a.shape)
    if full.shape[batch] != 1:
        raise ConvertError(f"a constant of shape {list(a.shape)} varies along the batch axis (one pixel's value "
                           "would depend on its index in the batch)")
    return full


def _shape_text(shape) -> str:
    return "[" + ", ".join("*" if n is None else str(n) for n in shape) + "]"


def component_types() -> list[str]:
    """The bundle component types an importer may emit."""
    return sorted(COMPONENTS)
