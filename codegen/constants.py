"""Named constants of a generated chunk in its shading language: ``#define NAME value`` in GLSL,
``const NAME: type = value;`` in WGSL, each value a float32 literal that round-trips."""
from __future__ import annotations

from .glsl import flt

WGSL_TYPES = {"vec3": "vec3<f32>", "float": "f32", "int": "i32"}


def literal(kind: str, v, language: str = "glsl") -> str:
    """``v`` as a ``kind`` (vec3, float, int) literal."""
    if kind == "vec3":
        return f"{WGSL_TYPES[kind] if language == 'wgsl' else kind}({', '.join(flt(x) for x in v)})"
    if kind == "int":
        return f"{int(v)}i" if language == "wgsl" else str(int(v))
    return flt(v)


def constant_lines(values, language: str = "glsl") -> list[str]:
    """One line per (name, kind, value) of ``values``."""
    if language == "wgsl":
        return [f"const {name}: {WGSL_TYPES[kind]} = {literal(kind, v, language)};" for name, kind, v in values]
    return [f"#define {name} {literal(kind, v, language)}" for name, kind, v in values]
