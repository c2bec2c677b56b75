"""Dense layers as mat4 blocks; torch twin in models/mlp.py.

A layer [out, in] is zero-padded to multiples of 4 and cut into 4x4 blocks; block (o, i)
multiplies input block i into output block o. Weight placement is a per-layer choice:

- inline:  const mat4 literals (fastest to run on most drivers, slow to compile when big)
- ubo:     one std140 uniform block per layer (weights swap without recompiling)
- texture: rows of an RGBA32F/RGBA16F texture read with texelFetch (any width)
All three give the same function signature and the same numbers (fp32 storage).
"""
from __future__ import annotations

import numpy as np

from .glsl import PlanRow, TextureResource, UniformBlockResource, blocks, flt, mat4, vec4
from .registry import emitter
from .values import declare

STORAGE_MODES = ("inline", "ubo", "texture", "auto")
UNROLL_MAX_BLOCKS = 256      # larger layers loop instead of unrolling (compile time)
INLINE_MAX_FLOATS = 4096     # auto: whole networks at most this big become literals
UBO_RESERVED_BLOCKS = 2      # auto: blocks left for the host program's own uniforms


def pack(weight: np.ndarray, bias: np.ndarray | None):
    """[out, in] weights -> blocks [OB, IB, 4, 4] (torch layout per block), bias [OB, 4]."""
    out_dim, in_dim = weight.shape
    ob, ib = blocks(out_dim), blocks(in_dim)
    w = np.zeros((ob * 4, ib * 4), np.float32)
    w[:out_dim, :in_dim] = weight
    b = np.zeros(ob * 4, np.float32)
    if bias is not None:
        b[:out_dim] = bias
    return w.reshape(ob, 4, ib, 4).transpose(0, 2, 1, 3), b.reshape(ob, 4)


def std140(wblocks: np.ndarray, bias: np.ndarray) -> bytes:
    """mat4 W[OB*IB] (column-major, 64 B each) followed by vec4 b[OB]."""
    cols = np.ascontiguousarray(wblocks.transpose(0, 1, 3, 2))  # [OB, IB, col, row]
    return cols.astype("<f4").tobytes() + bias.astype("<f4").tobytes()


def choose_storage(bundle, requested: str, limits: dict) -> dict[str, tuple[str, str]]:
    """Storage per dense node, with the reason the plan report prints."""
    dense = [n for n in bundle.nodes if n.type == "dense"]
    if requested != "auto":
        return {n.id: (requested, "requested") for n in dense}
    floats = sum(blocks(n.in_dim) * blocks(n.out_dim) * 16 + blocks(n.out_dim) * 4 for n in dense)
    if floats <= INLINE_MAX_FLOATS:
        why = f"network has {floats} floats <= {INLINE_MAX_FLOATS}: literals compile quickly"
        return {n.id: ("inline", why) for n in dense}
    max_bytes = int(limits.get("GL_MAX_UNIFORM_BLOCK_SIZE", 16384))
    free_blocks = int(limits.get("GL_MAX_FRAGMENT_UNIFORM_BLOCKS", 12)) - UBO_RESERVED_BLOCKS
    out = {}
    for n in dense:
        size = blocks(n.in_dim) * blocks(n.out_dim) * 64 + blocks(n.out_dim) * 16
        if size <= max_bytes and free_blocks > 0:
            free_blocks -= 1
            out[n.id] = ("ubo", f"{size} B fits GL_MAX_UNIFORM_BLOCK_SIZE={max_bytes}")
        elif size > max_bytes:
            out[n.id] = ("texture", f"{size} B exceeds GL_MAX_UNIFORM_BLOCK_SIZE={max_bytes}")
        else:
            out[n.id] = ("texture", "no uniform block binding left (GL_MAX_FRAGMENT_UNIFORM_BLOCKS)")
    return out


class WeightTexture:
    """One texture per network holding every texture-stored layer, a row per output block:
    texel 0 = bias, texels 1 + 4*i .. 4 + 4*i = the columns of block (o, i)."""

    def __init__(self, ctx):
        self.ctx, self.rows = ctx, []
        self.name = ctx.name("weights")

    def add(self, wblocks, bias) -> int:
        row0 = len(self.rows)
        for o in range(wblocks.shape[0]):
            cols = wblocks[o].transpose(0, 2, 1).reshape(-1, 4)  # [IB*4 columns, 4 rows]
            self.rows.append(np.concatenate([bias[o][None], cols], 0))
        return row0

    def resource(self) -> TextureResource | None:
        if not self.rows:
            return None
        width = max(len(r) for r in self.rows)
        data = np.zeros((len(self.rows), width, 4), np.float32)
        for y, r in enumerate(self.rows):
            data[y, : len(r)] = r
        fmt = self.ctx.texture_format
        if fmt == "f2":
            data = data.astype(np.float16)
        return TextureResource(self.name, data, fmt, "nearest")


def _accumulate(ctx, out, ob, ib, bias_expr, w_expr, src, loop: bool):
    if loop:
        ctx.body += [
            f"for (int o = 0; o < {ob}; ++o) {{",
            f"    vec4 acc = {bias_expr('o')};",
            f"    for (int i = 0; i < {ib}; ++i) acc += {w_expr('o', 'i')} * {src.array}[i];",
            f"    {out.array}[o] = acc;",
            "}",
        ]
        return
    for o in range(ob):
        terms = [bias_expr(str(o))] + [f"{w_expr(str(o), str(i))} * {src.array}[{i}]" for i in range(ib)]
        ctx.body.append(f"{out.array}[{o}] = " + "\n        + ".join(terms) + ";")


@emitter("dense")
def emit_dense(ctx, node, src, bundle):
    weight = bundle.tensor(node, "weight")
    bias = bundle.tensor(node, "bias") if node.params["bias"] else None
    wb, bb = pack(weight, bias)
    ob, ib = wb.shape[:2]
    mode, why = ctx.storage[node.id]
    big = ob * ib > UNROLL_MAX_BLOCKS
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    ctx.body.append(f"// {node.id}: dense {node.in_dim} -> {node.out_dim} ({ob}x{ib} mat4 blocks, {mode})")
    row = PlanRow(node.id, "dense", f"{node.in_dim}->{node.out_dim}", mode, why,
                  params=weight.size + (0 if bias is None else bias.size),
                  flops=2 * node.in_dim * node.out_dim + (node.out_dim if bias is not None else 0))
    name = ctx.name(node.id)
    if mode == "inline":
        ctx.globals.append(f"// {node.id}: dense {node.in_dim} -> {node.out_dim}, weights as literals")
        ctx.globals.append(f"const mat4 {name}_W[{ob * ib}] = mat4[](\n    "
                           + ",\n    ".join(mat4(wb[o, i]) for o in range(ob) for i in range(ib)) + ");")
        ctx.globals.append(f"const vec4 {name}_b[{ob}] = vec4[](" + ", ".join(vec4(b) for b in bb) + ");")
        _accumulate(ctx, out, ob, ib, lambda o: f"{name}_b[{o}]",
                    lambda o, i: f"{name}_W[{o} * {ib} + {i}]" if big else f"{name}_W[{int(o) * ib + int(i)}]",
                    src, big)
    elif mode == "ubo":
        data = std140(wb, bb)
        ctx.globals.append(f"// {node.id}: dense {node.in_dim} -> {node.out_dim}, std140 block of {len(data)} B")
        ctx.globals.append(f"layout(std140) uniform {name}_block {{\n    mat4 W[{ob * ib}];\n"
                           f"    vec4 b[{ob}];\n}} {name};")
        ctx.resources.append(UniformBlockResource(f"{name}_block", data))
        row.uniform_bytes = len(data)
        _accumulate(ctx, out, ob, ib, lambda o: f"{name}.b[{o}]",
                    lambda o, i: f"{name}.W[{o} * {ib} + {i}]" if big else f"{name}.W[{int(o) * ib + int(i)}]",
                    src, big)
    elif mode == "texture":
        tex = ctx.weight_texture
        row0 = tex.add(wb, bb)
        t = tex.name

        def fetch(o, i):
            r, c = f"{row0} + {o}", f"1 + 4 * {i}"
            return ("mat4(" + ", ".join(f"texelFetch({t}, ivec2({c} + {k}, {r}), 0)" for k in range(4)) + ")")
        _accumulate(ctx, out, ob, ib, lambda o: f"texelFetch({t}, ivec2(0, {row0} + {o}), 0)", fetch, src, True)
        row.fetches = ob * (1 + 4 * ib)
        row.texture_bytes = ob * (1 + 4 * ib) * 16 // (2 if ctx.texture_format == "f2" else 1)
    else:
        raise ValueError(f"unknown weight storage {mode!r} (choose from {', '.join(STORAGE_MODES)})")
    ctx.plan.append(row)
    return out
