"""GLSL of the feature-axis components (affine, select, reduce, layer_norm); torch twins in
models/feature_ops.py. Constants are literals: they are per-lane vectors, not weight matrices."""
from __future__ import annotations

import numpy as np

from .glsl import PlanRow, blocks, flt, vec4
from .registry import emitter
from .values import Value, declare


def _block(a: np.ndarray, k: int) -> np.ndarray:
    """Lanes 4k..4k+3 of ``a``, zero past its end."""
    part = np.asarray(a[4 * k:4 * k + 4], np.float32)
    return np.pad(part, (0, 4 - len(part)))


def _padded(a: np.ndarray, n: int, fill: float) -> np.ndarray:
    out = np.full(blocks(n) * 4, fill, np.float32)
    out[:n] = a
    return out


@emitter("affine")
def emit_affine(ctx, node, src, bundle):
    n = node.out_dim
    scale = _padded(bundle.tensor(node, "scale"), n, 0.0)
    offset = _padded(bundle.tensor(node, "offset"), n, 0.0)
    ctx.plan.append(PlanRow(node.id, "affine", f"{n}", flops=2 * n))
    out = declare(ctx, f"v_{node.id}", n)
    for b in range(blocks(n)):   # src is lane-0 aligned (gathered); padding lanes become 0 * x + 0
        ctx.body.append(f"{out.array}[{b}] = {src.array}[{b}] * {vec4(scale[4 * b:4 * b + 4])} + "
                        f"{vec4(offset[4 * b:4 * b + 4])};")
    return out


@emitter("select", separate_inputs=True)
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
        v, j = flat[i]
        ctx.body.append(f"{out.lane(k)} = {v.lane(j) if v.kind == 'float' else f'float({v.lane(j)})'};")
    return out


def _fold(terms: list[str], op: str) -> str:
    if op in ("max", "min"):
        expr = terms[0]
        for t in terms[1:]:
            expr = f"{op}({expr}, {t})"
        return expr
    return " + ".join(terms)


def _runs(src, groups: int, size: int):
    """Per group, its terms as whole vec4 blocks [(block expr, lanes used)] when every group starts
    on a block (size % 4 == 0, or one group: its last block partly used), else None (lane by lane)."""
    if not (src.aligned and (size % 4 == 0 or groups == 1)):
        return None
    out = []
    for g in range(groups):
        first = g * size // 4
        out.append([(f"{src.array}[{first + k}]", min(4, size - 4 * k)) for k in range(blocks(size))])
    return out


def _mask(used: int) -> str:
    return "vec4(1.0)" if used == 4 else vec4([1.0] * used + [0.0] * (4 - used))


@emitter("reduce")
def emit_reduce(ctx, node, src, bundle):
    op, groups = node.params["op"], node.params["groups"]
    size = node.in_dim // groups
    ctx.plan.append(PlanRow(node.id, f"reduce {op}", f"{node.in_dim}->{groups}", flops=2 * node.in_dim))
    out = declare(ctx, f"v_{node.id}", groups)
    runs = _runs(src, groups, size) if op in ("sum", "mean", "norm") else None
    for g in range(groups):
        if runs is not None:   # dot products of whole blocks (padding lanes masked out)
            terms = [f"dot({b}, {_mask(u)})" if op != "norm" else f"dot({b} * {_mask(u)}, {b})" for b, u in runs[g]]
        else:
            lanes = [src.lane(g * size + i) for i in range(size)]
            terms = [f"{x} * {x}" for x in lanes] if op == "norm" else lanes
        expr = _fold(terms, "sum" if op in ("norm", "mean") else op)
        expr = f"sqrt({expr})" if op == "norm" else f"({expr}) / {flt(size)}" if op == "mean" else expr
        ctx.body.append(f"{out.lane(g)} = {expr};")
    return out


@emitter("layer_norm")
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
        if runs is not None:   # whole blocks: the deviations d = (x - mean) * mask, one vec4 each
            parts = runs[g]
            ctx.body.append(f"float {m}_{g} = ({' + '.join(f'dot({x}, {_mask(u)})' for x, u in parts)}) / {flt(size)};")
            ctx.body += [f"vec4 {d}_{g}_{k} = ({x} - {m}_{g}) * {_mask(u)};" for k, (x, u) in enumerate(parts)]
            squares = " + ".join(f"dot({d}_{g}_{k}, {d}_{g}_{k})" for k in range(len(parts)))
            ctx.body.append(f"float {r}_{g} = 1.0 / sqrt(({squares}) / {flt(size)} + {flt(p['eps'])});")
            for k in range(len(parts)):
                expr = f"{d}_{g}_{k} * {r}_{g}"
                if w is not None:
                    expr += f" * {vec4(_block(w, k))} + {vec4(_block(b, k))}"
                ctx.body.append(f"{out.array}[{g * size // 4 + k}] = {expr};")
            continue
        lanes = [src.lane(g * size + i) for i in range(size)]
        ctx.body.append(f"float {m}_{g} = ({' + '.join(lanes)}) / {flt(size)};")
        squares = " + ".join(f"({x} - {m}_{g}) * ({x} - {m}_{g})" for x in lanes)
        # 1 / sqrt: inversesqrt may be an approximation (the GLSL spec allows 2 ulp)
        ctx.body.append(f"float {r}_{g} = 1.0 / sqrt(({squares}) / {flt(size)} + {flt(p['eps'])});")
        for i, x in enumerate(lanes):
            expr = f"({x} - {m}_{g}) * {r}_{g}"
            if w is not None:
                expr = f"{expr} * {flt(w[i])} + {flt(b[i])}"
            ctx.body.append(f"{out.lane(g * size + i)} = {expr};")
    return out


_COMPARE = {"gt": ">", "ge": ">=", "lt": "<", "le": "<="}


@emitter("where", separate_inputs=True)
def emit_where(ctx, node, srcs, bundle):
    n, op = node.out_dim, _COMPARE[node.params["op"]]
    ctx.plan.append(PlanRow(node.id, "where", f"{4 * n}->{n}", flops=2 * n))
    flat = [(v, i) for v in srcs for i in range(v.dim)]
    lane = lambda k: flat[k][0].lane(flat[k][1]) if flat[k][0].kind == "float" else f"float({flat[k][0].lane(flat[k][1])})"  # noqa: E731
    out = declare(ctx, f"v_{node.id}", n)
    for i in range(n):
        ctx.body.append(f"{out.lane(i)} = {lane(i)} {op} {lane(n + i)} ? {lane(2 * n + i)} : {lane(3 * n + i)};")
    return out
