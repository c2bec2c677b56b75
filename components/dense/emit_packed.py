"""The dense layer: an f16 or i8 layer's weights in a uniform block or storage buffer at its precision's
bytes (inshade/quantize.py), unpacked with integer operations every target has (no half type, no
packing built-ins: GLSL 3.30 has neither).

- f16: each mat4 block is two uvec4: lane r of the first holds column 0's row r in its low 16 bits and
  column 1's in its high bits, the second columns 2 and 3; lib/packed_weights' ``inshade_half4``
  rebuilds the float32 of each half's value with integer operations.
- i8: each mat4 block is one uvec4: lane r holds the codes of columns 0..3 at row r, a byte each, as
  code + 128; the row scales follow the biases (``vec4 s[OB]``).
Biases stay float32. The values rebuilt are the bundle's float32 weights exactly.
"""
from __future__ import annotations

import numpy as np

from inshade.codegen import ir

from . import emit_plan

def members(precision: str, ob: int, ib: int) -> tuple:
    per_block = {"f16": 2, "i8": 1}[precision]
    scales = (("vec4", "s", ob),) if precision == "i8" else ()
    return (("uvec4", "W", ob * ib * per_block), ("vec4", "b", ob), *scales)


def block_bytes(precision: str, wblocks: np.ndarray, bias: np.ndarray, scale: np.ndarray | None) -> bytes:
    """The block's std140 bytes (std430 the same): W, then b (then s for i8)."""
    cols = np.ascontiguousarray(wblocks.transpose(0, 1, 3, 2))  # [OB, IB, col, row]
    if precision == "f16":
        h = cols.astype(np.float16).view(np.uint16).astype(np.uint32)
        words = np.stack([h[:, :, 0] | (h[:, :, 1] << 16), h[:, :, 2] | (h[:, :, 3] << 16)], 2)   # [OB, IB, 2, 4]
        tail = [bias]
    else:
        s = np.where(scale > 0, scale, 1.0)[:, None, None, :]
        q = (np.rint(cols / s) + emit_plan.I8_OFFSET).astype(np.uint32)   # [OB, IB, col, row]
        words = (q[:, :, 0] | (q[:, :, 1] << 8) | (q[:, :, 2] << 16) | (q[:, :, 3] << 24))[:, :, None]
        tail = [bias, scale]
    return words.astype("<u4").tobytes() + b"".join(np.asarray(t, "<f4").tobytes() for t in tail)


def _u(value: int) -> ir.Vector:
    return ir.Vector("uvec4", (ir.Int(f"{value}u"),) * 4)   # WGSL's bit operations take no scalar with a vector


def columns(ctx, block: ir.Expr, precision: str, o: ir.Int, i: ir.Int, ib: int) -> list:
    """The four columns (vec4) of weight block (o, i) of a packed layer's block (f16: through
    lib/packed_weights' inshade_half4)."""
    if precision == "f16":
        ctx.include("lib/packed_weights")
        word = [ir.Index(ir.Member(block, "W"), ir.Int(f"(({o.text}) * {ib} + {i.text}) * 2 + {m}")) for m in (0, 1)]
        return [ir.Call("inshade_half4", (ir.Bin("&", word[k // 2], _u(0xFFFF)) if k % 2 == 0
                                          else ir.Bin(">>", word[k // 2], _u(16)),)) for k in range(4)]
    word = ir.Index(ir.Member(block, "W"), ir.Int(f"({o.text}) * {ib} + {i.text}"))
    scale = ir.Index(ir.Member(block, "s"), o)
    return [ir.Bin("*", ir.Paren(ir.Bin("-", ir.Convert("vec4", ir.Paren(ir.Bin("&", ir.Paren(ir.Bin(
        ">>", word, _u(8 * k))), _u(0xFF)))), ir.Lit(float(emit_plan.I8_OFFSET)))), scale) for k in range(4)]
