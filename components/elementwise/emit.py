"""Elementwise functions: the emitter, on vec4 blocks (torch twins: torch_twin.py). Ops with special
values (log, floor / ceil, fmod, remainder, power) call lib/activations' helpers, which match torch there."""
from __future__ import annotations

from inshade.codegen import ir
from inshade.codegen.glsl import PlanRow, blocks
from inshade.codegen.registry import emitter
from inshade.codegen.values import declare, gather
from inshade.components.elementwise.spec import ELEMENTWISE

# op -> the GLSL function of the value alone
_CALLS = {"sigmoid": "inshade_sigmoid", "tanh": "inshade_tanh", "exp": "exp", "silu": "inshade_silu",
          "erf": "inshade_erf", "abs": "abs", "sqrt": "sqrt", "log": "inshade_log", "log2": "inshade_log2",
          "floor": "inshade_floor", "ceil": "inshade_ceil", "trunc": "trunc",
          "round": "roundEven"}      # halves to even, as torch.round
# op -> the GLSL function of the value and a parameter, and that parameter
_CALLS_WITH = {"elu": ("inshade_elu", "alpha"), "fmod": ("inshade_fmod", "divisor"),
               "remainder": ("inshade_remainder", "divisor"), "power": ("inshade_pow", "exponent")}


def _softplus(v, p, t):
    if p["threshold"] is not None:
        return ir.Call("inshade_softplus", (v, ir.Lit(p["beta"]), ir.Lit(p["threshold"])), t)
    if p["beta"] == 1.0:
        return ir.Call("inshade_softplus", (v,), t)
    beta = ir.Lit(p["beta"])
    return ir.Paren(ir.Bin("/", ir.Call("inshade_softplus", (ir.Bin("*", beta, v),), t), beta))


def _clamp(v, p, t):
    lo, hi = p["min"], p["max"]
    if lo is not None and hi is not None:
        return ir.Call("clamp", (v, ir.Lit(lo), ir.Lit(hi)), t)
    return ir.Call("max", (v, ir.Lit(lo)), t) if lo is not None else ir.Call("min", (v, ir.Lit(hi)), t)


def _periodic(v, p, t):   # p["fn"]: sin or cos, or their range-reduced inshade_ forms (EmitContext.periodic)
    return ir.Call(p["fn"], (ir.Bin("*", ir.Lit(p["omega0"]), v),), t)


ZERO = ir.Lit(0.0)
_EXPR = {
    "relu": lambda v, p, t: ir.Call("max", (v, ZERO), t),
    "leaky_relu": lambda v, p, t: ir.Sum((ir.Call("max", (v, ZERO), t),
                                          ir.Bin("*", ir.Lit(p["slope"]), ir.Call("min", (v, ZERO), t)))),
    "softplus": _softplus,
    "sin": _periodic,
    "cos": _periodic,
    # GLSL has no expm1; exp(x) - 1 is within ~1e-7 absolute of it, inside the parity rule
    "expm1": lambda v, p, t: ir.Paren(ir.Bin("-", ir.Call("exp", (v,), t), ir.Lit(1.0))),
    "gelu": lambda v, p, t: ir.Call(f"inshade_gelu{'_tanh' if p['approximate'] == 'tanh' else ''}", (v,), t),
    "clamp": _clamp,
    "reciprocal": lambda v, p, t: ir.Paren(ir.Bin("/", ir.Lit(1.0), v)),
    # x - trunc(x) is exact in fp32 (trunc(x) is 0 or within a factor 2 of x: Sterbenz)
    "frac": lambda v, p, t: ir.Paren(ir.Bin("-", v, ir.Call("trunc", (v,), t))),
}
_FLOPS = {"relu": 1, "leaky_relu": 3, "sigmoid": 4, "tanh": 6, "softplus": 6, "sin": 2, "cos": 2, "exp": 1,
          "expm1": 2, "identity": 0, "silu": 4, "erf": 12, "gelu": 14, "elu": 4, "abs": 1, "clamp": 2, "sqrt": 1,
          "reciprocal": 1, "log": 4, "log2": 4, "floor": 3, "ceil": 3, "trunc": 1, "round": 1, "frac": 2,
          "fmod": 16, "remainder": 18, "power": 12}


def _expr(op: str, v: ir.Expr, p: dict, t: str) -> ir.Expr:
    """``op`` applied to the value ``v`` of type ``t`` (a lane, "float", or a whole block, "vec4")."""
    if op in _CALLS:
        return ir.Call(_CALLS[op], (v,), t)
    if op in _CALLS_WITH:
        fn, param = _CALLS_WITH[op]
        return ir.Call(fn, (v, ir.Lit(p[param])), t)
    return _EXPR[op](v, p, t)


def _infinite_at_zero(node_type: str, p: dict) -> bool:
    """Ops that turn a zero into +-inf: a padding lane (0) must not get one, since a dense layer
    that loops over whole blocks multiplies it by a zero weight (0 * inf = NaN)."""
    return node_type in ("reciprocal", "log", "log2") or node_type == "power" and p["exponent"] < 0


# Helpers with a loop: called on whole vec4 blocks only (their vec4 forms loop over the lanes), since
# llvmpipe's compile time doubles with each loop that follows another at the top level of a shader.
_LOOPING = ("fmod", "remainder")


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
            ctx.body.append(ir.Assign(out.block_ir(b), _expr(node.type, src.block_ir(b), params, "vec4")))
    for i in range(4 * whole, node.in_dim):
        ctx.body.append(ir.Assign(out.lane_ir(i), _expr(node.type, src.lane_ir(i), params, "float")))
    return out


emitter(*ELEMENTWISE, lowered=True)(emit_activation)
