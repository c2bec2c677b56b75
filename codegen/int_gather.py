"""Rows of a learned table at computed integer indices; torch twin in models/int_gather.py.

The node's program is straight-line uint32 code (GLSL's uint arithmetic wraps modulo 2^32, as the
twin reduces its int64 results), one `uint` per entry; each index then reads its row from the
table, stored as 2D textures in rows of 2^n texels (codegen/texture_rows.py), one per 4 features,
float32 (texelFetch returns the stored floats exactly).
"""
from __future__ import annotations

import numpy as np

from .glsl import PlanRow
from .registry import emitter
from .texture_rows import feature_textures, row_layout, texture_formats
from .values import declare

EXPRESSIONS = {
    "lane": lambda src, a: f"uint(int({src.lane(a)}))",   # toward 0, two's complement bits
    "const": lambda src, c: f"{c}u",
    "shl": lambda src, a, s: f"{a} << {s}u",
    "add": lambda src, a, b: f"{a} + {b}",
    "sub": lambda src, a, b: f"{a} - {b}",
    "mul": lambda src, a, b: f"{a} * {b}",
    "xor": lambda src, a, b: f"{a} ^ {b}",
    "and": lambda src, a, b: f"{a} & {b}",
    "or": lambda src, a, b: f"{a} | {b}",
}
ENTRY_ARGS = {"shl": (True, False), "lane": (False,), "const": (False,)}   # which arguments name entries


@emitter("int_gather")
def emit_int_gather(ctx, node, src, bundle):
    ctx.include("lib/int_gather")
    p = node.params
    table = bundle.tensor(node, "table")
    entry = lambda k: ctx.name(node.id, f"n{k}")   # noqa: E731
    for k, (op, *args) in enumerate(p["program"]):
        named = ENTRY_ARGS.get(op, (True, True))
        args = [entry(a) if is_entry else a for a, is_entry in zip(args, named)]
        ctx.body.append(f"uint {entry(k)} = {EXPRESSIONS[op](src, *args)};")
    log2w, n_rows = row_layout(node.id, "gathered table", table.shape[0], ctx.limits)
    feats = p["features"]
    if feats % 4 == 3:   # textures hold 1, 2 or 4 channels
        table = np.pad(table, ((0, 0), (0, 1)))
    groups = feature_textures(ctx, node.id, table, "f32", log2w, n_rows, f"{table.shape[0]} rows")
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    row = ctx.name(node.id, "row")
    ctx.body.append(f"vec4 {row};")
    for j, k in enumerate(p["indices"]):
        for g, (name, width) in enumerate(groups):
            fetch = f"int_gather_row({name}, {log2w}, {entry(k)}, {p['rows']}u)"
            first = j * feats + 4 * g
            width = min(width, feats - 4 * g)
            if width == 4 and first % 4 == 0:
                ctx.body.append(f"{out.array}[{first // 4}] = {fetch};")
                continue
            ctx.body.append(f"{row} = {fetch};")
            ctx.body += [f"{out.lane(first + ch)} = {row}.{'xyzw'[ch]};" for ch in range(width)]
    ctx.plan.append(PlanRow(node.id, node.type, f"{len(p['program'])} uint ops, {len(p['indices'])} rows of {feats}",
                            "texture/exact", f"{texture_formats(groups, 'f32')} table of {table.shape[0]} rows, "
                            f"rows of {1 << log2w} texels", params=int(table.size), flops=len(p["program"]),
                            fetches=len(p["indices"]) * len(groups),
                            texture_bytes=sum(r.nbytes for r in ctx.resources[-len(groups):])))
    return out
