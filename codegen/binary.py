"""Two branches combined lane by lane: a + b (residual connections), a - b, a * b, a / b, atan2(a, b)
(lib/activations' inshade_atan2: torch's values at zeros and infinities); torch twin in models/binary.py.

Input: the node's inputs as they are (separate_inputs), lanes concatenated = [a (n) | b (n)].
When a and b are two sources that start a vec4 block each, every whole block is one vec4 op and
the n % 4 tail is done lane by lane (a source's last block may hold another value's lanes, e.g.
bundle inputs packed side by side, so it is never used whole); otherwise lane by lane.
"""
from __future__ import annotations

from .glsl import PlanRow
from .registry import emitter
from .values import declare

EXPRESSIONS = {  # for floats and vec4s alike
    "add": lambda a, b: f"{a} + {b}",
    "sub": lambda a, b: f"{a} - {b}",
    "mul": lambda a, b: f"{a} * {b}",
    "div": lambda a, b: f"{a} / {b}",
    "atan2": lambda a, b: f"inshade_atan2({a}, {b})",
}
FLOPS = {"add": 1, "sub": 1, "mul": 1, "div": 1, "atan2": 20}


def _as_float(value, i: int) -> str:
    return value.lane(i) if value.kind == "float" else f"float({value.lane(i)})"


@emitter(*EXPRESSIONS, separate_inputs=True)
def emit_binary(ctx, node, srcs, bundle):
    n, op = node.out_dim, EXPRESSIONS[node.type]
    ctx.plan.append(PlanRow(node.id, node.type, f"{2 * n}->{n}", flops=FLOPS[node.type] * n))
    if node.type == "atan2":
        ctx.include("lib/activations")
    out = declare(ctx, f"v_{node.id}", n)
    if len(srcs) == 2 and all(s.dim == n and s.offset % 4 == 0 and s.kind == "float" for s in srcs):
        a, b = srcs
        ka, kb = a.offset // 4, b.offset // 4
        ctx.body += [f"{out.array}[{k}] = {op(f'{a.array}[{ka + k}]', f'{b.array}[{kb + k}]')};" for k in range(n // 4)]
        first = 4 * (n // 4)
    else:
        first = 0
    lanes = [(v, i) for v in srcs for i in range(v.dim)]
    for i in range(first, n):
        ctx.body.append(f"{out.lane(i)} = {op(_as_float(*lanes[i]), _as_float(*lanes[n + i]))};")
    return out
