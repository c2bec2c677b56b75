"""WGSL for WebGPU: a standalone module (library chunks pasted in), resources in @group(0) at the
plan's bindings, textures read with textureLoad (no sampler), the eval function taking and
returning arrays of vec4<f32> (WGSL has no out parameters)."""
from __future__ import annotations

from .. import ir
from .base import INDENT, Module, Printer, Unprintable, library_chunk

GROUP = 0   # the group the network's resources are bound in (an evaluation or host shader uses others)


class WGSLPrinter(Printer):
    language = "wgsl"
    types = {"float": "f32", "vec4": "vec4<f32>", "mat4": "mat4x4<f32>", "int": "i32", "uint": "u32",
             "uvec4": "vec4<u32>"}
    builtins = {"roundEven": "round", "inversesqrt": "inverseSqrt"}
    # the library's overloads by argument count (WGSL functions have one signature each)
    overloads = {("inshade_softplus", 3): "inshade_softplus_bt"}

    def _vec4(self, e: ir.Vec4) -> str:
        return f"vec4<f32>({', '.join(self.expr(i) for i in e.items)})"

    def _choose(self, e: ir.Choose) -> str:
        return f"select({self.expr(e.otherwise)}, {self.expr(e.then)}, {self.expr(e.a)} {e.op} {self.expr(e.b)})"

    def _fetch(self, e: ir.Fetch) -> str:
        return f"textureLoad({e.texture}, vec2<i32>({e.x.text}, {e.y.text}), 0)"

    def _call(self, e: ir.Call) -> str:
        name = self.overloads.get((e.fn, len(e.args)), self.builtins.get(e.fn, e.fn))
        if e.fn.startswith("inshade_") and e.type == "float":
            # WGSL has no overloads: the library's functions take vec4s, a lane is one of them
            first, *rest = (self.expr(a) for a in e.args)
            return f"{name}({', '.join([f'vec4<f32>({first})', *rest])}).x"
        # built-ins take arguments of one type: a float goes to every lane
        if e.type == "vec4" and not e.fn.startswith("inshade_"):
            args = [f"vec4<f32>({self.expr(a)})" if isinstance(a, ir.Lit) else self.expr(a) for a in e.args]
            return f"{name}({', '.join(args)})"
        return f"{name}({', '.join(self.expr(a) for a in e.args)})"

    def loop_head(self, s: ir.For) -> str:
        step = f"{s.var}++" if s.step is None else f"{s.var} += {s.step}"
        return f"for (var {s.var}: i32 = {s.start}; {s.var} < {s.stop}; {step}) {{"

    def declaration(self, s: ir.Declare) -> str:
        t = self.types[s.type] if s.count is None else f"array<{self.types[s.type]}, {s.count}>"
        init = "" if s.init is None else f" = {self.expr(s.init)}"
        return f"var {s.name}: {t}{init};"

    def global_(self, g, bindings: dict) -> str:
        if isinstance(g, str):
            raise Unprintable(f"wgsl: GLSL text has no wgsl spelling: {g.splitlines()[0]}")
        if isinstance(g, ir.Comment):
            return f"// {g.text}"
        if isinstance(g, ir.UniformBlock):
            members = "".join(f"    {n}: array<{self.types[t]}, {c}>,\n" for t, n, c in g.members)
            return (f"struct {g.block} {{\n{members}}}\n"
                    f"@group({GROUP}) @binding({bindings[g.block]}) var<uniform> {g.instance}: {g.block};")
        if isinstance(g, ir.Texture2D):
            comment = f"  // {g.comment}" if g.comment else ""
            return f"@group({GROUP}) @binding({bindings[g.name]}) var {g.name}: texture_2d<f32>;{comment}"
        if isinstance(g, ir.ConstArray):
            t = f"array<{self.types[g.type]}, {len(g.items)}>"
            items = ",\n    ".join(self.expr(i) for i in g.items)
            return f"const {g.name}: {t} = {t}(\n    {items});"
        raise TypeError(f"unknown module-level declaration {g!r}")

    def module(self, m: Module) -> str:
        up = m.prefix.upper()
        args = [*([f"xu_in: array<vec4<u32>, {up}_IN_UINT_BLOCKS>"] if m.uint_blocks else []),
                f"x_in: array<vec4<f32>, {up}_IN_BLOCKS>"]
        lines = [
            *m.comments,
            *(f"const {name}: i32 = {value};" for name, value in m.defines),
            *(library_chunk(c, "wgsl") for c in m.includes),
            *(self.global_(g, m.bindings) for g in m.globals),
            f"fn {m.prefix}_eval({', '.join(args)}) -> array<vec4<f32>, {up}_OUT_BLOCKS> {{",
            *([INDENT + "var xu = xu_in;"] if m.uint_blocks else []),
            INDENT + "var x = x_in;",
            *self.lines(m.body, 1),
            INDENT + f"var y: array<vec4<f32>, {up}_OUT_BLOCKS>;",
            *(INDENT + f"y[{b}] = {m.result}[{b}];" for b in range(m.out_blocks)),
            INDENT + "return y;",
            "}",
        ]
        return "\n".join(lines) + "\n"
