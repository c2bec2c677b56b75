"""Ops along the feature axis: constants, lane selection, branches, integer gathers, reductions, normalisation, the residual add: the bundle-level spec."""
from __future__ import annotations

from inshade.components.spec import (MAX_WIDTH, ComponentError, ComponentSpec, Param, TensorSpec, finite, pos_int,
                                     register, same_width)


register(ComponentSpec(
    "affine", "y = x * scale + offset, per lane (folded constants, BatchNorm in eval mode)",
    {}, out_dim=same_width,
    tensors=lambda p, d: {"scale": TensorSpec((d,), "float32"), "offset": TensorSpec((d,), "float32")},
    category="layer",
))


def _lanes_check(p, d):
    bad = [i for i in p["lanes"] if not (isinstance(i, int) and not isinstance(i, bool) and 0 <= i < d)]
    if bad:
        raise ComponentError(f"select: lane {bad[0]!r} is not in 0..{d - 1}")


register(ComponentSpec(
    "select", "y = x[lanes]: lanes of the input in any order, repeats allowed (slices, splits, broadcasts)",
    {"lanes": Param(list, check=lambda v: 1 <= len(v) <= MAX_WIDTH, doc=f"1..{MAX_WIDTH} lane indices")},
    out_dim=lambda p, d: len(p["lanes"]), extra_checks=_lanes_check, category="layer",
))
for _name, _expr in (("sub", "a - b"), ("mul", "a * b"), ("div", "a / b"),
                     ("atan2", "atan2(a, b) as torch.atan2(a, b): the angle of the point (x = b, y = a), C's "
                               "special values (atan2(+-0, -0) = +-pi, atan2(+-0, +0) = +-0)")):
    register(ComponentSpec(
        _name, f"two branches: input [a (n lanes), b (n lanes)] -> {_expr} (n lanes)", {},
        out_dim=lambda p, d: d // 2, in_dim=lambda p, d: d >= 2 and d % 2 == 0, category="layer"))

# integer lanes: uint32 arithmetic, wrapping modulo 2^32 (torch's int64 agrees on every result
# whose true value lies in 0..2^32-1, which is what a table index must be)
INT_OPS = {"lane": 1, "const": 1, "add": 2, "sub": 2, "mul": 2, "xor": 2, "and": 2, "or": 2, "shl": 2}
MAX_INT_PROGRAM = 4096
MAX_GATHER_ROWS = 1 << 26


def _int_gather_checks(p, d):
    prog = p["program"]
    for k, op in enumerate(prog):
        if not (isinstance(op, list) and op and op[0] in INT_OPS and len(op) == 1 + INT_OPS[op[0]]
                and all(isinstance(a, int) and not isinstance(a, bool) for a in op[1:])):
            raise ComponentError(f"program[{k}]: {op!r} is not [op, arg...] with op one of {', '.join(INT_OPS)}")
        name, args = op[0], op[1:]
        if name == "lane" and not 0 <= args[0] < d:
            raise ComponentError(f"program[{k}]: lane {args[0]} is not in 0..{d - 1}")
        if name == "const" and not 0 <= args[0] < 1 << 32:
            raise ComponentError(f"program[{k}]: constant {args[0]} is not a uint32")
        if name == "shl" and not (0 <= args[0] < k and 0 <= args[1] < 32):
            raise ComponentError(f"program[{k}]: shl takes an earlier entry and a shift in 0..31")
        if name not in ("lane", "const", "shl") and not all(0 <= a < k for a in args):
            raise ComponentError(f"program[{k}]: {name} must refer to earlier entries")
    bad = [i for i in p["indices"] if not (isinstance(i, int) and 0 <= i < len(prog))]
    if bad:
        raise ComponentError(f"indices: {bad[0]!r} is not an entry of the program")


register(ComponentSpec(
    "int_gather",
    "rows of a learned table at computed integer indices: each program entry is a uint32 "
    "(['lane', k]: input lane k truncated toward 0, as torch's float -> int cast; ['const', c]; "
    "add, sub, mul, xor, and, or of two earlier entries, shl of an entry by a constant: all modulo 2^32); "
    "output = table[entry] for each entry in indices, concatenated (zeros where an index is >= the "
    "table's rows)",
    {"program": Param(list, check=lambda v: 1 <= len(v) <= MAX_INT_PROGRAM,
                      doc=f"1..{MAX_INT_PROGRAM} entries"),
     "indices": Param(list, check=lambda v: 1 <= len(v) <= MAX_WIDTH, doc="program entries used as row indices"),
     "rows": Param(int, check=pos_int(MAX_GATHER_ROWS)),
     "features": Param(int, check=pos_int(MAX_WIDTH))},
    out_dim=lambda p, d: len(p["indices"]) * p["features"],
    tensors=lambda p, d: {"table": TensorSpec((p["rows"], p["features"]), "float32")},
    category="lookup", extra_checks=_int_gather_checks,
))

COMPARISONS = ("gt", "ge", "lt", "le")
register(ComponentSpec(
    "where", "a comparison choosing between branches: input [a, b, x, y] (n lanes each) -> "
             "(a op b) ? x : y, op one of gt, ge, lt, le",
    {"op": Param(str, check=lambda v: v in COMPARISONS, doc=", ".join(COMPARISONS))},
    out_dim=lambda p, d: d // 4, in_dim=lambda p, d: d >= 4 and d % 4 == 0, category="layer",
))
REDUCE_OPS = ("sum", "mean", "norm", "max", "min")


def _groups_check(p, d):
    if d % p["groups"]:
        raise ComponentError(f"groups: {p['groups']} does not divide the input width {d}")


register(ComponentSpec(
    "reduce", "the input as `groups` equal runs of lanes, each reduced to one lane by op "
              "(sum, mean, norm = sqrt of the sum of squares, max, min)",
    {"op": Param(str, check=lambda v: v in REDUCE_OPS, doc=", ".join(REDUCE_OPS)),
     "groups": Param(int, 1, pos_int(MAX_WIDTH))},
    out_dim=lambda p, d: p["groups"], extra_checks=_groups_check, category="layer",
))
register(ComponentSpec(
    "layer_norm", "LayerNorm of each of `groups` equal runs of lanes: (x - mean) / sqrt(var + eps), "
                  "biased variance; then * weight + bias per lane of a run when `affine`",
    {"eps": Param(float, 1e-5, lambda v: finite(v) and v >= 0, "finite and >= 0"),
     "groups": Param(int, 1, pos_int(MAX_WIDTH)), "affine": Param(bool, True)},
    out_dim=same_width, extra_checks=_groups_check, category="layer",
    tensors=lambda p, d: ({"weight": TensorSpec((d // p["groups"],), "float32"),
                           "bias": TensorSpec((d // p["groups"],), "float32")} if p["affine"] else {}),
))

register(ComponentSpec(
    "add", "residual connection: input [a (n lanes), b (n lanes)] -> a + b (n lanes)",
    {},
    out_dim=lambda p, d: d // 2,
    in_dim=lambda p, d: d >= 2 and d % 2 == 0,
    category="layer",
))
