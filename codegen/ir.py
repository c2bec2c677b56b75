"""The lowered form of a network's code: what an emitter says, before a printer spells it in one
shading language (GLSL for OpenGL and Vulkan, WGSL, HLSL, Slang).

An emitter builds statements out of these nodes; a printer (codegen/printers/) turns them into
text. The node set is what the mat4-block code of a network needs -- 4-lane blocks, mat4 blocks,
integer index arithmetic, texel reads, uniform-block members, loops -- and nothing a language
would have to imitate. Integer index expressions (``Int``) are written once, in the C-like syntax
every target shares (``(o + 1) * 3 + i``).

Types are named by their GLSL spelling (``float``, ``vec4``, ``mat4``, ``int``, ``uint``, ``uvec4``);
each printer maps them.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Union


# --- expressions -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class Lit:
    """A float32 literal; ``text``: its decimal spelling where a formula writes one (``0.99``), which
    every target reads as the same float32, instead of the round-trip spelling (``%.9g``)."""
    value: float
    text: str = ""


@dataclass(frozen=True)
class Int:
    """An integer expression in the syntax every target shares: a literal, a loop variable, + and *."""
    text: str


@dataclass(frozen=True)
class Var:
    name: str


@dataclass(frozen=True)
class Index:
    base: "Expr"
    index: Union["Expr", int]


@dataclass(frozen=True)
class Lane:
    """One lane (0..3) of a vec4."""
    base: "Expr"
    lane: int


@dataclass(frozen=True)
class Member:
    """A member of a uniform block (``block.W``)."""
    base: "Expr"
    name: str


@dataclass(frozen=True)
class Swizzle:
    """Some lanes of a vector, in order (``lanes`` "xy", "xyz"): spelled the same in every target."""
    base: "Expr"
    lanes: str


@dataclass(frozen=True)
class Vector:
    """A vector of another type than vec4 (``vec2``, ``vec3``, ``ivec2``..``ivec4``, ``uvec3``) from
    one item per lane."""
    type: str
    items: tuple


@dataclass(frozen=True)
class Bool:
    value: bool


@dataclass(frozen=True)
class TextureArg:
    """A texture handed to a library function; a filtered one comes with its sampler in languages
    that keep samplers apart from textures (``t, t_sampler``)."""
    name: str
    filtered: bool = False


@dataclass(frozen=True)
class Vec4:
    """A vec4 from four float expressions, or one repeated (``splat``)."""
    items: tuple

    @staticmethod
    def of(values) -> "Vec4":
        return Vec4(tuple(Lit(float(v)) for v in values))

    @staticmethod
    def splat(value: float) -> "Vec4":
        return Vec4((Lit(float(value)),))


@dataclass(frozen=True)
class Mat4:
    """A mat4 from its four columns (vec4 expressions) or its 16 column-major float literals."""
    items: tuple


@dataclass(frozen=True)
class Bin:
    """``a op b`` for + - * / of floats and vec4s (a float with a vec4 applies to every lane), and
    + - * ^ & | << of uints (wrapping modulo 2^32)."""
    op: str
    a: "Expr"
    b: "Expr"


@dataclass(frozen=True)
class MatVec:
    """A mat4 times a vec4 (the matrix's columns weigh the vector's lanes)."""
    m: "Expr"
    v: "Expr"


@dataclass(frozen=True)
class Sum:
    """``a + b + c ...`` summed left to right."""
    terms: tuple


@dataclass(frozen=True)
class Paren:
    e: "Expr"


@dataclass(frozen=True)
class Choose:
    """``then`` where ``a op b`` (op: < <= > >=) holds, else ``otherwise``: floats."""
    op: str
    a: "Expr"
    b: "Expr"
    then: "Expr"
    otherwise: "Expr"


@dataclass(frozen=True)
class Call:
    """A built-in (by its GLSL name: max, min, clamp, exp, abs, sqrt, sin, cos, trunc, ...) or a
    library function (``inshade_*``); ``type`` is the result's, for printers that name overloads."""
    fn: str
    args: tuple
    type: str = "vec4"


@dataclass(frozen=True)
class Convert:
    """A value converted to another type (``float(u)``, ``vec4(uvec4)``)."""
    type: str
    e: "Expr"


@dataclass(frozen=True)
class Out:
    """A variable handed to a function that writes it (an ``out`` parameter; WGSL passes ``&name``)."""
    var: Var


@dataclass(frozen=True)
class Fetch:
    """The texel at integer (x, y) of level 0 of a 2D float texture, exactly (no filtering)."""
    texture: str
    x: Int
    y: Int


Expr = Union[Lit, Int, Var, Index, Lane, Member, Swizzle, Vector, Bool, TextureArg, Vec4, Mat4, MatVec, Bin, Sum, Paren, Choose, Call, Convert, Fetch, Out]


# --- statements ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Declare:
    """``type name`` (``[count]`` for an array), with an initial value or none."""
    type: str
    name: str
    count: int | None = None
    init: Expr | None = None


@dataclass(frozen=True)
class Assign:
    """``target = value`` (``op`` "=") or ``target += value`` (``op`` "+=")."""
    target: Expr
    value: Expr
    op: str = "="


@dataclass(frozen=True)
class For:
    """``for (int var = start; var < stop; var += step)`` over ``body``; ``step`` None counts by one
    (``++var``)."""
    var: str
    start: int
    stop: int
    step: int | None
    body: tuple


@dataclass(frozen=True)
class Scope:
    """A braced block of statements."""
    body: tuple


@dataclass(frozen=True)
class Comment:
    text: str


@dataclass(frozen=True)
class Group:
    """Statements that belong together (one layer's output block): printed as consecutive lines, or
    on one line (``one_line``: declarations that read as one, ``uvec3 c; uvec3 e;``)."""
    body: tuple
    one_line: bool = False


@dataclass(frozen=True)
class Do:
    """A call made for what it writes to its ``Out`` arguments (``f(x, y);``)."""
    call: Call


@dataclass(frozen=True)
class Return:
    """``return value;`` (the last statement of a Function)."""
    value: Expr


Stmt = Union[Declare, Assign, For, Scope, Comment, Group, Do, Return]


# --- module-level declarations -----------------------------------------------------------------------

@dataclass(frozen=True)
class UniformBlock:
    """A std140 uniform block of arrays: ``members`` = ((type, name, count), ...); ``instance`` is how the
    code refers to it (``Member(Var(instance), name)``)."""
    block: str
    instance: str
    members: tuple
    comment: str = ""
    storage: bool = False     # a read-only storage buffer (std430) rather than a uniform block


@dataclass(frozen=True)
class Texture:
    """A float texture of ``dims`` 2 or 3, read texel by texel (``Fetch``, or a library function);
    ``filtered``: also read with hardware filtering, through a sampler of its own
    (``<name>_sampler``) in languages that keep samplers apart; ``integer``: its texels are uints
    (read texel by texel only)."""
    name: str
    comment: str = ""
    dims: int = 2
    filtered: bool = False
    integer: bool = False


@dataclass(frozen=True)
class ConstArray:
    """A constant array of literals (``const mat4 W[n] = ...``): items are Mat4 / Vec4 of literals."""
    type: str
    name: str
    items: tuple
    comment: str = ""


@dataclass(frozen=True)
class Constant:
    """A named integer the code and its caller read (``#define NAME value`` in the C family, ``const``
    in WGSL)."""
    name: str
    value: int


@dataclass(frozen=True)
class Function:
    """A function the caller may call too: ``type name(params) { body }``; ``params`` = ((type,
    name), ...); the body ends with a Return."""
    type: str
    name: str
    params: tuple
    body: tuple


Global = Union[UniformBlock, Texture, ConstArray, Comment, Constant, Function]
