"""The dense layer: runs of identical layers emitted once, as a loop over the layers.

A run is two or more dense layers of one shape (in = out width, same bias presence), all stored
in the weight texture, each followed by the same elementwise activation; each dense feeds only
its activation, and each activation but the last feeds only the next dense. Their rows are
consecutive in the weight texture (``WeightTexture.add``, OB rows a layer), so layer l reads
rows ``row0 + OB * l + o``:

    vec4 h[IB] = <the run's input>;
    for (int l = 0; l < L; ++l) { vec4 y[OB] = dense(h, rows of layer l); h = activation(y); }

Why: a driver that JIT-compiles shaders (llvmpipe) spends most of a big network's first draw
compiling it, and code emitted once is compiled once; a pixel does the same fetches and
arithmetic either way. Only texture layers fold: inline literals and uniform blocks differ per
layer in the code itself.

A driver that caps a pixel's loop iterations (``limits.loop_iteration_cap``) counts each layer
of the loop as one more: a run folds only while the network still fits the caller's evaluations.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from inshade.codegen import ir
from inshade.codegen.glsl import blocks
from inshade.codegen.limits import loop_iteration_cap
from inshade.codegen.registry import EMITTERS
from inshade.codegen.values import Value, declare
from inshade.components.elementwise.spec import ELEMENTWISE

# as modules: any module of this folder may be the first to import inshade.codegen, which loads emit.py
# (and so this folder's modules) while that one is still loading
from . import emit_plan, emit_products

MIN_RUN = 2   # layers; a single layer gains nothing from a loop


@dataclass(frozen=True)
class Run:
    layers: tuple   # ((dense node, activation node), ...) in graph order

    @property
    def first(self):
        return self.layers[0][0]

    @property
    def output(self):
        """The last activation: the run's value outside the loop."""
        return self.layers[-1][1]

    @property
    def ids(self) -> list[str]:
        return [n.id for pair in self.layers for n in pair]

    def __len__(self) -> int:
        return len(self.layers)


def _consumers(bundle) -> dict[str, list[str]]:
    """Node id -> the nodes (and bundle outputs) reading it, once per use."""
    out: dict[str, list[str]] = {}
    for n in bundle.nodes:
        for s in n.inputs:
            out.setdefault(s, []).append(n.id)
    for p in bundle.outputs:
        out.setdefault(p.node, []).append(f"output {p.name}")
    return out


def _layer(dense, nodes, consumers, storage):
    """(dense, its activation, the shape key layers of one run share), or None when the dense
    cannot be a layer of a run."""
    if dense.type != "dense" or storage.get(dense.id, ("",))[0] != "texture" or dense.in_dim != dense.out_dim:
        return None
    users = consumers.get(dense.id, [])
    act = nodes.get(users[0]) if len(users) == 1 else None
    if act is None or act.type not in ELEMENTWISE:
        return None
    key = (dense.in_dim, bool(dense.params["bias"]), dense.params.get("precision"), act.type, act.params)
    return dense, act, key


def find_runs(bundle, storage: dict) -> list[Run]:
    """Every maximal run of identical texture layers, in graph order."""
    nodes = {n.id: n for n in bundle.nodes}
    consumers = _consumers(bundle)
    runs, taken = [], set()
    for n in bundle.nodes:
        layer = _layer(n, nodes, consumers, storage)
        if layer is None or n.id in taken:
            continue
        pairs, key = [layer[:2]], layer[2]
        while True:
            users = consumers.get(pairs[-1][1].id, [])
            nxt = nodes.get(users[0]) if len(users) == 1 else None
            step = _layer(nxt, nodes, consumers, storage) if nxt is not None else None
            if step is None or step[2] != key or tuple(nxt.inputs) != (pairs[-1][1].id,):
                break
            pairs.append(step[:2])
        taken.update(d.id for d, _ in pairs)
        if len(pairs) >= MIN_RUN:
            runs.append(Run(tuple(pairs)))
    return runs


def fold_runs(bundle, storage: dict, chunks: dict, limits: dict, calls: int = 1) -> dict[str, Run]:
    """The runs to emit as layer loops, by their first dense's id: every run whose layers share
    one chunk (``emit_plan.loop_chunks``), while the loops' iterations stay within a capped driver's
    budget for ``calls`` evaluations (a run that does not fit stays unfolded)."""
    cap = loop_iteration_cap(limits)
    shapes = {n.id: (blocks(n.out_dim), blocks(n.in_dim)) for n in bundle.nodes if n.id in chunks}
    written = emit_plan.inputs_written_max(limits)
    used = sum(emit_plan.loop_iterations(*shapes[k], c, written) for k, (c, _) in chunks.items())
    out = {}
    for run in find_runs(bundle, storage):
        if len({chunks.get(d.id, (1, ''))[0] for d, _ in run.layers}) != 1:
            continue
        if cap is not None and used + len(run) > emit_plan.loop_budget(cap, calls):
            continue
        used += len(run)
        out[run.first.id] = run
    return out


def _captured(ctx, emit):
    """emit()'s result, and the body lines and plan rows it appended, taken back out of ctx."""
    nb, nr = len(ctx.body), len(ctx.plan)
    value = emit()
    body, rows = ctx.body[nb:], ctx.plan[nr:]
    del ctx.body[nb:], ctx.plan[nr:]
    return value, body, rows


def _weights(bundle, dense):
    return bundle.tensor(dense, "weight"), bundle.tensor(dense, "bias") if dense.params["bias"] else None


def _rows(tex, bundle, dense) -> int:
    """The layer's rows added to its weight texture (an i8 layer's with its row scales); its first row."""
    wb, bb = emit_plan.pack(*_weights(bundle, dense))
    scale = emit_plan.pack_rows(bundle.tensor(dense, "weight_scale"), wb.shape[0]) if tex.fmt == "i8" else None
    return tex.add(wb, bb, dense.id, scale)


def emit_run(ctx, run: Run, src: Value, bundle) -> Value:
    """The run as one loop over its layers, reading h and writing it back; the plan keeps a row
    per node, saying which loop it is in."""
    first, act0 = run.layers[0]
    ob, ib = blocks(first.out_dim), blocks(first.in_dim)
    chunk, unrolled = ctx.loop_chunks.get(first.id, (1, ""))
    tex = emit_plan.weight_texture(ctx, emit_plan.weight_format(ctx, first))
    row0 = [_rows(tex, bundle, d) for d, _ in run.layers][0]   # consecutive rows
    h = f"h_{first.id}"
    spare = emit_products.loop_spare(ob, ib, chunk)
    y, body, _ = _captured(ctx, lambda: declare(ctx, f"v_{first.id}", first.out_dim, spare=spare))
    rows = f"{row0} + {ob} * l"
    exprs = (emit_products.i8_texture_exprs(tex.name, rows, tex.side_name, ctx.option("dense", "i8_texels"))
             if tex.fmt == "i8" else emit_products.texture_exprs(tex.name, rows))
    arith = emit_products.ARITHMETICS[ctx.option("dense", "arithmetic")]
    written = emit_plan.inputs_written_max(ctx.limits)
    body.append(emit_products.loop_statement(y.array, ob, ib, chunk, *exprs, h, written, arith))
    out, act_body, act_rows = _captured(ctx, lambda: EMITTERS[act0.type](ctx, act0, y, bundle))
    body += act_body + [ir.Assign(ir.Index(ir.Var(h), b), out.block_ir(b)) for b in range(ib)]

    dense_ids = [d.id for d, _ in run.layers]
    ctx.body.append(ir.Comment(f"{', '.join(dense_ids)}: {len(run)} dense {first.in_dim} -> {first.out_dim} layers "
                               f"({ob}x{ib} mat4 blocks, texture rows {row0} + {ob} * l) with {act0.type}, one loop"))
    ctx.body.append(ir.Declare("vec4", h, ib))
    ctx.body += [ir.Assign(ir.Index(ir.Var(h), b), src.block_ir(b)) for b in range(ib)]
    ctx.body.append(ir.For("l", 0, len(run), None, tuple(body)))
    for d, act in run.layers:
        others = ", ".join(i for i in dense_ids if i != d.id)
        mode, why = ctx.storage[d.id]
        ctx.plan.append(emit_products.dense_row(ctx, d, *_weights(bundle, d), mode, why + unrolled + (
            f"; folded into one loop over layers with {others} (same shape and activation: its code is emitted once)")))
        ctx.plan += [replace(r, node=act.id, why=f"in the loop over layers {', '.join(dense_ids)}") for r in act_rows]
    return Value(h, 0, first.out_dim)
