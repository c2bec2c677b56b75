"""Input encodings; torch twins in models/encodings.py."""
from __future__ import annotations

import math

import numpy as np

from .glsl import PlanRow, flt
from .registry import emitter
from .spherical_harmonics import basis_statements
from .values import declare


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


@emitter("one_blob")
def emit_one_blob(ctx, node, src, bundle):
    """Per input, the blob's cdf at the n_bins + 1 bin boundaries (each shared by two bins), and each
    bin the difference of its two: models/encodings.py (OneBlob) states the rule."""
    ctx.include("lib/one_blob")
    d, n = node.in_dim, node.params["n_bins"]
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    left, right = f"ob_{node.id}_left", f"ob_{node.id}_right"
    ctx.body.append(f"float {left}, {right};")
    bins = flt(float(n))
    for i in range(d):
        ctx.body.append(f"{left} = one_blob_cdf(0.0, {src.lane(i)}, {bins});")
        for k in range(n):
            ctx.body += [f"{right} = one_blob_cdf({flt((k + 1) / n)}, {src.lane(i)}, {bins});",
                         f"{out.lane(i * n + k)} = {right} - {left};", f"{left} = {right};"]
    ctx.plan.append(PlanRow(node.id, node.type, f"{d}->{node.out_dim}", flops=d * (n + 1) * 3 * 12))
    return out


@emitter("spherical_harmonics")
def emit_spherical_harmonics(ctx, node, src, bundle):
    deg = node.params["degree"]
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    ctx.body += basis_statements(deg, [src.lane(i) for i in range(3)], out.lane, f"m_{node.id}_")
    ctx.plan.append(PlanRow(node.id, node.type, f"3->{node.out_dim}", flops=3 * node.out_dim))
    return out
