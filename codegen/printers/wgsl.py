"""WGSL for WebGPU: a standalone module (library chunks pasted in), resources in @group(0) at the
plan's bindings, textures read with textureLoad (no sampler), the eval function taking and
returning arrays of vec4<f32> (WGSL has no out parameters).

``WGSLPrinter(textures_as_arguments=True)`` declares no textures: the eval function takes each (and a
filtered one's sampler) as a parameter, as a host that binds its own resources (three.js's ``wgslFn``)
passes them. WGSL has no module-level handles but its own, so every function on the way to the network
takes them too: a library chunk marks where with the slots ``/*net_textures*/`` (in a parameter list)
and ``/*net_texture_names*/`` (in a call), comments that ``thread_textures`` fills and that read as
nothing where the network declares its textures itself."""
from __future__ import annotations

from .. import ir
from .base import INDENT, SAMPLER_SUFFIX, Module, Printer, Unprintable, library_source

GROUP = 0   # the group the network's resources are bound in (an evaluation or host shader uses others)
TEXTURES_SLOT = "/*net_textures*/"              # a parameter list's: the network's textures as parameters
TEXTURE_NAMES_SLOT = "/*net_texture_names*/"    # a call's: the same, passed on


class WGSLPrinter(Printer):
    language = "wgsl"
    half = "enable f16;"
    types = {"float": "f32", "vec2": "vec2<f32>", "vec3": "vec3<f32>", "vec4": "vec4<f32>", "mat4": "mat4x4<f32>",
             "f16vec4": "vec4<f16>", "f16mat4": "mat4x4<f16>",
             "int": "i32", "ivec2": "vec2<i32>", "ivec3": "vec3<i32>", "ivec4": "vec4<i32>", "uint": "u32",
             "uvec3": "vec3<u32>", "uvec4": "vec4<u32>", "bool": "bool"}
    builtins = {"roundEven": "round", "inversesqrt": "inverseSqrt", "uintBitsToFloat": "bitcast<vec4<f32>>"}
    # the library's overloads by argument count (WGSL functions have one signature each)
    overloads = {("inshade_softplus", 3): "inshade_softplus_bt"}
    # library functions of more than one lane (a float call passes each as a vec4)
    lane_args = {"inshade_atan2": 2}

    def __init__(self, textures_as_arguments: bool = False):
        self.textures_as_arguments = textures_as_arguments

    def _vec4(self, e: ir.Vec4) -> str:
        return f"vec4<f32>({', '.join(self.expr(i) for i in e.items)})"

    def _choose(self, e: ir.Choose) -> str:
        return f"select({self.expr(e.otherwise)}, {self.expr(e.then)}, {self.expr(e.a)} {e.op} {self.expr(e.b)})"

    def _fetch(self, e: ir.Fetch) -> str:
        return f"textureLoad({e.texture}, vec2<i32>({e.x.text}, {e.y.text}), 0)"

    def _out(self, e: ir.Out) -> str:
        return f"&{self.expr(e.var)}"     # WGSL passes what a function writes as a pointer

    def _call(self, e: ir.Call) -> str:
        name = self.overloads.get((e.fn, len(e.args)), self.builtins.get(e.fn, e.fn))
        if e.fn.startswith("inshade_") and e.type == "float":
            # WGSL has no overloads: the library's functions take vec4s, a lane is one of them (the
            # first argument, or the first lane_args[fn]; the others are parameters)
            lanes = self.lane_args.get(e.fn, 1)
            args = [f"vec4<f32>({a})" if i < lanes else a for i, a in enumerate(self.expr(a) for a in e.args)]
            return f"{name}({', '.join(args)}).x"
        # built-ins take arguments of one type: a float goes to every lane (GLSL's built-in names have
        # no underscore; a library function's name has one)
        if e.type == "vec4" and "_" not in e.fn:
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

    def constant(self, g: ir.Constant) -> str:
        return f"const {g.name}: i32 = {g.value};"

    def function_head(self, g: ir.Function) -> str:
        params = ", ".join(f"{n}: {self.types[t]}" for t, n in g.params)
        return f"fn {g.name}({params}) -> {self.types[g.type]} {{"

    def global_(self, g, bindings: dict) -> str:
        if isinstance(g, str):
            raise Unprintable(f"wgsl: GLSL text has no wgsl spelling: {g.splitlines()[0]}")
        if isinstance(g, ir.Comment):
            return f"// {g.text}"
        if isinstance(g, ir.UniformBlock):
            members = "".join(f"    {n}: array<{self.types[t]}, {c}>,\n" for t, n, c in g.members)
            return (f"struct {g.block} {{\n{members}}}\n"
                    f"@group({GROUP}) @binding({bindings[g.block]}) var<{'storage, read' if g.storage else 'uniform'}> "
                    f"{g.instance}: {g.block};")
        if isinstance(g, ir.Texture):
            comment = f"  // {g.comment}" if g.comment else ""
            text = f"@group({GROUP}) @binding({bindings[g.name]}) var {g.name}: {texture_type(g)};{comment}"
            if g.filtered:
                name = g.name + SAMPLER_SUFFIX
                text += f"\n@group({GROUP}) @binding({bindings[name]}) var {name}: sampler;"
            return text
        if isinstance(g, (ir.Constant, ir.Function)):
            return self.definition(g)
        if isinstance(g, ir.ConstArray):
            t = f"array<{self.types[g.type]}, {len(g.items)}>"
            items = ",\n    ".join(self.expr(i) for i in g.items)
            return f"const {g.name}: {t} = {t}(\n    {items});"
        raise TypeError(f"unknown module-level declaration {g!r}")

    def texture_parameters(self, m: Module) -> list[tuple[str, str]]:
        """(name, WGSL type) of the eval function's texture parameters (each texture, then a filtered
        one's sampler), in plan order; a network reading a uniform or storage block cannot take it so."""
        blocks = [g.block for g in m.globals if isinstance(g, ir.UniformBlock)]
        if blocks:
            raise Unprintable(f"wgsl: {', '.join(blocks)}: a block is not a function argument; "
                              "store the weights in textures")
        out = []
        for g in sorted((g for g in m.globals if isinstance(g, ir.Texture)), key=lambda g: m.bindings[g.name]):
            out.append((g.name, texture_type(g)))
            out += [(g.name + SAMPLER_SUFFIX, "sampler")] if g.filtered else []
        return out

    def module(self, m: Module) -> str:
        up = m.prefix.upper()
        textures = self.texture_parameters(m) if self.textures_as_arguments else []
        args = [*([f"xu_in: array<vec4<u32>, {up}_IN_UINT_BLOCKS>"] if m.uint_blocks else []),
                f"x_in: array<vec4<f32>, {up}_IN_BLOCKS>", *(f"{n}: {t}" for n, t in textures)]
        lines = [
            *([self.half] if "f16" in m.enables else []),   # before every declaration
            *m.comments,
            *(f"const {name}: i32 = {value};" for name, value in m.defines),
            *library_source(m.includes, (".wgsl",)),
            *(self.global_(g, m.bindings) for g in m.globals if not (textures and isinstance(g, ir.Texture))),
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


def texture_type(g: ir.Texture) -> str:
    return f"texture_{g.dims}d<{'u32' if g.integer else 'f32'}>"


def thread_textures(source: str, parameters: list[tuple[str, str]]) -> str:
    """``source`` with its texture slots filled: ``/*net_textures*/`` becomes ``, name: type, ...`` and
    ``/*net_texture_names*/`` ``, name, ...`` for the network's texture ``parameters``
    (``WGSLPrinter.texture_parameters``)."""
    declared = "".join(f", {n}: {t}" for n, t in parameters)
    return source.replace(TEXTURES_SLOT, declared).replace(TEXTURE_NAMES_SLOT, "".join(f", {n}" for n, _ in parameters))
