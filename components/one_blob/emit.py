"""tiny-cuda-nn's OneBlob encoding: the emitter (its chunk: one_blob.glsl, and .wgsl / .hlsl)."""
from __future__ import annotations

from inshade.codegen import ir
from inshade.codegen.glsl import PlanRow
from inshade.codegen.registry import emitter
from inshade.codegen.values import declare


@emitter("one_blob", lowered=True)
def emit_one_blob(ctx, node, src, bundle):
    """Per input, the blob's cdf at the n_bins + 1 bin boundaries (each shared by two bins), and each
    bin the difference of its two: torch_twin.py (OneBlob) states the rule."""
    ctx.include("one_blob/one_blob")
    d, n = node.in_dim, node.params["n_bins"]
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    left, right = ir.Var(f"ob_{node.id}_left"), ir.Var(f"ob_{node.id}_right")
    ctx.body += [ir.Declare("float", left.name), ir.Declare("float", right.name)]
    bins = ir.Lit(float(n))
    for i in range(d):
        x = src.lane_ir(i)
        ctx.body.append(ir.Assign(left, ir.Call("one_blob_cdf", (ir.Lit(0.0), x, bins), "float")))
        for k in range(n):
            ctx.body += [ir.Assign(right, ir.Call("one_blob_cdf", (ir.Lit((k + 1) / n), x, bins), "float")),
                         ir.Assign(out.lane_ir(i * n + k), ir.Bin("-", right, left)), ir.Assign(left, right)]
    ctx.plan.append(PlanRow(node.id, node.type, f"{d}->{node.out_dim}", flops=d * (n + 1) * 3 * 12))
    return out
