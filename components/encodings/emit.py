"""Input encodings: NeRF's frequencies, triangle waves, spherical harmonics: the emitters (lowered: every target)."""
from __future__ import annotations

import math

import numpy as np

from inshade.codegen import ir
from inshade.codegen.glsl import PlanRow
from inshade.codegen.registry import emitter
from inshade.codegen.spherical_harmonics import basis_statements
from inshade.codegen.values import declare


@emitter("frequency", lowered=True)
def emit_frequency(ctx, node, src, bundle):
    d, n = node.in_dim, node.params["n_freqs"]
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    k = 0
    if node.params["include_input"]:
        for i in range(d):
            ctx.body.append(ir.Assign(out.lane_ir(k), src.lane_ir(i)))
            k += 1
    for fn in ("sin", "cos"):
        for f in range(n):
            scale = ir.Lit(np.float32((2.0 ** f) * math.pi))
            call = ctx.periodic(fn, node.id, f)
            for i in range(d):
                ctx.body.append(ir.Assign(out.lane_ir(k), ir.Call(call, (ir.Bin("*", src.lane_ir(i), scale),), "float")))
                k += 1
    ctx.plan.append(PlanRow(node.id, node.type, f"{d}->{node.out_dim}", flops=4 * d * n))
    return out


@emitter("triangle_wave", lowered=True)
def emit_triangle_wave(ctx, node, src, bundle):
    ctx.include("lib/activations")
    d, n = node.in_dim, node.params["n_freqs"]
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    for f in range(n):
        for i in range(d):
            arg = ir.Bin("*", src.lane_ir(i), ir.Lit(2.0 ** f))
            ctx.body.append(ir.Assign(out.lane_ir(f * d + i), ir.Call("inshade_triangle", (arg,), "float")))
    ctx.plan.append(PlanRow(node.id, node.type, f"{d}->{node.out_dim}", flops=5 * d * n))
    return out


@emitter("spherical_harmonics", lowered=True)
def emit_spherical_harmonics(ctx, node, src, bundle):
    deg = node.params["degree"]
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    ctx.body += basis_statements(deg, [src.lane_ir(i) for i in range(3)], out.lane_ir, f"m_{node.id}_")
    ctx.plan.append(PlanRow(node.id, node.type, f"3->{node.out_dim}", flops=3 * node.out_dim))
    return out
