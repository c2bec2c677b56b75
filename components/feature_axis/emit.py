"""The feature axis of an imported network: the emitters (torch twins in torch_twin.py), writing
lowered code (every target).

Per-lane maps (affine, select, reduce, layer_norm, where): constants are literals, since they are
per-lane vectors, not weight matrices.

Two branches combined lane by lane (add, sub, mul, div, atan2; atan2 is lib/activations'
inshade_atan2: torch's values at zeros and infinities). Input: the node's inputs as they are
(separate_inputs), lanes concatenated = [a (n) | b (n)]. When a and b are two sources that start a
vec4 block each, every whole block is one vec4 op and the n % 4 tail is done lane by lane (a
source's last block may hold another value's lanes, e.g. bundle inputs packed side by side, so it is
never used whole); otherwise lane by lane.

int_gather: the node's program is straight-line uint32 code (GLSL's uint arithmetic wraps modulo
2^32, as the twin reduces its int64 results), one `uint` per entry; each index then reads its row
from the table, stored as 2D textures in rows of 2^n texels (codegen/texture_rows.py), one per 4
features, float32 (a texel read returns the stored floats exactly); int_gather.glsl reads a row (and
its .vulkan.glsl, .wgsl, .hlsl versions).
"""
from __future__ import annotations

import numpy as np

from inshade.codegen import ir
from inshade.codegen.glsl import PlanRow, blocks
from inshade.codegen.registry import emitter
from inshade.codegen.texture_rows import feature_textures, row_layout, texture_formats
from inshade.codegen.values import Value, declare


def _block(a: np.ndarray, k: int) -> np.ndarray:
    """Lanes 4k..4k+3 of ``a``, zero past its end."""
    part = np.asarray(a[4 * k:4 * k + 4], np.float32)
    return np.pad(part, (0, 4 - len(part)))


def _padded(a: np.ndarray, n: int, fill: float) -> np.ndarray:
    out = np.full(blocks(n) * 4, fill, np.float32)
    out[:n] = a
    return out


def _float_lane(value, i: int):
    """Lane i of a value as a float (a uint lane converted), lowered."""
    return value.lane_ir(i) if value.kind == "float" else ir.Convert("float", value.lane_ir(i))


@emitter("affine", lowered=True)
def emit_affine(ctx, node, src, bundle):
    n = node.out_dim
    scale = _padded(bundle.tensor(node, "scale"), n, 0.0)
    offset = _padded(bundle.tensor(node, "offset"), n, 0.0)
    ctx.plan.append(PlanRow(node.id, "affine", f"{n}", flops=2 * n))
    out = declare(ctx, f"v_{node.id}", n)
    for b in range(blocks(n)):   # src is lane-0 aligned (gathered); padding lanes become 0 * x + 0
        scaled = ir.Bin("*", src.block_ir(b), ir.Vec4.of(scale[4 * b:4 * b + 4]))
        ctx.body.append(ir.Assign(out.block_ir(b), ir.Sum((scaled, ir.Vec4.of(offset[4 * b:4 * b + 4])))))
    return out


@emitter("select", separate_inputs=True, lowered=True)
def emit_select(ctx, node, srcs, bundle):
    lanes = node.params["lanes"]
    ctx.plan.append(PlanRow(node.id, "select", f"{node.in_dim}->{len(lanes)}"))
    flat = [(v, i) for v in srcs for i in range(v.dim)]
    first = lanes[0]
    run = lanes == list(range(first, first + len(lanes)))
    owner, start = flat[first]
    if run and all(flat[k][0] is owner for k in lanes) and owner.kind == "float":
        return Value(owner.array, owner.offset + start, len(lanes))    # a contiguous slice: no copy
    out = declare(ctx, f"v_{node.id}", len(lanes))
    for k, i in enumerate(lanes):
        ctx.body.append(ir.Assign(out.lane_ir(k), _float_lane(*flat[i])))
    return out


def _fold(terms: list, op: str):
    if op in ("max", "min"):
        expr = terms[0]
        for t in terms[1:]:
            expr = ir.Call(op, (expr, t), "float")
        return expr
    return ir.Sum(tuple(terms))


def _runs(src, groups: int, size: int):
    """Per group, its terms as whole vec4 blocks [(block expr, lanes used)] when every group starts
    on a block (size % 4 == 0, or one group: its last block partly used), else None (lane by lane)."""
    if not (src.aligned and (size % 4 == 0 or groups == 1)):
        return None
    out = []
    for g in range(groups):
        first = g * size // 4
        out.append([(src.block_ir(first + k), min(4, size - 4 * k)) for k in range(blocks(size))])
    return out


def _mask(used: int):
    return ir.Vec4.splat(1.0) if used == 4 else ir.Vec4.of([1.0] * used + [0.0] * (4 - used))


def _dot(a, b):
    return ir.Call("dot", (a, b), "float")


@emitter("reduce", lowered=True)
def emit_reduce(ctx, node, src, bundle):
    op, groups = node.params["op"], node.params["groups"]
    size = node.in_dim // groups
    ctx.plan.append(PlanRow(node.id, f"reduce {op}", f"{node.in_dim}->{groups}", flops=2 * node.in_dim))
    out = declare(ctx, f"v_{node.id}", groups)
    runs = _runs(src, groups, size) if op in ("sum", "mean", "norm") else None
    for g in range(groups):
        if runs is not None:   # dot products of whole blocks (padding lanes masked out)
            terms = [_dot(b, _mask(u)) if op != "norm" else _dot(ir.Bin("*", b, _mask(u)), b) for b, u in runs[g]]
        else:
            lanes = [src.lane_ir(g * size + i) for i in range(size)]
            terms = [ir.Bin("*", x, x) for x in lanes] if op == "norm" else lanes
        expr = _fold(terms, "sum" if op in ("norm", "mean") else op)
        if op == "norm":
            expr = ir.Call("sqrt", (expr,), "float")
        elif op == "mean":
            expr = ir.Bin("/", ir.Paren(expr), ir.Lit(size))
        ctx.body.append(ir.Assign(out.lane_ir(g), expr))
    return out


def _inverse_deviation(r: str, squares: list, size: int, eps: float):
    """float r = 1 / sqrt(mean of the squares + eps) (inversesqrt may be an approximation: the GLSL spec
    allows 2 ulp)."""
    variance = ir.Sum((ir.Bin("/", ir.Paren(ir.Sum(tuple(squares))), ir.Lit(size)), ir.Lit(eps)))
    return ir.Declare("float", r, init=ir.Bin("/", ir.Lit(1.0), ir.Call("sqrt", (variance,), "float")))


def _mean(m: str, terms: list, size: int):
    return ir.Declare("float", m, init=ir.Bin("/", ir.Paren(ir.Sum(tuple(terms))), ir.Lit(size)))


@emitter("layer_norm", lowered=True)
def emit_layer_norm(ctx, node, src, bundle):
    p = node.params
    groups, n = p["groups"], node.out_dim
    size = n // groups
    ctx.plan.append(PlanRow(node.id, "layer_norm", f"{n}", flops=6 * n))
    out = declare(ctx, f"v_{node.id}", n)
    w = bundle.tensor(node, "weight") if p["affine"] else None
    b = bundle.tensor(node, "bias") if p["affine"] else None
    m, r, d = f"m_{node.id}", f"r_{node.id}", f"d_{node.id}"
    runs = _runs(src, groups, size)
    for g in range(groups):
        mean, scale = ir.Var(f"{m}_{g}"), ir.Var(f"{r}_{g}")
        if runs is not None:   # whole blocks: the deviations d = (x - mean) * mask, one vec4 each
            parts = runs[g]
            devs = [ir.Var(f"{d}_{g}_{k}") for k in range(len(parts))]
            ctx.body.append(_mean(mean.name, [_dot(x, _mask(u)) for x, u in parts], size))
            ctx.body += [ir.Declare("vec4", dev.name, init=ir.Bin("*", ir.Paren(ir.Bin("-", x, mean)), _mask(u)))
                         for dev, (x, u) in zip(devs, parts)]
            ctx.body.append(_inverse_deviation(scale.name, [_dot(dev, dev) for dev in devs], size, p["eps"]))
            for k, dev in enumerate(devs):
                expr = ir.Bin("*", dev, scale)
                if w is not None:
                    expr = ir.Sum((ir.Bin("*", expr, ir.Vec4.of(_block(w, k))), ir.Vec4.of(_block(b, k))))
                ctx.body.append(ir.Assign(out.block_ir(g * size // 4 + k), expr))
            continue
        lanes = [src.lane_ir(g * size + i) for i in range(size)]
        ctx.body.append(_mean(mean.name, lanes, size))
        devs = [ir.Paren(ir.Bin("-", x, mean)) for x in lanes]
        ctx.body.append(_inverse_deviation(scale.name, [ir.Bin("*", dev, dev) for dev in devs], size, p["eps"]))
        for i, dev in enumerate(devs):
            expr = ir.Bin("*", dev, scale)
            if w is not None:
                expr = ir.Sum((ir.Bin("*", expr, ir.Lit(w[i])), ir.Lit(b[i])))
            ctx.body.append(ir.Assign(out.lane_ir(g * size + i), expr))
    return out


_COMPARE = {"gt": ">", "ge": ">=", "lt": "<", "le": "<="}


@emitter("where", separate_inputs=True, lowered=True)
def emit_where(ctx, node, srcs, bundle):
    n, op = node.out_dim, _COMPARE[node.params["op"]]
    ctx.plan.append(PlanRow(node.id, "where", f"{4 * n}->{n}", flops=2 * n))
    flat = [(v, i) for v in srcs for i in range(v.dim)]
    lane = lambda k: _float_lane(*flat[k])  # noqa: E731
    out = declare(ctx, f"v_{node.id}", n)
    for i in range(n):
        choice = ir.Choose(op, lane(i), lane(n + i), lane(2 * n + i), lane(3 * n + i))
        ctx.body.append(ir.Assign(out.lane_ir(i), choice))
    return out


# --- two branches ---------------------------------------------------------------------------

BINARY_EXPRESSIONS = {  # for floats and vec4s alike (t: which)
    "add": lambda a, b, t: ir.Bin("+", a, b),
    "sub": lambda a, b, t: ir.Bin("-", a, b),
    "mul": lambda a, b, t: ir.Bin("*", a, b),
    "div": lambda a, b, t: ir.Bin("/", a, b),
    "atan2": lambda a, b, t: ir.Call("inshade_atan2", (a, b), t),
}
BINARY_FLOPS = {"add": 1, "sub": 1, "mul": 1, "div": 1, "atan2": 20}


def emit_binary(ctx, node, srcs, bundle):
    n, op = node.out_dim, BINARY_EXPRESSIONS[node.type]
    ctx.plan.append(PlanRow(node.id, node.type, f"{2 * n}->{n}", flops=BINARY_FLOPS[node.type] * n))
    if node.type == "atan2":
        ctx.include("lib/activations")
    out = declare(ctx, f"v_{node.id}", n)
    if len(srcs) == 2 and all(s.dim == n and s.offset % 4 == 0 and s.kind == "float" for s in srcs):
        a, b = srcs
        ka, kb = a.offset // 4, b.offset // 4
        ctx.body += [ir.Assign(out.block_ir(k), op(a.block_ir(ka + k), b.block_ir(kb + k), "vec4"))
                     for k in range(n // 4)]
        first = 4 * (n // 4)
    else:
        first = 0
    lanes = [(v, i) for v in srcs for i in range(v.dim)]
    for i in range(first, n):
        ctx.body.append(ir.Assign(out.lane_ir(i), op(_float_lane(*lanes[i]), _float_lane(*lanes[n + i]), "float")))
    return out


emitter("add", "sub", "mul", "div", "atan2", separate_inputs=True, lowered=True)(emit_binary)


# --- int_gather -----------------------------------------------------------------------------

def _uint_op(sign: str):
    return lambda src, a, b: ir.Bin(sign, ir.Var(a), ir.Var(b))


INT_EXPRESSIONS = {   # uint arithmetic wraps modulo 2^32 in every target
    "lane": lambda src, a: ir.Convert("uint", ir.Convert("int", src.lane_ir(a))),   # toward 0, two's complement bits
    "const": lambda src, c: ir.Int(f"{c}u"),
    "shl": lambda src, a, s: ir.Bin("<<", ir.Var(a), ir.Int(f"{s}u")),
    "add": _uint_op("+"),
    "sub": _uint_op("-"),
    "mul": _uint_op("*"),
    "xor": _uint_op("^"),
    "and": _uint_op("&"),
    "or": _uint_op("|"),
}
ENTRY_ARGS = {"shl": (True, False), "lane": (False,), "const": (False,)}   # which arguments name entries


@emitter("int_gather", lowered=True)
def emit_int_gather(ctx, node, src, bundle):
    ctx.include("feature_axis/int_gather")
    p = node.params
    table = bundle.tensor(node, "table")
    entry = lambda k: ctx.name(node.id, f"n{k}")   # noqa: E731
    for k, (op, *args) in enumerate(p["program"]):
        named = ENTRY_ARGS.get(op, (True, True))
        args = [entry(a) if is_entry else a for a, is_entry in zip(args, named)]
        ctx.body.append(ir.Declare("uint", entry(k), init=INT_EXPRESSIONS[op](src, *args)))
    log2w, n_rows = row_layout(node.id, "gathered table", table.shape[0], ctx.limits)
    feats = p["features"]
    if feats % 4 == 3:   # textures hold 1, 2 or 4 channels
        table = np.pad(table, ((0, 0), (0, 1)))
    groups = feature_textures(ctx, node.id, table, "f32", log2w, n_rows, f"{table.shape[0]} rows")
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    row = ir.Var(ctx.name(node.id, "row"))
    ctx.body.append(ir.Declare("vec4", row.name))
    for j, k in enumerate(p["indices"]):
        for g, (name, width) in enumerate(groups):
            fetch = ir.Call("int_gather_row", (ir.TextureArg(name), ir.Int(str(log2w)), ir.Var(entry(k)),
                                               ir.Int(f"{p['rows']}u")))
            first = j * feats + 4 * g
            width = min(width, feats - 4 * g)
            if width == 4 and first % 4 == 0:
                ctx.body.append(ir.Assign(out.block_ir(first // 4), fetch))
                continue
            ctx.body.append(ir.Assign(row, fetch))
            ctx.body += [ir.Assign(out.lane_ir(first + ch), ir.Lane(row, ch)) for ch in range(width)]
    ctx.plan.append(PlanRow(node.id, node.type, f"{len(p['program'])} uint ops, {len(p['indices'])} rows of {feats}",
                            "texture/exact", f"{texture_formats(groups, 'f32')} table of {table.shape[0]} rows, "
                            f"rows of {1 << log2w} texels", params=int(table.size), flops=len(p["program"]),
                            fetches=len(p["indices"]) * len(groups),
                            texture_bytes=sum(r.nbytes for r in ctx.resources[-len(groups):])))
    return out
