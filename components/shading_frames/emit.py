"""Learned shading frames (Eq. 7): the GLSL emitter, inline; torch twin and layout in torch_twin.py.

The 6N x latent layer is small (96 weights for the paper's N = 2, latent 8), so its weights are
literals: per 3-vector, bias + sum_i z_i * column_i, then the guarded normalisations and dots.
"""
from __future__ import annotations

from inshade.codegen.glsl import PlanRow, flt
from inshade.codegen.registry import emitter
from inshade.codegen.values import declare


def _vec3(values) -> str:
    return "vec3(" + ", ".join(flt(v) for v in values) + ")"


@emitter("shading_frames")
def emit_shading_frames(ctx, node, src, bundle):
    ctx.include("shading_frames/shading_frames")
    p = node.params
    latent, frames = p["latent"], p["frames"]
    w, b = bundle.tensor(node, "weight"), bundle.tensor(node, "bias")
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    light = f"vec3({', '.join(src.lane(latent + i) for i in range(3))})"
    view = f"vec3({', '.join(src.lane(latent + 3 + i) for i in range(3))})"
    for k in range(frames):
        vecs = []
        for j, what in enumerate(("n", "t")):
            rows = slice(6 * k + 3 * j, 6 * k + 3 * j + 3)
            name = ctx.name(node.id, f"{what}{k}")
            terms = " + ".join([_vec3(b[rows])] + [f"{src.lane(i)} * {_vec3(w[rows, i])}" for i in range(latent)])
            ctx.body.append(f"vec3 {name} = inshade_frame_normalize({terms});")
            vecs.append(name)
        n, t = vecs
        bt = ctx.name(node.id, f"b{k}")
        ctx.body.append(f"vec3 {bt} = inshade_frame_normalize(cross({n}, {t}));")
        for i, (vec, d) in enumerate([(t, light), (bt, light), (n, light), (t, view), (bt, view), (n, view)]):
            ctx.body.append(f"{out.lane(6 * k + i)} = dot({vec}, {d});")
    ctx.plan.append(PlanRow(node.id, "shading_frames", f"{latent}->{frames} frames", "inline",
                            params=int(w.size + b.size), flops=frames * (2 * 6 * latent + 40)))
    return out
