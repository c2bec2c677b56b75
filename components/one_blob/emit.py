"""tiny-cuda-nn's OneBlob encoding: the GLSL emitter (its chunk: one_blob.glsl)."""
from __future__ import annotations

from inshade.codegen.glsl import PlanRow, flt
from inshade.codegen.registry import emitter
from inshade.codegen.values import declare


@emitter("one_blob")
def emit_one_blob(ctx, node, src, bundle):
    """Per input, the blob's cdf at the n_bins + 1 bin boundaries (each shared by two bins), and each
    bin the difference of its two: torch_twin.py (OneBlob) states the rule."""
    ctx.include("one_blob/one_blob")
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
