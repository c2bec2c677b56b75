"""Integer lanes. An index a graph computes (a hash of grid vertices, an Embedding id) is uint32 code
kept aside until a table is read at it: one ``int_gather`` node then carries the code it needs."""
from __future__ import annotations

import numpy as np

from inshade.components import MAX_GATHER_ROWS

from .lanes import ConvertError, Feat, IntFeat, const_against, constant_in

UINT32_MASK = 0xFFFFFFFF
INT_COMMUTATIVE = ("add", "mul", "xor", "and", "or")
INT_ENTRY_ARGS = {"shl": (True, False), "lane": (False,), "const": (False,)}   # arguments naming entries
INT_OP_NAMES = {"mul": "a multiply", "add": "an add", "sub": "a subtraction", "xor": "a xor", "and": "an and",
                "or": "an or", "shl": "a shift", "const": "a constant"}
INTEGRAL_NODES = ("floor", "ceil", "trunc", "round")   # their outputs are whole numbers already


class IntLowering:
    """The integer operations of a ``Lowering``."""

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
        c = constant_in(c, like.batch, max(like.rank, c.ndim)) if c.ndim else c.reshape(())
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
