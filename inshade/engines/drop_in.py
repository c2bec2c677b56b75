"""A network's HLSL as an engine's node takes it, and the check that runs that very text.

The network is generated for the ``hlsl`` target with its weights as literals (a node's code binds
no resources of inshade's) under a prefix of its own, so several networks live in one material;
the library functions they share sit behind include guards (codegen/printers/base.py). A port of
more than 4 lanes becomes several node pins (``name_0``, ``name_1``, ...: pins are 1 to 4 floats).
"""
from __future__ import annotations

import re
import time
from dataclasses import dataclass

import numpy as np

from inshade.codegen import generate
from inshade.codegen.targets import TargetError

from . import unity, unreal
from .pins import pins

ENGINE_TEXT = {"unity": unity, "unreal": unreal}
# the compiler a check runs the text through: glslang's HLSL front end, but for Unreal's Code, which
# declares a struct with methods inside a function (as DXC and FXC take it; glslang takes methods at
# global scope only): the Slang compiler, which reads it in place
CHECK_COMPILER = {"unity": "hlsl", "unreal": "slang"}


@dataclass(frozen=True)
class DropIn:
    engine: str
    text: str            # the file to add (Unity) or the node body to paste (Unreal)
    check_source: str    # the text where its engine puts it, called as the engine calls it (the check's module)
    generated: object    # codegen.Generated of the network inside
    inputs: list
    outputs: list
    node: str            # how to set the node up, one line

    def report(self) -> str:
        return (f"{self.engine} drop-in: {len(self.text)} characters, the weights as literals; {self.node}")


def default_prefix(bundle) -> str:
    """The bundle's name as a function name (a node's name in the material)."""
    name = re.sub(r"_+", "_", re.sub(r"\W", "_", bundle.name)).strip("_") or "net"
    return name if name[0].isalpha() else "net_" + name


def drop_in(bundle, engine: str, prefix: str | None = None) -> DropIn:
    """The drop-in of ``bundle`` for ``engine`` (unity, unreal), its symbols under ``prefix`` (by default
    the bundle's name)."""
    prefix = default_prefix(bundle) if prefix is None else prefix
    if engine not in ENGINE_TEXT:
        raise ValueError(f"unknown engine {engine!r} (choose from {', '.join(ENGINE_TEXT)})")
    if any(p.dtype == "uint" for p in bundle.inputs):
        raise TargetError(f"{engine}: {bundle.name} takes uint inputs "
                          f"({', '.join(p.name for p in bundle.inputs if p.dtype == 'uint')}); a node's pins are floats")
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", prefix) or "__" in prefix:
        raise ValueError(f"--prefix {prefix!r}: the node's function name needs a letter then letters, digits, "
                         "single underscores")
    gen = generate(bundle, target="hlsl", storage="inline", prefix=prefix)
    if gen.resources:
        raise TargetError(f"{engine}: {bundle.name} reads {len(gen.resources)} textures or blocks "
                          f"({', '.join(r.name for r in gen.resources)}); the drop-in holds its weights as literals "
                          "only: use --target hlsl without --engine and bind them yourself")
    ins = pins(bundle.inputs)
    outs = pins(bundle.outputs, taken={p.name for p in ins})
    text, check_source, node = ENGINE_TEXT[engine].write(bundle, gen, ins, outs)
    return DropIn(engine, text, check_source, gen, ins, outs, node)


def check_drop_in(d: DropIn, source, bundle, x: np.ndarray):
    """``d``'s text, called as its engine calls it, through the HLSL driver on inputs ``x`` [N, in_dim],
    against ``source`` (the bundle's torch twin or the module it came from): a CheckResult."""
    import dataclasses

    from inshade.convert.check import compare, judge, per_input, source_outputs
    from inshade.runtime.compute import SOURCES, device_name, evaluate
    from inshade.runtime.compute.run import HERE

    start = time.perf_counter()
    harness, _ = SOURCES["hlsl"]
    code = SOURCES[CHECK_COMPILER[d.engine]][1](d.check_source + (HERE / harness).read_text())
    x = np.asarray(x, np.float32)
    out = evaluate(d.generated, x, "hlsl", code=code)
    parts = per_input(bundle, x)
    ref = source_outputs(source, parts, bundle)
    result = compare(out, ref, device_name("hlsl"), "inline", time.perf_counter() - start)
    return judge(dataclasses.replace(result, language=f"hlsl ({d.engine})"), source, parts, bundle, out, ref)
