"""The dense layer: the GLSL emitter, mat4 blocks (torch twin: torch_twin.py).

A layer [out, in] is zero-padded to multiples of 4 and cut into 4x4 blocks; block (o, i)
multiplies input block i into output block o. Weight placement is a per-layer choice:

- inline:  literals written straight into the expressions (fastest to run on every driver
           measured, slowest to compile when big)
- ubo:     one std140 uniform block per layer (weights swap without recompiling)
- ssbo:    one read-only storage buffer per layer, the same bytes (no uniform block size cap; Vulkan,
           WebGPU and D3D only: OpenGL's GLSL 3.30 and ES 3.00 have none)
- texture: rows of an RGBA32F/RGBA16F texture read with texelFetch (any width)
All give the same function signature and the same numbers (fp32 storage).

How the code is shaped, and why (measured with `inshade bench mlp` on Mesa 22.3 llvmpipe,
LLVM 15, 256-bit, 2 cores; see the bench report for numbers):

- llvmpipe runs a fragment shader SoA, 8 pixels per AVX register: every GLSL float is one ymm
  register, so a 64-wide layer holds 64 live inputs (16 registers exist) and spills whatever
  form the source takes. What helps is short dependency chains (floats are not reassociated):
  each output block sums into SPLIT partial accumulators, and each term is
  `x[i].k * vec4(column)` with padding columns left out.
- inline literals are constant-pool operands; `const mat4 W[]` arrays cost ~3x the GLSL
  compile+link time for no runtime gain, so literals go straight into the expressions.
- In llvmpipe fragment shaders every UBO load and texelFetch is a per-lane gather (lane 0 may
  be inactive, so the scalar fast path is off): ubo and texture run 10-20x slower than inline
  there, and unrolled UBO code takes minutes to JIT. Hence big layers loop (small code), and
  on software renderers `auto` keeps literals up to a much larger size.
- Runs of identical texture layers loop over the layers too (emit_layer_loop.py): code emitted
  once is JIT-compiled once.

The plan (storage per layer, loop sizes, packing, the weight texture) is emit_plan.py, the code of a
layer's products emit_products.py, the loops over layers emit_layer_loop.py.
"""
from __future__ import annotations

from inshade.codegen import ir
from inshade.codegen.glsl import INTEGER_DTYPES, StorageBufferResource, UniformBlockResource
from inshade.codegen.registry import Fused, emitter, network_step
from inshade.codegen.values import declare
from inshade.codegen.targets import TargetError
from inshade.codegen.targets import TARGETS
from inshade.codegen.targets import target as find_target
from inshade.components.dense.spec import ARITHMETIC, I8_TEXELS, OPENGL_STORAGE_MODES, STORAGE_MODES, TEXTURE_FORMATS

# as modules: any module of this folder may be the first to import inshade.codegen, which loads this
# module (and so the others) while that one is still loading
from . import emit_layer_loop, emit_packed, emit_plan, emit_products


@network_step("dense")
class DenseNetwork:
    """What a network's dense layers share: the storage of each (chosen over the whole network: ``auto``
    counts every layer's floats), the loop sizes, one weight texture, and runs of identical layers
    emitted as one loop over the layers."""

    @staticmethod
    def begin(ctx, bundle, calls: int) -> dict:
        requested = ctx.option("dense", "storage")
        if find_target(ctx.target).opengl and requested not in OPENGL_STORAGE_MODES:
            raise TargetError(f"storage {requested!r}: OpenGL's GLSL ({ctx.target}) has no storage buffers here "
                              f"(GLSL 3.30 and ES 3.00 have none); choose from {', '.join(OPENGL_STORAGE_MODES)}, "
                              "or a target that has them (vulkan, wgsl, hlsl, slang)")
        check_arithmetic(ctx, bundle)
        ctx.storage = emit_plan.choose_storage(bundle, requested, ctx.limits)
        ctx.loop_chunks = emit_plan.loop_chunks(bundle, ctx.storage, ctx.limits, calls)
        ctx.weight_textures = {}
        runs = emit_layer_loop.fold_runs(bundle, ctx.storage, ctx.loop_chunks, ctx.limits, calls)
        return {first: Fused(tuple(run.ids), run.output.id,
                             lambda ctx, src, bundle, run=run: emit_layer_loop.emit_run(ctx, run, src, bundle))
                for first, run in runs.items()}

    @staticmethod
    def end(ctx) -> None:
        if ctx.option("dense", "arithmetic") != "f32":
            ctx.enables.add("f16")
        for fmt, tex in reversed(ctx.weight_textures.items()):
            texture, side = tex.resource(), tex.side_resource()
            if side is not None:
                ctx.globals.insert(0, ir.Texture(side.name, "the int8 rows' biases (texel 0) and scales (texel 1)"))
                ctx.resources.insert(0, side)
            if texture is not None:
                what = "int8 codes + 128" if fmt == "i8" else "rows"
                ctx.globals.insert(0, ir.Texture(texture.name, f"dense layers stored as texture {what}",
                                                 integer=texture.dtype in INTEGER_DTYPES))
                ctx.resources.insert(0, texture)


def _inline(ctx, node, out, wb, bb, chunk, row, src, bundle):
    """Weights as literals: in the expressions, or a const array a big layer loops over."""
    ob, ib = wb.shape[:2]
    name = ctx.name(node.id)
    arith = arithmetic(ctx)
    if ob * ib <= emit_plan.UNROLL_MAX_BLOCKS:
        x = emit_products.half_inputs(ctx, out, src, ib, arith)
        emit_products.emit_unrolled(ctx, out, wb, lambda o: ir.Vec4.of(bb[o]), lambda o, i: emit_products.column_terms(
            i, node.in_dim, x(i), lambda k: arith.value(ir.Vec4.of(wb[o, i][:, k]))), arith)
        return
    ctx.globals += [
        ir.Comment(f"{node.id}: dense {node.in_dim} -> {node.out_dim}, weights as literals"),
        ir.ConstArray("mat4", f"{name}_W", tuple(ir.Mat4(tuple(ir.Lit(v) for v in wb[o, i].T.reshape(-1)))
                                                  for o in range(ob) for i in range(ib))),
        ir.ConstArray("vec4", f"{name}_b", tuple(ir.Vec4.of(b) for b in bb))]
    emit_products.emit_loop(ctx, out, ob, ib, chunk, lambda o: ir.Index(ir.Var(f"{name}_b"), o),
                            lambda o, i: ir.Index(ir.Var(f"{name}_W"), ir.Int(f"({o.text}) * {ib} + {i.text}")), src,
                            arith)


def _block(ctx, node, out, wb, bb, chunk, row, src, bundle, storage: bool = False):
    """Weights in a std140 uniform block of their own (or, ``storage``, a read-only storage buffer: the
    same bytes in std430); an f16 or i8 layer's at its precision's bytes (emit_packed.py)."""
    ob, ib = wb.shape[:2]
    name = ctx.name(node.id)
    precision = node.params.get("precision", "f32")
    block = ir.Var(name)
    if precision == "f32":
        data, members = emit_plan.std140(wb, bb), (("mat4", "W", ob * ib), ("vec4", "b", ob))

        def column(o, i, k):
            return ir.Index(ir.Index(ir.Member(block, "W"), ir.Int(f"({o.text}) * {ib} + {i.text}")), k)
    else:
        scale = emit_plan.pack_rows(bundle.tensor(node, "weight_scale"), ob) if precision == "i8" else None
        data, members = emit_packed.block_bytes(precision, wb, bb, scale), emit_packed.members(precision, ob, ib)

        def column(o, i, k):
            return emit_packed.columns(ctx, block, precision, o, i, ib)[k]
    what = "std430 storage buffer" if storage else "std140 block"
    ctx.globals += [ir.Comment(f"{node.id}: dense {node.in_dim} -> {node.out_dim}, {what} of {len(data)} B"),
                    ir.UniformBlock(f"{name}_block", name, members, storage=storage)]
    ctx.resources.append((StorageBufferResource if storage else UniformBlockResource)(f"{name}_block", data, name,
                                                                                    members))
    row.uniform_bytes = len(data)
    arith = arithmetic(ctx)
    if ob * ib <= emit_plan.UBO_UNROLL_MAX_BLOCKS:
        x = emit_products.half_inputs(ctx, out, src, ib, arith)
        emit_products.emit_unrolled(
            ctx, out, wb, lambda o: ir.Index(ir.Member(block, "b"), o), lambda o, i: emit_products.column_terms(
                i, node.in_dim, x(i), lambda k: arith.value(column(ir.Int(str(o)), ir.Int(str(i)), k))), arith)
    else:
        emit_products.emit_loop(ctx, out, ob, ib, chunk, lambda o: ir.Index(ir.Member(block, "b"), o),
                                lambda o, i: ir.Mat4(tuple(column(o, i, k) for k in range(4))), src, arith)


def _texture(ctx, node, out, wb, bb, chunk, row, src, bundle):
    """Weights as rows of the network's weight texture of the layer's format; an i8 layer's codes, with
    its biases and row scales in a float texture beside them."""
    ob, ib = wb.shape[:2]
    tex = emit_plan.weight_texture(ctx, emit_plan.weight_format(ctx, node))
    if tex.fmt != "i8":
        row0 = tex.add(wb, bb, node.id)
        emit_products.emit_loop(ctx, out, ob, ib, chunk, *emit_products.texture_exprs(tex.name, str(row0)), src,
                                arithmetic(ctx))
        return
    row0 = tex.add(wb, bb, node.id, emit_plan.pack_rows(bundle.tensor(node, "weight_scale"), ob))
    emit_products.emit_loop(ctx, out, ob, ib, chunk, *emit_products.i8_texture_exprs(
        tex.name, str(row0), tex.side_name, ctx.option("dense", "i8_texels")), src, arithmetic(ctx))


# storage -> how a layer stored so is written
_STORED = {"inline": _inline, "ubo": _block, "texture": _texture,
           "ssbo": lambda *args: _block(*args, storage=True)}


def arithmetic(ctx) -> emit_products.Arithmetic:
    """The types the layers' products and sums are computed in (codegen option ``arithmetic``)."""
    return emit_products.ARITHMETICS[ctx.option("dense", "arithmetic")]


def check_arithmetic(ctx, bundle) -> None:
    """fp16 arithmetic: a target that has it, and float16 weights (none rounded on the way in)."""
    chosen = ctx.option("dense", "arithmetic")
    if chosen == "f32":
        return
    printer = find_target(ctx.target).printer
    if printer.half is None:
        have = ", ".join(name for name, t in TARGETS.items() if t.printer.half is not None)
        raise TargetError(f"arithmetic {chosen}: target {ctx.target} has no float16 arithmetic here; targets "
                          f"with it: {have}")
    for n in bundle.nodes:
        if n.type == "dense" and n.params.get("precision", "f32") != "f16":
            raise TargetError(f"node {n.id}: arithmetic {chosen} computes with float16 weights: store the layer at "
                              f"precision f16 (inshade.quantize, --precision f16), not "
                              f"{n.params.get('precision', 'f32')}")


@emitter("dense", options={"storage": (STORAGE_MODES, "auto"), "texture_format": (TEXTURE_FORMATS, "f4"),
                           "arithmetic": (ARITHMETIC, "f32"), "i8_texels": (tuple(I8_TEXELS), "uint")},
         lowered=True)
def emit_dense(ctx, node, src, bundle):
    weight = bundle.tensor(node, "weight")
    bias = bundle.tensor(node, "bias") if node.params["bias"] else None
    wb, bb = emit_plan.pack(weight, bias)
    ob, ib = wb.shape[:2]
    mode, why = ctx.storage[node.id]
    chunk, unrolled = ctx.loop_chunks.get(node.id, (1, ""))
    why += unrolled
    spare = emit_products.loop_spare(ob, ib, chunk) if emit_plan.looped(mode, ob, ib) else 0
    out = declare(ctx, f"v_{node.id}", node.out_dim, spare=spare)
    ctx.body.append(ir.Comment(f"{node.id}: dense {node.in_dim} -> {node.out_dim} ({ob}x{ib} mat4 blocks, {mode})"))
    row = emit_products.dense_row(ctx, node, weight, bias, mode, why)
    if mode not in _STORED:
        raise ValueError(f"unknown weight storage {mode!r} (choose from {', '.join(STORAGE_MODES)})")
    _STORED[mode](ctx, node, out, wb, bb, chunk, row, src, bundle)
    ctx.plan.append(row)
    return out
