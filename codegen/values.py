"""Values in generated code: a graph value lives in lanes of a `vec4 name[blocks]` array, or of a
`uvec4` array for "uint" bundle inputs (e.g. a triangle id)."""
from __future__ import annotations

from dataclasses import dataclass

from . import ir
from .glsl import EmitContext, blocks, lane


@dataclass(frozen=True)
class Value:
    array: str
    offset: int   # first lane in the array
    dim: int
    kind: str = "float"   # "uint": the array is uvec4 and each lane a uint expression

    def lane(self, i: int) -> str:
        return lane(self.array, self.offset + i)

    def block_ir(self, b: int) -> ir.Index:
        """Block b of the array (lowered code)."""
        return ir.Index(ir.Var(self.array), b)

    def lane_ir(self, i: int) -> ir.Lane:
        """Lane i of the value (lowered code)."""
        j = self.offset + i
        return ir.Lane(ir.Index(ir.Var(self.array), j // 4), j % 4)

    @property
    def aligned(self) -> bool:
        return self.offset == 0


def gather(ctx: EmitContext, name: str, sources: list[Value]) -> Value:
    """The concatenation of sources as one lane-0-aligned float array; copies only when needed.
    uint lanes become floats (exact below 2^24, as torch carries them)."""
    if len(sources) == 1 and sources[0].aligned and sources[0].kind == "float":
        return sources[0]
    dim = sum(s.dim for s in sources)
    ctx.body.append(ir.Declare("vec4", name, blocks(dim)))
    out = Value(name, 0, dim)
    k = 0
    for s in sources:
        i = 0
        while i < s.dim:
            # whole vec4 copies when both sides are block-aligned, lanes otherwise
            if (k % 4 == 0) and ((s.offset + i) % 4 == 0) and s.dim - i >= 4:
                block = s.block_ir((s.offset + i) // 4)
                ctx.body.append(ir.Assign(out.block_ir(k // 4), block if s.kind == "float" else ir.Convert("vec4", block)))
                i += 4
                k += 4
            else:
                lane = s.lane_ir(i)
                ctx.body.append(ir.Assign(out.lane_ir(k), lane if s.kind == "float" else ir.Convert("float", lane)))
                i += 1
                k += 1
    for j in range(k, blocks(dim) * 4):  # zero the padding lanes: dense layers read them
        ctx.body.append(ir.Assign(out.lane_ir(j), ir.Lit(0.0)))
    return out


def declare(ctx: EmitContext, name: str, dim: int, spare: int = 0) -> Value:
    """A new array; a partly used last block starts at zero so padding lanes are defined. ``spare``
    blocks past the value: a loop that writes the array must not iterate exactly its length, or
    Mesa's NIR unrolls it whatever its size (a loop over a whole array is unrolled to drop the indexing)."""
    ctx.body.append(ir.Declare("vec4", name, blocks(dim) + spare))
    if dim % 4:
        ctx.body.append(ir.Assign(ir.Index(ir.Var(name), blocks(dim) - 1), ir.Vec4.splat(0.0)))
    return Value(name, 0, dim)


def swizzle(v: Value, n: int) -> ir.Expr:
    """The first n lanes of v as one float / vecN expression (n <= 4)."""
    if v.offset % 4 == 0:
        block = v.block_ir(v.offset // 4)
        return block if n == 4 else ir.Swizzle(block, "xyzw"[:n])
    lanes = tuple(v.lane_ir(i) for i in range(n))
    return lanes[0] if n == 1 else ir.Vector(f"vec{n}", lanes)
