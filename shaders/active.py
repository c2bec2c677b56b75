"""The text a GLSL preprocessor keeps of an assembled source: the lines of the ``#if`` branches its
macros select (``#if`` / ``#ifdef`` / ``#ifndef`` / ``#elif`` / ``#else`` / ``#endif``, object-like
``#define`` / ``#undef``; ``#if`` expressions of integers, macros, ``defined``, comparisons, arithmetic
and ``&&`` ``||`` ``!``). What the driver will compile, known without a driver: a program that picks
one of several networks by a define calls only that one (runtime/compile_cost.py).
"""
from __future__ import annotations

import re

_TOKEN = re.compile(r"\s*(defined\s*\(\s*\w+\s*\)|defined\s+\w+|0[xX][0-9a-fA-F]+[uU]?|\d+[uU]?|\w+|&&|\|\||==|!="
                    r"|<=|>=|<<|>>|[<>!()+\-*/%&|^~])")
_PYTHON = {"&&": " and ", "||": " or ", "!": " not ", "/": "//"}
_DEPTH = 16   # macros naming macros, at most this deep


class Unevaluable(ValueError):
    """An #if expression this evaluator does not read (a function-like macro, a float)."""


def evaluate(expr: str, macros: dict, depth: int = 0) -> int:
    """The value of a preprocessor expression with ``macros`` (name -> replacement text) defined."""
    if depth > _DEPTH:
        raise Unevaluable(f"macros nested past {_DEPTH}: {expr!r}")
    expr = expr.split("//")[0].strip()
    if re.search(r"\b\w+\s*\(", re.sub(r"\bdefined\s*\(\s*\w+\s*\)", "", expr)):
        raise Unevaluable(f"#if {expr!r}: a function-like macro")
    out, pos = [], 0
    for m in _TOKEN.finditer(expr):
        if m.start() != pos:
            break
        pos, t = m.end(), m.group(1)
        if t.startswith("defined"):
            out.append("1" if re.findall(r"\w+", t)[1] in macros else "0")
        elif t[0].isdigit():
            digits = t.rstrip("uU")
            out.append(str(int(digits, 16 if digits[:2] in ("0x", "0X") else 10)))
        elif t[0].isalpha() or t[0] == "_":
            value = macros.get(t)
            out.append(f"({evaluate(value, macros, depth + 1)})" if value and value.strip() else "0")
        else:
            out.append(_PYTHON.get(t, t))
    if pos != len(expr) or not out:
        raise Unevaluable(f"#if {expr!r}")
    try:
        return int(eval("".join(out), {"__builtins__": {}}, {}))   # digits, operators, and/or/not only
    except (SyntaxError, ZeroDivisionError, TypeError) as exc:
        raise Unevaluable(f"#if {expr!r}: {exc}") from None


def _directive(line: str) -> tuple[str, str]:
    body = line.strip()[1:].strip()
    word = re.match(r"\w*", body).group(0)
    return word, body[len(word):].strip()


def active_source(source: str) -> tuple[str, dict]:
    """The lines of ``source`` its preprocessor keeps (directives dropped), and the object-like macros
    defined there. Raises Unevaluable on an #if it does not read."""
    macros: dict[str, str] = {}
    stack: list[tuple[bool, bool]] = []   # per open #if: (the enclosing branch is active, a branch was taken)
    active, out = True, []
    for line in source.splitlines():
        if not line.lstrip().startswith("#"):
            if active:
                out.append(line)
            continue
        word, rest = _directive(line)
        if word in ("if", "ifdef", "ifndef"):
            cond = active and (evaluate(rest, macros) != 0 if word == "if" else (rest.split()[0] in macros) == (
                word == "ifdef"))
            stack.append((active, cond))
            active = cond
        elif word == "elif":
            parent, taken = stack[-1]
            active = parent and not taken and evaluate(rest, macros) != 0
            stack[-1] = (parent, taken or active)
        elif word == "else":
            parent, taken = stack[-1]
            active = parent and not taken
            stack[-1] = (parent, True)
        elif word == "endif":
            active = stack.pop()[0]
        elif active and word == "define":
            name = re.match(r"\w+", rest).group(0)
            if rest[len(name):].startswith("("):
                raise Unevaluable(f"function-like macro {name}")
            macros[name] = rest[len(name):].strip()
        elif active and word == "undef":
            macros.pop(rest.split()[0], None)
    return "\n".join(out), macros


def called(source: str, functions) -> set[str]:
    """Which of ``functions`` the branches ``source``'s preprocessor keeps call, by name or through an
    object-like macro that names one (``#define NET_EVAL transfer_eval``). Raises Unevaluable as
    active_source does."""
    text, macros = active_source(source)

    def target(name: str) -> str:
        for _ in range(_DEPTH):
            if macros.get(name, "").strip() in ("", name):
                return name
            name = macros[name].strip()
        return name
    names = {f: [f, *(m for m in macros if target(m) == f)] for f in functions}
    return {f for f, spelled in names.items() if any(calls(text, n) > 0 for n in spelled)}


def calls(source: str, function: str) -> int:
    """How many times ``source`` calls ``function`` (its definitions and declarations not counted)."""
    every = re.findall(rf"\b{function}\s*\(", source)
    defined = [m for m in re.finditer(rf"\b(\w+)\s+{function}\s*\(", source) if m.group(1) != "return"]
    return len(every) - len(defined)
