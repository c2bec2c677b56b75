"""Learned shading frames (Eq. 7): the emitter, inline, as lowered code for every shading language (the
guarded normalise: shading_frames.glsl and its .wgsl / .hlsl versions); torch twin and layout in torch_twin.py.

The 6N x latent layer is small (96 weights for the paper's N = 2, latent 8), so its weights are
literals: per 3-vector, bias + sum_i z_i * column_i, then the guarded normalisations and dots.
"""
from __future__ import annotations

from inshade.codegen import ir
from inshade.codegen.glsl import PlanRow
from inshade.codegen.registry import emitter
from inshade.codegen.values import declare


def _vec3(values) -> ir.Vector:
    return ir.Vector("vec3", tuple(ir.Lit(float(v)) for v in values))


def _normalize(e) -> ir.Call:
    return ir.Call("inshade_frame_normalize", (e,), "vec3")


@emitter("shading_frames", lowered=True)
def emit_shading_frames(ctx, node, src, bundle):
    ctx.include("shading_frames/shading_frames")
    p = node.params
    latent, frames = p["latent"], p["frames"]
    w, b = bundle.tensor(node, "weight"), bundle.tensor(node, "bias")
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    light = ir.Vector("vec3", tuple(src.lane_ir(latent + i) for i in range(3)))
    view = ir.Vector("vec3", tuple(src.lane_ir(latent + 3 + i) for i in range(3)))
    for k in range(frames):
        vecs = []
        for j, what in enumerate(("n", "t")):
            rows = slice(6 * k + 3 * j, 6 * k + 3 * j + 3)
            name = ctx.name(node.id, f"{what}{k}")
            terms = (_vec3(b[rows]), *(ir.Bin("*", src.lane_ir(i), _vec3(w[rows, i])) for i in range(latent)))
            ctx.body.append(ir.Declare("vec3", name, init=_normalize(ir.Sum(terms))))
            vecs.append(ir.Var(name))
        n, t = vecs
        bt = ctx.name(node.id, f"b{k}")
        ctx.body.append(ir.Declare("vec3", bt, init=_normalize(ir.Call("cross", (n, t), "vec3"))))
        for i, (vec, d) in enumerate([(t, light), (ir.Var(bt), light), (n, light), (t, view), (ir.Var(bt), view),
                                      (n, view)]):
            ctx.body.append(ir.Assign(out.lane_ir(6 * k + i), ir.Call("dot", (vec, d), "float")))
    ctx.plan.append(PlanRow(node.id, "shading_frames", f"{latent}->{frames} frames", "inline",
                            params=int(w.size + b.size), flops=frames * (2 * 6 * latent + 40)))
    return out
