"""Flattened GLSL made compact for pasting (a Shadertoy pass): comments and blank lines dropped, and
the top-level functions nothing reachable from the entry points calls (the unused part of the shared
library chunks). Preprocessor lines and declarations are always kept; every overload of a called
name is kept; a function referenced from a disabled ``#if`` branch is kept too (the text is never
preprocessed here, only pruned).
"""
from __future__ import annotations

import re

_COMMENT = re.compile(r"//[^\n]*|/\*.*?\*/", re.S)
_IDENT = re.compile(r"\b[A-Za-z_]\w*\b")
_FUNCTION_HEAD = re.compile(r"([A-Za-z_]\w*)\s*\($")


def _items(source: str) -> list[tuple[str | None, str]]:
    """Top-level items in order: (function name or None, text). A preprocessor line, a declaration
    ending in ``;`` and a function definition are one item each."""
    items, buf, depth = [], [], 0
    for line in source.splitlines():
        if depth == 0 and line.lstrip().startswith("#"):
            if "".join(buf).strip():
                items.append((None, "\n".join(buf)))
                buf = []
            items.append((None, line))
            continue
        buf.append(line)
        depth += line.count("{") - line.count("}")
        text = "\n".join(buf)
        if depth == 0 and (line.rstrip().endswith("}") or line.rstrip().endswith(";")):
            head = text.split("{", 1)[0] if "{" in text and line.rstrip().endswith("}") else None
            name = None
            if head is not None and "(" in head:
                match = _FUNCTION_HEAD.search(head[:head.index("(") + 1].strip())
                name = match.group(1) if match else None
            items.append((name, text))
            buf = []
    if "".join(buf).strip():
        items.append((None, "\n".join(buf)))
    return items


def compact(source: str, roots: tuple[str, ...]) -> str:
    """``source`` without comments, blank lines and the functions unreachable from ``roots`` (function
    names) or from any kept declaration or preprocessor line."""
    items = _items(_COMMENT.sub("", source))
    functions: dict[str, list[int]] = {}
    for i, (name, _) in enumerate(items):
        if name is not None:
            functions.setdefault(name, []).append(i)
    kept = {i for i, (name, _) in enumerate(items) if name is None}
    todo = [i for r in roots for i in functions.get(r, [])] + sorted(kept)
    kept.update(todo)
    while todo:
        for ident in _IDENT.findall(items[todo.pop()][1]):
            for j in functions.get(ident, ()):
                if j not in kept:
                    kept.add(j)
                    todo.append(j)
    lines = [line.rstrip() for i in sorted(kept) for line in items[i][1].splitlines()]
    return "\n".join(line for line in lines if line.strip()) + "\n"
