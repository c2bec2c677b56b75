"""What every printer shares: walking the lowered statements and expressions (codegen/ir.py).

A language's printer says how it spells types, literals, vectors, matrices, texel reads, calls,
declarations and loops; the walk, the indentation and the sums are the same everywhere.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from inshade.shaders import find_chunk

from .. import ir
from ..glsl import SAMPLER_SUFFIX, flt

INDENT = "    "
_INCLUDE = re.compile(r"^\s*#include\s+<([^>]+)>\s*$")


class Unprintable(ValueError):
    """Code a target's printer cannot spell (a GLSL-only statement from a component without a lowering)."""


def library_guard(name: str) -> str:
    """The include guard of library chunk ``name`` where a language has a preprocessor: two networks in
    one shader (two Unity Custom Function files, two pasted HLSL functions) share its functions
    instead of defining them twice."""
    return "INSHADE_LIB_" + re.sub(r"\W", "_", name).upper()


def library_source(names, suffixes: tuple[str, ...], guard: bool = False) -> list[str]:
    """The library chunks ``names`` in another shading language, pasted into a standalone module:
    each chunk's version with the first of ``suffixes`` it has (``.wgsl``; ``.vulkan.glsl`` before
    ``.glsl``), its ``#include <dep>`` lines replaced by the dependencies (each pasted once, first);
    ``guard``: each within its ``library_guard``."""
    return [text for _, text in library_chunks(names, suffixes, guard)]


def library_chunks(names, suffixes: tuple[str, ...], guard: bool = False) -> list[tuple[str, str]]:
    """(name, text) of each chunk ``library_source`` pastes, in its order."""
    done, out = set(), []

    def paste(name: str) -> None:
        if name in done:
            return
        done.add(name)
        path = next((p for p in (find_chunk(name, suffix=s) for s in suffixes) if p is not None), None)
        if path is None:
            raise Unprintable(f"{suffixes[0][1:]}: the library chunk <{name}> has no version in that language "
                              f"({name}{suffixes[0]})")
        lines = []
        for line in path.read_text().rstrip("\n").split("\n"):
            match = _INCLUDE.match(line)
            if match:
                paste(match.group(1))
            else:
                lines.append(line)
        if guard:
            lines = [f"#ifndef {library_guard(name)}", f"#define {library_guard(name)}", *lines, "#endif"]
        out.append((name, "\n".join(lines)))

    for name in names:
        paste(name)
    return out


@dataclass
class Module:
    """What a printer turns into one source: the network's header lines, its defines, its
    module-level declarations, the library chunks it includes and its eval function."""
    prefix: str
    comments: list[str]
    defines: list[tuple[str, int]]
    includes: list[str]
    globals: list
    body: list
    in_blocks: int
    out_blocks: int
    uint_blocks: int          # 0: the function takes no uint input array
    result: str               # the array holding the outputs
    bindings: dict = field(default_factory=dict)   # resource name -> binding index
    enables: tuple = ()      # language features the code needs ("f16"), enabled at the top of the source


class Printer:
    """The shared walk; subclasses spell each node."""
    language = ""
    types: dict[str, str] = {}
    half: str | None = None   # the line enabling float16 arithmetic (None: the language has none here)
    # built-ins whose name differs from GLSL's
    builtins: dict[str, str] = {}

    # --- expressions ---
    def expr(self, e) -> str:
        return getattr(self, f"_{type(e).__name__.lower()}")(e)

    def _lit(self, e: ir.Lit) -> str:
        return e.text or flt(e.value)

    def _int(self, e: ir.Int) -> str:
        return e.text

    def _var(self, e: ir.Var) -> str:
        return e.name

    def _index(self, e: ir.Index) -> str:
        index = e.index if isinstance(e.index, int) else self.expr(e.index)
        return f"{self.expr(e.base)}[{index}]"

    def _lane(self, e: ir.Lane) -> str:
        return f"{self.expr(e.base)}.{'xyzw'[e.lane]}"

    def _member(self, e: ir.Member) -> str:
        return f"{self.expr(e.base)}.{e.name}"

    def _swizzle(self, e: ir.Swizzle) -> str:
        return f"{self.expr(e.base)}.{e.lanes}"

    def _vector(self, e: ir.Vector) -> str:
        return f"{self.types[e.type]}({', '.join(self.expr(i) for i in e.items)})"

    def _bool(self, e: ir.Bool) -> str:
        return "true" if e.value else "false"

    def _texturearg(self, e: ir.TextureArg) -> str:
        return f"{e.name}, {e.name}{SAMPLER_SUFFIX}" if e.filtered else e.name

    def _sum(self, e: ir.Sum) -> str:
        return " + ".join(self.expr(t) for t in e.terms)

    def _paren(self, e: ir.Paren) -> str:
        return f"({self.expr(e.e)})"

    def _matvec(self, e: ir.MatVec) -> str:
        return f"{self.expr(e.m)} * {self.expr(e.v)}"

    def _bin(self, e: ir.Bin) -> str:
        return f"{self.expr(e.a)} {e.op} {self.expr(e.b)}"

    def _choose(self, e: ir.Choose) -> str:
        return f"{self.expr(e.a)} {e.op} {self.expr(e.b)} ? {self.expr(e.then)} : {self.expr(e.otherwise)}"

    def _call(self, e: ir.Call) -> str:
        return f"{self.builtins.get(e.fn, e.fn)}({', '.join(self.expr(a) for a in e.args)})"

    def _convert(self, e: ir.Convert) -> str:
        return f"{self.types[e.type]}({self.expr(e.e)})"

    def _vec4(self, e: ir.Vec4) -> str:
        return f"{self.types['vec4']}({', '.join(self.expr(i) for i in e.items)})"

    def _mat4(self, e: ir.Mat4) -> str:
        return f"{self.types['mat4']}({', '.join(self.expr(i) for i in e.items)})"

    def _out(self, e: ir.Out) -> str:
        return self.expr(e.var)

    # --- statements ---
    def lines(self, stmts, depth: int = 0) -> list[str]:
        out = []
        for s in stmts:
            if isinstance(s, str):
                out += self.legacy(s, depth)
            else:
                out += getattr(self, f"_s_{type(s).__name__.lower()}")(s, depth)
        return out

    def legacy(self, text: str, depth: int) -> list[str]:
        raise Unprintable(f"{self.language}: GLSL text has no {self.language} spelling: {text.splitlines()[0]}")

    def _s_group(self, s: ir.Group, depth: int) -> list[str]:
        if s.one_line:
            return [INDENT * depth + " ".join(line.strip() for line in self.lines(s.body))]
        return self.lines(s.body, depth)

    def _s_do(self, s: ir.Do, depth: int) -> list[str]:
        return [INDENT * depth + f"{self.expr(s.call)};"]

    def _s_comment(self, s: ir.Comment, depth: int) -> list[str]:
        return [INDENT * depth + f"// {s.text}"]

    def _s_assign(self, s: ir.Assign, depth: int) -> list[str]:
        return [INDENT * depth + f"{self.expr(s.target)} {s.op} {self.expr(s.value)};"]

    def _s_scope(self, s: ir.Scope, depth: int) -> list[str]:
        return [INDENT * depth + "{", *self.lines(s.body, depth + 1), INDENT * depth + "}"]

    def _s_for(self, s: ir.For, depth: int) -> list[str]:
        return [INDENT * depth + self.loop_head(s), *self.lines(s.body, depth + 1), INDENT * depth + "}"]

    def _s_declare(self, s: ir.Declare, depth: int) -> list[str]:
        return [INDENT * depth + self.declaration(s)]

    def _s_return(self, s: ir.Return, depth: int) -> list[str]:
        return [INDENT * depth + f"return {self.expr(s.value)};"]

    # --- module-level definitions the caller reads too ---
    def definition(self, g: ir.Constant | ir.Function) -> str:
        if isinstance(g, ir.Constant):
            return self.constant(g)
        return "\n".join([self.function_head(g), *self.lines(g.body, 1), "}"])

    def constant(self, g: ir.Constant) -> str:
        return f"#define {g.name} {g.value}"

    def function_head(self, g: ir.Function) -> str:
        params = ", ".join(f"{self.types[t]} {n}" for t, n in g.params)
        return f"{self.types[g.type]} {g.name}({params}) {{"

    # --- what each language spells (the C family's spelling by default) ---
    def loop_head(self, s: ir.For) -> str:
        step = f"++{s.var}" if s.step is None else f"{s.var} += {s.step}"
        return f"for (int {s.var} = {s.start}; {s.var} < {s.stop}; {step}) {{"

    def declaration(self, s: ir.Declare) -> str:
        size = "" if s.count is None else f"[{s.count}]"
        init = "" if s.init is None else f" = {self.expr(s.init)}"
        return f"{self.types[s.type]} {s.name}{size}{init};"

    def module(self, m: Module) -> str:
        raise NotImplementedError
