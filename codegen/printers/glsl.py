"""GLSL: 3.30, 4.50 and ES 3.00 for OpenGL (a chunk the runtime's resolver assembles, library
chunks by ``#include``) and 4.50 for Vulkan (a standalone chunk: library chunks pasted in,
explicit set/binding layout, textures read without a sampler (GL_EXT_samplerless_texture_functions)
or, filtered, through a sampler of their own)."""
from __future__ import annotations

from .. import ir
from .base import INDENT, SAMPLER_SUFFIX, Module, Printer, library_source

# the set the network's resources are bound in (an evaluation or host shader uses others)
VULKAN_SET = 0
SAMPLERLESS = "#extension GL_EXT_samplerless_texture_functions : require"


class GLSLPrinter(Printer):
    language = "glsl"
    types = {t: t for t in ("float", "vec2", "vec3", "vec4", "mat4", "int", "ivec2", "ivec3", "ivec4", "uint",
                            "uvec3", "uvec4", "bool")}

    def legacy(self, text: str, depth: int) -> list[str]:
        return [INDENT * depth + line for line in text.split("\n")]

    def _texturearg(self, e: ir.TextureArg) -> str:
        return e.name   # a sampler2D/sampler3D: the texture with its filtering

    def _fetch(self, e: ir.Fetch) -> str:
        return f"texelFetch({e.texture}, ivec2({e.x.text}, {e.y.text}), 0)"

    # --- module level ---
    def global_(self, g, bindings: dict) -> str:
        if isinstance(g, str):
            return g
        if isinstance(g, ir.Comment):
            return f"// {g.text}"
        if isinstance(g, ir.UniformBlock):
            members = "".join(f"    {self.types[t]} {n}[{c}];\n" for t, n, c in g.members)
            kind = "readonly buffer" if g.storage else "uniform"
            return f"{self.block_layout(g, bindings)} {kind} {g.block} {{\n{members}}} {g.instance};"
        if isinstance(g, ir.Texture):
            return self.texture(g, bindings) + (f"  // {g.comment}" if g.comment else "") + self.sampler(g, bindings)
        if isinstance(g, (ir.Constant, ir.Function)):
            return self.definition(g)
        if isinstance(g, ir.ConstArray):
            t = self.types[g.type]
            items = [self.expr(i) for i in g.items]
            joined = "(\n    " + ",\n    ".join(items) + ")" if g.type == "mat4" else "(" + ", ".join(items) + ")"
            return f"const {t} {g.name}[{len(items)}] = {t}[]{joined};"
        raise TypeError(f"unknown module-level declaration {g!r}")

    def block_layout(self, g: ir.UniformBlock, bindings: dict) -> str:
        return f"layout({'std430' if g.storage else 'std140'})"

    def texture(self, g: ir.Texture, bindings: dict) -> str:
        return f"uniform {'u' * g.integer}sampler{g.dims}D {g.name};"

    def sampler(self, g: ir.Texture, bindings: dict) -> str:
        """A filtered texture's sampler, on a line of its own ("" where the sampler is the texture's)."""
        return ""

    def include_lines(self, m: Module) -> list[str]:
        return [f"#include <{c}>" for c in m.includes]

    def signature(self, m: Module) -> str:
        up = m.prefix.upper()
        uint_arg = f"in uvec4 xu[{up}_IN_UINT_BLOCKS], " if m.uint_blocks else ""
        return f"void {m.prefix}_eval({uint_arg}in vec4 x[{up}_IN_BLOCKS], out vec4 y[{up}_OUT_BLOCKS]) {{"

    def module(self, m: Module) -> str:
        lines = [
            *m.comments,
            *self.include_lines(m),
            *(f"#define {name} {value}" for name, value in m.defines),
            *(self.global_(g, m.bindings) for g in m.globals),
            self.signature(m),
            *self.lines(m.body, 1),
            *(f"    y[{b}] = {m.result}[{b}];" for b in range(m.out_blocks)),
            "}",
        ]
        return "\n".join(lines) + "\n"


class VulkanGLSLPrinter(GLSLPrinter):
    language = "vulkan"
    half = "#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require"
    types = {**GLSLPrinter.types, "f16vec4": "f16vec4", "f16mat4": "f16mat4"}

    def legacy(self, text: str, depth: int) -> list[str]:
        return Printer.legacy(self, text, depth)

    def block_layout(self, g: ir.UniformBlock, bindings: dict) -> str:
        return f"layout({'std430' if g.storage else 'std140'}, set = {VULKAN_SET}, binding = {bindings[g.block]})"

    def _texturearg(self, e: ir.TextureArg) -> str:
        return Printer._texturearg(self, e)

    def texture(self, g: ir.Texture, bindings: dict) -> str:
        return f"layout(set = {VULKAN_SET}, binding = {bindings[g.name]}) uniform {'u' * g.integer}texture{g.dims}D {g.name};"

    def sampler(self, g: ir.Texture, bindings: dict) -> str:
        name = g.name + SAMPLER_SUFFIX
        return f"\nlayout(set = {VULKAN_SET}, binding = {bindings[name]}) uniform sampler {name};" if g.filtered else ""

    def global_(self, g, bindings: dict) -> str:
        if isinstance(g, str):
            Printer.legacy(self, g, 0)
        return super().global_(g, bindings)

    def include_lines(self, m: Module) -> list[str]:
        return library_source(m.includes, (".vulkan.glsl", ".glsl"), guard=True)

    def module(self, m: Module) -> str:
        textures = any(isinstance(g, ir.Texture) for g in m.globals)
        enabled = [self.half] if "f16" in m.enables else []
        return "".join(line + "\n" for line in [*enabled, *([SAMPLERLESS] if textures else [])]) + super().module(m)
