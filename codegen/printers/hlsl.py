"""HLSL (Shader Model 5.0 and 6.x: D3D11/12, Unity, Unreal) and Slang.

Matrices are made row by row in HLSL, so a mat4 built from the network's columns is the transpose
of GLSL's: the product is written ``mul(v, M)``, and uniform-block matrices are declared
``row_major`` so the same std140 bytes read the same way. Resources carry both a D3D register
(t# for textures, b# for constant buffers, in plan order) and a Vulkan binding
(``[[vk::binding(n, 0)]]``) so one source serves D3D and SPIR-V compilers alike. Textures are read
with ``Load`` (no sampler). ``HLSLPrinter(textures_as_arguments=True)`` declares none: the eval function
takes each texture (and a filtered one's sampler) as an argument, as an engine's node passes what it
binds."""
from __future__ import annotations

from .. import ir
from .base import INDENT, SAMPLER_SUFFIX, Module, Printer, Unprintable, library_source

SPACE = 0   # the Vulkan set / D3D space of the network's resources


class HLSLPrinter(Printer):
    language = "hlsl"
    # float16 arithmetic is Slang's here: HLSL's `half` is 16-bit only under DXC's -enable-16bit-types, which
    # this machine cannot check (glslang's HLSL front end has no mul() of half matrices)
    half = None
    types = {"float": "float", "vec2": "float2", "vec3": "float3", "vec4": "float4", "mat4": "float4x4", "int": "int",
             "ivec2": "int2", "ivec3": "int3", "ivec4": "int4", "uint": "uint", "uvec3": "uint3", "uvec4": "uint4",
             "bool": "bool", "f16vec4": "half4", "f16mat4": "half4x4"}
    builtins = {"roundEven": "round", "inversesqrt": "rsqrt", "fract": "frac", "mix": "lerp", "uintBitsToFloat": "asfloat"}

    def __init__(self, textures_as_arguments: bool = False):
        self.textures_as_arguments = textures_as_arguments

    def _vec4(self, e: ir.Vec4) -> str:
        if len(e.items) == 1:   # HLSL constructors take every lane; a cast repeats one
            return f"((float4){self.expr(e.items[0])})"
        return f"float4({', '.join(self.expr(i) for i in e.items)})"

    def _matvec(self, e: ir.MatVec) -> str:
        return f"mul({self.expr(e.v)}, {self.expr(e.m)})"

    def _convert(self, e: ir.Convert) -> str:
        return f"(({self.types[e.type]}){self.expr(e.e)})"

    def _fetch(self, e: ir.Fetch) -> str:
        return f"{e.texture}.Load(int3({e.x.text}, {e.y.text}, 0))"

    def global_(self, g, bindings: dict, registers: dict) -> str:
        if isinstance(g, str):
            raise Unprintable(f"{self.language}: GLSL text has no {self.language} spelling: {g.splitlines()[0]}")
        if isinstance(g, ir.Comment):
            return f"// {g.text}"
        if isinstance(g, ir.UniformBlock):
            members = "".join(f"    {'row_major ' if t == 'mat4' else ''}{self.types[t]} {n}[{c}];\n"
                              for t, n, c in g.members)
            head = f"struct {g.block}_data {{\n{members}}};\n[[vk::binding({bindings[g.block]}, {SPACE})]]\n"
            if g.storage:   # a structured buffer of one element, which the code names as it would a block
                return (head + f"StructuredBuffer<{g.block}_data> {g.instance}_buffer : "
                        f"register(t{registers[g.block]}, space{SPACE});\n#define {g.instance} {g.instance}_buffer[0]")
            return head + self.constant_buffer(g, f"register(b{registers[g.block]}, space{SPACE})")
        if isinstance(g, ir.Texture):
            comment = f"  // {g.comment}" if g.comment else ""
            text = (f"[[vk::binding({bindings[g.name]}, {SPACE})]] "
                    f"Texture{g.dims}D<{'uint4' if g.integer else 'float4'}> {g.name} : register(t{registers[g.name]}, space{SPACE});{comment}")
            if g.filtered:
                name = g.name + SAMPLER_SUFFIX
                text += (f"\n[[vk::binding({bindings[name]}, {SPACE})]] "
                         f"SamplerState {name} : register(s{registers[name]}, space{SPACE});")
            return text
        if isinstance(g, (ir.Constant, ir.Function)):
            return self.definition(g)
        if isinstance(g, ir.ConstArray):
            items = ",\n    ".join(self.expr(i) for i in g.items)
            return f"static const {self.types[g.type]} {g.name}[{len(g.items)}] = {{\n    {items}}};"
        raise TypeError(f"unknown module-level declaration {g!r}")

    visibility = ""   # Slang: "public " (what an importing module may call)

    def texture_arguments(self, m: Module) -> list[str]:
        """The eval function's texture parameters (each texture, then a filtered one's sampler), in plan
        order; a network reading a uniform or storage block cannot take it so."""
        blocks = [g.block for g in m.globals if isinstance(g, ir.UniformBlock)]
        if blocks:
            raise Unprintable(f"{self.language}: {', '.join(blocks)}: a block is not a function argument; "
                              "store the weights in textures")
        out = []
        for g in sorted((g for g in m.globals if isinstance(g, ir.Texture)), key=lambda g: m.bindings[g.name]):
            out.append(f"Texture{g.dims}D<{'uint4' if g.integer else 'float4'}> {g.name}")
            out += [f"SamplerState {g.name}{SAMPLER_SUFFIX}"] if g.filtered else []
        return out

    def texture_declarations(self, m: Module) -> list[str]:
        """The module-level declarations of the textures (and samplers) ``texture_arguments`` takes."""
        registers = self.registers(m)
        return [self.global_(g, m.bindings, registers) for g in m.globals if isinstance(g, ir.Texture)]

    @staticmethod
    def registers(m: Module) -> dict:
        """Each resource's D3D register, counted per class in plan order: constant buffers b0..,
        textures and structured buffers t0.., samplers s0.."""
        classes = {"b": [], "t": [], "s": []}
        for g in m.globals:
            if isinstance(g, ir.UniformBlock):
                classes["t" if g.storage else "b"].append(g.block)
            elif isinstance(g, ir.Texture):
                classes["t"].append(g.name)
                classes["s"] += [g.name + SAMPLER_SUFFIX] if g.filtered else []
        return {n: i for names in classes.values() for i, n in enumerate(sorted(names, key=m.bindings.__getitem__))}

    def function_head(self, g: ir.Function) -> str:
        return self.visibility + super().function_head(g)

    def constant_buffer(self, g: ir.UniformBlock, register: str) -> str:
        """The block's declaration: a cbuffer holding one struct (Shader Model 5.0 has no ConstantBuffer<>)."""
        return f"cbuffer {g.block} : {register} {{ {g.block}_data {g.instance}; }};"

    def module(self, m: Module) -> str:
        up = m.prefix.upper()
        registers = self.registers(m)
        uint_arg = f"in uint4 xu[{up}_IN_UINT_BLOCKS], " if m.uint_blocks else ""
        arguments = self.texture_arguments(m) if self.textures_as_arguments else []
        declared = [g for g in m.globals if not (arguments and isinstance(g, ir.Texture))]
        lines = [
            *([self.half] if "f16" in m.enables else []),
            *m.comments,
            *(f"#define {name} {value}" for name, value in m.defines),
            *library_source(m.includes, (".hlsl",), guard=True),
            *(self.global_(g, m.bindings, registers) for g in declared),
            f"{self.visibility}void {m.prefix}_eval({uint_arg}in float4 x[{up}_IN_BLOCKS], "
            f"out float4 y[{up}_OUT_BLOCKS]{''.join(', ' + a for a in arguments)}) {{",
            *self.lines(m.body, 1),
            *(INDENT + f"y[{b}] = {m.result}[{b}];" for b in range(m.out_blocks)),
            "}",
        ]
        return "\n".join(lines) + "\n"


class SlangPrinter(HLSLPrinter):
    """Slang reads HLSL; the module is what a Slang program imports (``import net;``)."""
    language = "slang"
    visibility = "public "
    half = "// float16 arithmetic (half): SPIR-V Float16 (Vulkan shaderFloat16), D3D Shader Model 6.2+"

    def constant_buffer(self, g: ir.UniformBlock, register: str) -> str:
        return f"ConstantBuffer<{g.block}_data> {g.instance} : {register};"
