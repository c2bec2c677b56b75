"""Elementwise lowerings: components applied lane by lane (unary, affine, binary, where) and the
arithmetic built on them (constants folded into per-lane scales and offsets, powers by their exact
forms)."""
from __future__ import annotations

import numpy as np

from .lanes import ConvertError, Feat, const_against, constant_in


class ElementwiseLowering:
    """The elementwise operations of a ``Lowering``."""

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
        s, o = (np.broadcast_to(constant_in(a, f.batch, len(shape)), shape) for a in (scale, offset))
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
            per_lane = np.broadcast_to(constant_in(exponent, f.batch, len(shape)), shape)
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
