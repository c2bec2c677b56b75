"""toy_softsign: the GLSL emitter; its chunk is toy_softsign.glsl in this folder."""
from __future__ import annotations

from inshade.codegen.glsl import PlanRow, flt
from inshade.codegen.registry import emitter
from inshade.codegen.values import declare


@emitter("toy_softsign")
def emit_toy_softsign(ctx, node, src, bundle):
    ctx.include("toy_softsign/toy_softsign")
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    scale = flt(node.params["scale"])
    for i in range(node.in_dim):
        ctx.body.append(f"{out.lane(i)} = toy_softsign({src.lane(i)}, {scale});")
    ctx.plan.append(PlanRow(node.id, node.type, f"{node.in_dim}->{node.out_dim}", flops=3 * node.in_dim))
    return out
