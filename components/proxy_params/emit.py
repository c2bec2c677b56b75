"""The importance-sampling proxy's output activation: the GLSL emitter (formulas in models/proxy_lobe.py).
The sampling routine and pdf that consume its 9 lanes are shaders/lib/proxy_lobe.glsl, which the
techniques' programs include too."""
from __future__ import annotations

from inshade.codegen.glsl import PlanRow, flt
from inshade.codegen.registry import emitter
from inshade.codegen.values import declare


@emitter("proxy_params")
def emit_proxy_params(ctx, node, src, bundle):
    ctx.include("lib/proxy_lobe")
    iso, amin = node.params["isotropic"], flt(node.params["alpha_min"])
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    r = src.lane
    alpha = lambda i: f"max(0.5 * (1.0 + proxy_tanh_q({r(i)})), {amin})"  # noqa: E731
    lanes = [f"proxy_softmax2({r(0)}, {r(1)})", f"proxy_softmax2({r(1)}, {r(0)})"]
    if iso:
        lanes += ["0.0", "0.0", alpha(2), alpha(2), "0.0", "0.0", "0.0"]
    else:
        lanes += [f"proxy_sinh_q({r(2)})", f"proxy_sinh_q({r(3)})", alpha(4), alpha(5),
                  f"0.99 * proxy_tanh_q({r(6)})", f"proxy_sinh_q({r(7)})", f"proxy_sinh_q({r(8)})"]
    for i, expr in enumerate(lanes):
        ctx.body.append(f"{out.lane(i)} = {expr};")
    ctx.plan.append(PlanRow(node.id, "proxy_params", f"{node.in_dim}->9" + (" isotropic" if iso else ""),
                            flops=40))
    return out
