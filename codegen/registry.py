"""GLSL emitters, registered under the bundle's component type names, with the codegen options
each component type takes.

An option is declared by the emitter of its component type (``@emitter("dense", options=...)``)
as ``name -> (choices, default)``. ``generate(bundle, options={"dense": {"storage": "ubo"},
"lookup_array": {"filter": "fast"}})`` passes them; an emitter reads ``ctx.option(type, name)``.
A new component type brings its own options without touching ``generate``'s signature.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from inshade.components import registry
from inshade.shaders import add_search_provider

# type -> emitter (codegen/network.py loads the component folders' emitters into it)
EMITTERS: dict = registry.entries("glsl")
SEPARATE_INPUTS: set[str] = set()   # types whose emitter takes a list of input Values (may be uint), not one gathered
# types whose emitter writes lowered code (codegen/ir.py), which every target's printer spells; the
# others write GLSL text, for the OpenGL targets only
LOWERED: set[str] = set()
OPTIONS: dict[str, dict[str, tuple[tuple, object]]] = {}   # type -> option -> (choices, default)
# type -> what its nodes plan across the whole network (network_step), in registration order
NETWORK_STEPS: dict[str, type] = {}


@dataclass(frozen=True)
class Fused:
    """Nodes a network step emits as one piece of code (a loop over identical layers): ``emit(ctx, src,
    bundle)`` takes the first node's input and returns the value of node ``output``; none of ``ids``
    is emitted alone."""
    ids: tuple[str, ...]
    output: str
    emit: Callable


def network_step(component_type: str):
    """Register a class whose ``begin(ctx, bundle, calls)`` runs before a network's first node is emitted
    (a plan across the type's nodes, kept on ctx; it returns the nodes emitted together as ``{first
    node id: Fused}``) and whose ``end(ctx)`` runs after the last (the resources the nodes filled)."""
    def deco(cls):
        NETWORK_STEPS[component_type] = cls
        return cls
    return deco


def emitter(*types: str, options: dict | None = None, separate_inputs: bool = False, lowered: bool = False):
    """Register ``fn(ctx, node, src, bundle) -> Value``; with ``separate_inputs`` ``src`` is the list
    of the node's input Values as they are (a uint input stays uint), else their float concatenation.
    ``lowered``: the emitter writes codegen.ir statements (every target), not GLSL text."""
    def deco(fn):
        for t in types:
            registry.add("glsl", t, fn)
            if separate_inputs:
                SEPARATE_INPUTS.add(t)
            if lowered:
                LOWERED.add(t)
            if options:
                OPTIONS.setdefault(t, {}).update(options)
        return fn
    return deco


# a component folder's chunks are included as "<folder>/<chunk>"
add_search_provider(registry.chunk_roots)


def resolve_options(options: dict | None) -> dict[str, dict]:
    """Every declared option filled in: ``options`` checked (unknown type, option or value is a
    ValueError naming it) over the declared defaults."""
    out = {t: {name: default for name, (_, default) in opts.items()} for t, opts in OPTIONS.items()}
    for t, given in (options or {}).items():
        if t not in OPTIONS:
            raise ValueError(f"codegen options: component type {t!r} takes no options "
                             f"(types with options: {', '.join(sorted(OPTIONS))})")
        if not isinstance(given, dict):
            raise ValueError(f"codegen options: {t}: must be an object {{option: value}}")
        for name, value in given.items():
            if name not in OPTIONS[t]:
                raise ValueError(f"codegen options: {t}.{name}: unknown option (known: {', '.join(OPTIONS[t])})")
            choices = OPTIONS[t][name][0]
            if value not in choices:
                raise ValueError(f"codegen options: {t}.{name}: unknown value {value!r} "
                                 f"(choose from {', '.join(map(str, choices))})")
            out[t][name] = value
    return out
