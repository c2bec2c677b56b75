"""Elementwise activations and ops on vec4 blocks; torch twins in models/activations.py. Ops with special
values (log, floor / ceil, fmod, remainder, power) call lib/activations' helpers, which match torch there."""
from __future__ import annotations

from .glsl import PlanRow, blocks, flt
from .registry import emitter
from .values import declare, gather

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
    "sin": lambda v, p: f"{p['fn']}({flt(p['omega0'])} * {v})",   # fn: sin or inshade_sin (EmitContext.periodic)
    "cos": lambda v, p: f"{p['fn']}({flt(p['omega0'])} * {v})",
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
    "log": lambda v, p: f"inshade_log({v})",
    "log2": lambda v, p: f"inshade_log2({v})",
    "floor": lambda v, p: f"inshade_floor({v})",
    "ceil": lambda v, p: f"inshade_ceil({v})",
    "trunc": lambda v, p: f"trunc({v})",
    "round": lambda v, p: f"roundEven({v})",      # halves to even, as torch.round
    # x - trunc(x) is exact in fp32 (trunc(x) is 0 or within a factor 2 of x: Sterbenz)
    "frac": lambda v, p: f"({v} - trunc({v}))",
    "fmod": lambda v, p: f"inshade_fmod({v}, {flt(p['divisor'])})",
    "remainder": lambda v, p: f"inshade_remainder({v}, {flt(p['divisor'])})",
    "power": lambda v, p: f"inshade_pow({v}, {flt(p['exponent'])})",
}
_FLOPS = {"relu": 1, "leaky_relu": 3, "sigmoid": 4, "tanh": 6, "softplus": 6, "sin": 2, "cos": 2, "exp": 1,
          "expm1": 2, "identity": 0, "silu": 4, "erf": 12, "gelu": 14, "elu": 4, "abs": 1, "clamp": 2, "sqrt": 1,
          "reciprocal": 1, "log": 4, "log2": 4, "floor": 3, "ceil": 3, "trunc": 1, "round": 1, "frac": 2,
          "fmod": 16, "remainder": 18, "power": 12}


def _infinite_at_zero(node_type: str, p: dict) -> bool:
    """Ops that turn a zero into +-inf: a padding lane (0) must not get one, since a dense layer
    that loops over whole blocks multiplies it by a zero weight (0 * inf = NaN)."""
    return node_type in ("reciprocal", "log", "log2") or node_type == "power" and p["exponent"] < 0


# Helpers with a loop: called on whole vec4 blocks only (their vec4 forms loop over the lanes), since
# llvmpipe's compile time doubles with each loop that follows another at the top level of a shader.
_LOOPING = ("fmod", "remainder")


@emitter(*_EXPR, "identity")
def emit_activation(ctx, node, src, bundle):
    ctx.plan.append(PlanRow(node.id, node.type, f"{node.in_dim}", flops=_FLOPS[node.type] * node.in_dim))
    if node.type == "identity":
        return src
    ctx.include("lib/activations")
    if node.type in _LOOPING and not src.aligned:
        src = gather(ctx, f"g_{node.id}", [src])
    params = node.params
    if node.type in ("sin", "cos"):
        params = {**params, "fn": ctx.periodic(node.type, node.id)}
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    whole = 0
    if src.aligned:   # whole blocks, the last one's padding lanes too unless that makes them infinite
        whole = node.in_dim // 4 if _infinite_at_zero(node.type, node.params) else blocks(node.in_dim)
        for b in range(whole):
            ctx.body.append(f"{out.array}[{b}] = {_EXPR[node.type](f'{src.array}[{b}]', params)};")
    for i in range(4 * whole, node.in_dim):
        ctx.body.append(f"{out.lane(i)} = {_EXPR[node.type](src.lane(i), params)};")
    return out
