"""GLSL: 3.30, 4.50 and ES 3.00 for OpenGL (a chunk the runtime's resolver assembles, library
chunks by ``#include``) and 4.50 for Vulkan (a standalone chunk: library chunks pasted in,
explicit set/binding layout, textures read without a sampler: GL_EXT_samplerless_texture_functions)."""
from __future__ import annotations

from inshade.shaders import flatten

from .. import ir
from .base import INDENT, Module, Printer

# the set the network's resources are bound in (an evaluation or host shader uses others)
VULKAN_SET = 0
SAMPLERLESS = "#extension GL_EXT_samplerless_texture_functions : require"


class GLSLPrinter(Printer):
    language = "glsl"
    types = {"float": "float", "vec4": "vec4", "mat4": "mat4", "int": "int", "uint": "uint", "uvec4": "uvec4"}

    def legacy(self, text: str, depth: int) -> list[str]:
        return [INDENT * depth + line for line in text.split("\n")]

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
            return f"{self.block_layout(g.block, bindings)} uniform {g.block} {{\n{members}}} {g.instance};"
        if isinstance(g, ir.Texture2D):
            return self.texture(g, bindings) + (f"  // {g.comment}" if g.comment else "")
        if isinstance(g, ir.ConstArray):
            t = self.types[g.type]
            items = [self.expr(i) for i in g.items]
            joined = "(\n    " + ",\n    ".join(items) + ")" if g.type == "mat4" else "(" + ", ".join(items) + ")"
            return f"const {t} {g.name}[{len(items)}] = {t}[]{joined};"
        raise TypeError(f"unknown module-level declaration {g!r}")

    def block_layout(self, block: str, bindings: dict) -> str:
        return "layout(std140)"

    def texture(self, g: ir.Texture2D, bindings: dict) -> str:
        return f"uniform sampler2D {g.name};"

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

    def legacy(self, text: str, depth: int) -> list[str]:
        return Printer.legacy(self, text, depth)

    def block_layout(self, block: str, bindings: dict) -> str:
        return f"layout(std140, set = {VULKAN_SET}, binding = {bindings[block]})"

    def texture(self, g: ir.Texture2D, bindings: dict) -> str:
        return f"layout(set = {VULKAN_SET}, binding = {bindings[g.name]}) uniform texture2D {g.name};"

    def global_(self, g, bindings: dict) -> str:
        if isinstance(g, str):
            Printer.legacy(self, g, 0)
        return super().global_(g, bindings)

    def include_lines(self, m: Module) -> list[str]:
        return [flatten(c).rstrip("\n") for c in m.includes]

    def module(self, m: Module) -> str:
        textures = any(isinstance(g, ir.Texture2D) for g in m.globals)
        return (SAMPLERLESS + "\n" if textures else "") + super().module(m)
