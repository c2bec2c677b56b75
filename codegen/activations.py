"""Elementwise activations on vec4 blocks; torch twins in models/activations.py."""
from __future__ import annotations

from .glsl import PlanRow, blocks, flt
from .registry import emitter
from .values import declare

def _softplus(v, p):
    if p["threshold"] is not None:
        return f"inshade_softplus({v}, {flt(p['beta'])}, {flt(p['threshold'])})"
    return f"inshade_softplus({v})" if p["beta"] == 1.0 else f"(inshade_softplus({flt(p['beta'])} * {v}) / {flt(p['beta'])})"


def _clamp(v, p):
    lo, hi = p["min"], p["max"]
    if lo is not None and hi is not None:
        return f"clamp({v}, {flt(lo)}, {flt(hi)})"
    return f"max({v}, {flt(lo)})" if lo is not None else f"min({v}, {flt(hi)})"


_EXPR = {
    "relu": lambda v, p: f"max({v}, 0.0)",
    "leaky_relu": lambda v, p: f"max({v}, 0.0) + {flt(p['slope'])} * min({v}, 0.0)",
    "sigmoid": lambda v, p: f"inshade_sigmoid({v})",
    "tanh": lambda v, p: f"inshade_tanh({v})",
    "softplus": _softplus,
    "sin": lambda v, p: f"sin({flt(p['omega0'])} * {v})",
    "cos": lambda v, p: f"cos({flt(p['omega0'])} * {v})",
    "exp": lambda v, p: f"exp({v})",
    # GLSL has no expm1; exp(x) - 1 is within ~1e-7 absolute of it, inside the parity rule
    "expm1": lambda v, p: f"(exp({v}) - 1.0)",
    "silu": lambda v, p: f"inshade_silu({v})",
    "erf": lambda v, p: f"inshade_erf({v})",
    "gelu": lambda v, p: f"inshade_gelu{'_tanh' if p['approximate'] == 'tanh' else ''}({v})",
    "elu": lambda v, p: f"inshade_elu({v}, {flt(p['alpha'])})",
    "abs": lambda v, p: f"abs({v})",
    "clamp": _clamp,
    "sqrt": lambda v, p: f"sqrt({v})",
    "reciprocal": lambda v, p: f"(1.0 / {v})",
}
_FLOPS = {"relu": 1, "leaky_relu": 3, "sigmoid": 4, "tanh": 6, "softplus": 6, "sin": 2, "cos": 2, "exp": 1,
          "expm1": 2, "identity": 0, "silu": 4, "erf": 12, "gelu": 14, "elu": 4, "abs": 1, "clamp": 2, "sqrt": 1,
          "reciprocal": 1}


@emitter(*_EXPR, "identity")
def emit_activation(ctx, node, src, bundle):
    ctx.plan.append(PlanRow(node.id, node.type, f"{node.in_dim}", flops=_FLOPS[node.type] * node.in_dim))
    if node.type == "identity":
        return src
    ctx.include("lib/activations")
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    if src.aligned:
        for b in range(blocks(node.in_dim)):
            ctx.body.append(f"{out.array}[{b}] = {_EXPR[node.type](f'{src.array}[{b}]', node.params)};")
    else:
        for i in range(node.in_dim):
            ctx.body.append(f"{out.lane(i)} = {_EXPR[node.type](src.lane(i), node.params)};")
    return out
