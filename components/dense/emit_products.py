"""The dense layer: the lowered code of one layer's mat4 block products -- unrolled into partial sums, or a loop
over output blocks (and over input blocks beyond what is written out) -- and its plan row. emit.py says
why the code has this shape.
"""
from __future__ import annotations

from dataclasses import dataclass

from inshade.codegen import ir
from inshade.codegen.glsl import PlanRow, blocks

# as a module: any module of this folder may be the first to import inshade.codegen, which loads emit.py
# (and so this folder's modules) while that one is still loading
from . import emit_plan

SPLIT = 4                    # partial sums per output block (breaks the add dependency chain)
# Looped layers of more mat4 blocks keep their loop over outputs (loop_spare): 64 x 64 (256 blocks)
# and smaller unroll, as a network of many small layers compiles fastest unrolled
KEEP_LOOP_MIN_BLOCKS = 256


@dataclass(frozen=True)
class Arithmetic:
    """The types a layer's products and sums are computed in (``vec4``: float32; ``f16vec4``: float16),
    and the conversions between them and the float32 values around the layer."""
    product: str
    sum: str

    def value(self, e: ir.Expr) -> ir.Expr:
        """An input block or weight column as the products take it."""
        return e if self.product == "vec4" else ir.Convert(self.product, e)

    def matrix(self, e: ir.Expr) -> ir.Expr:
        return e if self.product == "vec4" else ir.Convert("f16mat4", e)

    def summand(self, e: ir.Expr) -> ir.Expr:
        """A product as the sums take it."""
        return e if self.sum == self.product else ir.Convert(self.sum, e)

    def start(self, bias: ir.Expr) -> ir.Expr:
        return bias if self.sum == "vec4" else ir.Convert(self.sum, bias)

    def result(self, e: ir.Expr) -> ir.Expr:
        return e if self.sum == "vec4" else ir.Convert("vec4", e)


ARITHMETICS = {"f32": Arithmetic("vec4", "vec4"), "f16": Arithmetic("f16vec4", "f16vec4"),
               "f16_acc32": Arithmetic("f16vec4", "vec4")}
FLOAT32 = ARITHMETICS["f32"]


def half_inputs(ctx, out, src, ib: int, arith: Arithmetic):
    """The input blocks of an unrolled layer as its products take them: float16 copies declared once
    (``h_<out>_<i>``) where the products are float16."""
    if arith.product == "vec4":
        return src.block_ir
    names = [f"h_{out.array}_{i}" for i in range(ib)]
    ctx.body.append(ir.Group(tuple(ir.Declare(arith.product, n, init=arith.value(src.block_ir(i)))
                                   for i, n in enumerate(names))))
    return lambda i: ir.Var(names[i])


def column_terms(i: int, in_dim: int, x: ir.Expr, column) -> list:
    """`x.k * column(k)` for the columns k of input block i that are not padding. Structural,
    not value-based: a UBO's weights may change later, and 0 * inf must stay NaN as in torch."""
    return [ir.Bin("*", ir.Lane(x, k), column(k)) for k in range(4) if 4 * i + k < in_dim]


def emit_unrolled(ctx, out, wb, bias_expr, terms, arith: Arithmetic = FLOAT32):
    """out[o] = bias + sum_i W(o, i) x[i], summed into SPLIT partial accumulators per output
    block (input block i goes to partial i % SPLIT), one output block at a time so only the
    block's accumulators and one input block need registers; the sums in ``arith.sum``."""
    ob, ib = wb.shape[:2]
    for o in range(ob):
        accs, stmts = {}, []
        for i in range(ib):
            ts = [arith.summand(t) for t in terms(o, i)]
            if not ts:
                continue
            p = i % SPLIT
            acc = f"{out.array}_{o}_{p}"
            if p not in accs:
                init = [arith.start(bias_expr(o))] if p == 0 else []
                stmts.append(ir.Declare(arith.sum, acc, init=ir.Sum(tuple(init + ts[:1]))))
                accs[p], ts = acc, ts[1:]
            stmts += [ir.Assign(ir.Var(acc), t, "+=") for t in ts]
        total = ([] if 0 in accs else [arith.start(bias_expr(o))]) + [ir.Var(accs[p]) for p in sorted(accs)]
        stmts.append(ir.Assign(out.block_ir(o), arith.result(ir.Sum(tuple(total)))))
        ctx.body.append(ir.Group(tuple(stmts)))


def loop_statement(out: str, ob, ib, chunk, bias_expr, w_expr, src: str, written: int,
                   arith: Arithmetic = FLOAT32):
    """for o in chunks of output blocks: acc = bias; acc += W(o, i) * x[i] over the inputs, written
    out up to ``written`` blocks (emit_plan.inputs_written_max), a loop beyond; each block's product in
    ``arith.product``, the sums in ``arith.sum``. The output array needs a spare block
    (``declare(spare=1)``) when the loop over outputs runs one block per pass, so that the compiler keeps
    that loop a loop."""
    base = "o" if ob > chunk else "0"

    def at(c):
        return ir.Int(f"{base} + {c}")

    def product(c, i, x):
        return arith.summand(ir.MatVec(arith.matrix(w_expr(at(c), i)), x))
    body = [ir.Declare(arith.sum, f"acc{c}", init=arith.start(bias_expr(at(c)))) for c in range(chunk)]
    if ib > written:
        body.append(ir.For("i", 0, ib, None, (
            ir.Declare(arith.product, "xi", init=arith.value(ir.Index(ir.Var(src), ir.Int("i")))),
            *(ir.Assign(ir.Var(f"acc{c}"), product(c, ir.Int("i"), ir.Var("xi")), "+=") for c in range(chunk)))))
    else:
        body += [ir.Assign(ir.Var(f"acc{c}"), product(c, ir.Int(str(i)), arith.value(ir.Index(ir.Var(src), i))), "+=")
                 for i in range(ib) for c in range(chunk)]
    body += [ir.Assign(ir.Index(ir.Var(out), at(c)), arith.result(ir.Var(f"acc{c}"))) for c in range(chunk)]
    return ir.For("o", 0, ob, chunk, tuple(body)) if ob > chunk else ir.Scope(tuple(body))


def loop_spare(ob: int, ib: int, chunk: int) -> int:
    """Spare output blocks a looped layer declares (see loop_statement): one where the loop over outputs
    runs a block per pass and the layer is big (KEEP_LOOP_MIN_BLOCKS); a small layer's loop is left for
    the compiler to unroll, since llvmpipe's compile time doubles with each loop that follows another."""
    return 1 if ob > chunk and chunk == 1 and ob * ib > KEEP_LOOP_MIN_BLOCKS else 0


def emit_loop(ctx, out, ob, ib, chunk, bias_expr, w_expr, src, arith: Arithmetic = FLOAT32):
    written = emit_plan.inputs_written_max(ctx.limits)
    ctx.body.append(loop_statement(out.array, ob, ib, chunk, bias_expr, w_expr, src.array, written, arith))


def texture_exprs(t: str, row: str):
    """Bias and weight-block expressions of a layer whose rows start at ``row`` in texture t."""
    def bias(o: ir.Int):
        return ir.Fetch(t, ir.Int("0"), ir.Int(f"{row} + {o.text}"))

    def weight(o: ir.Int, i: ir.Int):
        r, c = f"{row} + {o.text}", f"1 + 4 * {i.text}"
        return ir.Mat4(tuple(ir.Fetch(t, ir.Int(f"{c} + {k}"), ir.Int(r)) for k in range(4)))
    return bias, weight


# a fetched i8 texel (codes + 128) -> the codes + 128 as a vec4 of integral floats, by the texels
# (spec.I8_TEXELS): an integer texel converted, or a unorm one times 255 rounded
I8_CODES = {"uint": lambda texel: ir.Convert("vec4", texel),
            "unorm": lambda texel: ir.Call("floor", (ir.Bin("+", ir.Bin("*", texel, ir.Lit(255.0)), ir.Lit(0.5)),))}


def i8_texture_exprs(t: str, row: str, side: str, texels: str = "uint"):
    """(bias, weight-block) expressions of an i8 layer whose rows start at ``row`` in texture t: the bias
    texel 0 of the row in the float texture ``side``; each weight column (its codes + 128, minus 128)
    * the output rows' scales (texel 1 there), the float32 values the bundle holds."""
    def bias(o: ir.Int):
        return ir.Fetch(side, ir.Int("0"), ir.Int(f"{row} + {o.text}"))

    def weight(o: ir.Int, i: ir.Int):
        r, c = f"{row} + {o.text}", f"4 * {i.text}"
        s = ir.Fetch(side, ir.Int("1"), ir.Int(r))

        def column(k):
            code = I8_CODES[texels](ir.Fetch(t, ir.Int(f"{c} + {k}"), ir.Int(r)))
            return ir.Bin("*", ir.Paren(ir.Bin("-", code, ir.Lit(float(emit_plan.I8_OFFSET)))), s)
        return ir.Mat4(tuple(column(k) for k in range(4)))
    return bias, weight


# what a layer at a precision below f32 keeps, by storage (inline literals hold the values as float32)
PRECISION_NOTES = {"f16": {"texture": "float16 rows (RGBA16F)", "block": "float16 pairs in uvec4s",
                           "inline": "float16 values as float32 literals"},
                   "i8": {"texture": "int8 codes (RGBA8UI, or RGBA8 with i8_texels unorm), row scales and biases "
                                      "in RGBA32F",
                          "block": "int8 codes, four to a uint, and row scales",
                          "inline": "int8 codes x row scales as float32 literals"}}


ARITHMETIC_NOTES = {"f16": "float16 products and sums", "f16_acc32": "float16 block products, float32 sums"}


def dense_row(ctx, node, weight, bias, mode: str, why: str) -> PlanRow:
    """A dense layer's plan row; a texture layer's fetches and bytes filled in."""
    precision = node.params.get("precision", "f32")
    arithmetic = ctx.option("dense", "arithmetic")
    if arithmetic in ARITHMETIC_NOTES:
        why += f"; arithmetic {arithmetic}: {ARITHMETIC_NOTES[arithmetic]}"
    if precision in PRECISION_NOTES:
        notes = PRECISION_NOTES[precision]
        why += f"; precision {precision}: {notes['block' if mode in ('ubo', 'ssbo') else mode]}"
    row = PlanRow(node.id, "dense", f"{node.in_dim}->{node.out_dim}", mode, why,
                  params=weight.size + (0 if bias is None else bias.size),
                  flops=2 * node.in_dim * node.out_dim + (node.out_dim if bias is not None else 0))
    if mode == "texture":
        ob, ib = blocks(node.out_dim), blocks(node.in_dim)
        fmt = emit_plan.weight_format(ctx, node)
        texels = ob * (1 + 4 * ib)   # i8: the bias and the scales in a texture of their own, both read
        row.fetches = texels + (ob if fmt == "i8" else 0)
        row.texture_bytes = ob * 4 * ib * {"f4": 16, "f2": 8, "i8": 4}[fmt] + ob * {"f4": 16, "f2": 8, "i8": 32}[fmt]
    return row
