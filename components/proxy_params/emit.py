"""The importance-sampling proxy's output activation: the emitter, as lowered code for every shading
language (formulas in models/proxy_lobe.py). The sampling routine and pdf that consume its 9 lanes are
shaders/lib/proxy_lobe.glsl, which the techniques' programs include too; its .wgsl / .hlsl versions
hold only the activation's functions."""
from __future__ import annotations

from inshade.codegen import ir
from inshade.codegen.glsl import PlanRow
from inshade.codegen.registry import emitter
from inshade.codegen.values import declare


def _float_call(fn: str, *args) -> ir.Call:
    return ir.Call(fn, args, "float")


@emitter("proxy_params", lowered=True)
def emit_proxy_params(ctx, node, src, bundle):
    ctx.include("lib/proxy_lobe")
    iso, amin = node.params["isotropic"], ir.Lit(node.params["alpha_min"])
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    r = src.lane_ir
    zero = ir.Lit(0.0)

    def alpha(i):   # max(0.5 * (1 + tanh_q(x)), alpha_min)
        half = ir.Bin("*", ir.Lit(0.5), ir.Paren(ir.Bin("+", ir.Lit(1.0), _float_call("proxy_tanh_q", r(i)))))
        return _float_call("max", half, amin)

    lanes = [_float_call("proxy_softmax2", r(0), r(1)), _float_call("proxy_softmax2", r(1), r(0))]
    if iso:
        lanes += [zero, zero, alpha(2), alpha(2), zero, zero, zero]
    else:
        rho = ir.Bin("*", ir.Lit(0.99, "0.99"), _float_call("proxy_tanh_q", r(6)))
        lanes += [_float_call("proxy_sinh_q", r(2)), _float_call("proxy_sinh_q", r(3)), alpha(4), alpha(5), rho,
                  _float_call("proxy_sinh_q", r(7)), _float_call("proxy_sinh_q", r(8))]
    for i, expr in enumerate(lanes):
        ctx.body.append(ir.Assign(out.lane_ir(i), expr))
    ctx.plan.append(PlanRow(node.id, "proxy_params", f"{node.in_dim}->9" + (" isotropic" if iso else ""),
                            flops=40))
    return out
