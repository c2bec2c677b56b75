"""Input encodings: NeRF's frequencies, triangle waves, spherical harmonics: the GLSL emitters."""
from __future__ import annotations

import math

import numpy as np

from inshade.codegen.glsl import PlanRow, flt
from inshade.codegen.registry import emitter
from inshade.codegen.spherical_harmonics import basis_statements
from inshade.codegen.values import declare


@emitter("frequency")
def emit_frequency(ctx, node, src, bundle):
    d, n = node.in_dim, node.params["n_freqs"]
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    k = 0
    if node.params["include_input"]:
        for i in range(d):
            ctx.body.append(f"{out.lane(k)} = {src.lane(i)};")
            k += 1
    for fn in ("sin", "cos"):
        for f in range(n):
            scale = flt(np.float32((2.0 ** f) * math.pi))
            call = ctx.periodic(fn, node.id, f)
            for i in range(d):
                ctx.body.append(f"{out.lane(k)} = {call}({src.lane(i)} * {scale});")
                k += 1
    ctx.plan.append(PlanRow(node.id, node.type, f"{d}->{node.out_dim}", flops=4 * d * n))
    return out


@emitter("triangle_wave")
def emit_triangle_wave(ctx, node, src, bundle):
    ctx.include("lib/activations")
    d, n = node.in_dim, node.params["n_freqs"]
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    for f in range(n):
        for i in range(d):
            ctx.body.append(f"{out.lane(f * d + i)} = inshade_triangle({src.lane(i)} * {flt(2.0 ** f)});")
    ctx.plan.append(PlanRow(node.id, node.type, f"{d}->{node.out_dim}", flops=5 * d * n))
    return out


@emitter("spherical_harmonics")
def emit_spherical_harmonics(ctx, node, src, bundle):
    deg = node.params["degree"]
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    ctx.body += basis_statements(deg, [src.lane(i) for i in range(3)], out.lane, f"m_{node.id}_")
    ctx.plan.append(PlanRow(node.id, node.type, f"3->{node.out_dim}", flops=3 * node.out_dim))
    return out
