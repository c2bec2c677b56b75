"""A network's HLSL as an engine's node takes it, and the check that runs that very text.

The network is generated for the ``hlsl`` target under a prefix of its own, so several networks live
in one material; the library functions they share sit behind include guards (codegen/printers/base.py).
Its weights are literals (``storage="inline"``: a node's code binds nothing of inshade's) or textures
(``storage="texture"``; a network's lookup tables are textures either way): each texture then is an
image file the engine imports (engines/textures.py) and an input of the node, passed to the network's
function as an argument. A port of more than 4 lanes becomes several node pins (``name_0``,
``name_1``, ...: pins are 1 to 4 floats).
"""
from __future__ import annotations

import re
import time
from dataclasses import dataclass

import numpy as np

from inshade.codegen import generate
from inshade.codegen.printers.hlsl import HLSLPrinter
from inshade.codegen.targets import TargetError

from . import unity, unreal
from .pins import pins
from .textures import BOTTOM_UP, engine_texture, image_bytes, texture_files

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
    images: list         # (engines/textures.py TextureFile, its pixels) of each texture, in argument order

    def report(self) -> str:
        weights = (f"the weights in {len(self.images)} textures ({', '.join(f.file for f, _ in self.images)})"
                   if self.images else "the weights as literals")
        return f"{self.engine} drop-in: {len(self.text)} characters, {weights}; {self.node}"


def default_prefix(bundle) -> str:
    """The bundle's name as a function name (a node's name in the material)."""
    name = re.sub(r"_+", "_", re.sub(r"\W", "_", bundle.name)).strip("_") or "net"
    return name if name[0].isalpha() else "net_" + name


def drop_in(bundle, engine: str, prefix: str | None = None, storage: str = "inline",
            lut_filter: str = "exact") -> DropIn:
    """The drop-in of ``bundle`` for ``engine`` (unity, unreal), its symbols under ``prefix`` (by default
    the bundle's name), its dense weights as literals (``storage="inline"``) or a texture ("texture")."""
    prefix = default_prefix(bundle) if prefix is None else prefix
    if engine not in ENGINE_TEXT:
        raise ValueError(f"unknown engine {engine!r} (choose from {', '.join(ENGINE_TEXT)})")
    if any(p.dtype == "uint" for p in bundle.inputs):
        raise TargetError(f"{engine}: {bundle.name} takes uint inputs "
                          f"({', '.join(p.name for p in bundle.inputs if p.dtype == 'uint')}); a node's pins are floats")
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", prefix) or "__" in prefix:
        raise ValueError(f"--prefix {prefix!r}: the node's function name needs a letter then letters, digits, "
                         "single underscores")
    if storage not in ("inline", "texture"):
        raise ValueError(f"storage {storage!r}: a drop-in's weights are literals (inline) or a texture (texture); "
                         "a block is not a node's input")
    # an i8 layer's codes as unorm texels: an engine imports image files, not integer textures
    gen = generate(bundle, target="hlsl", storage=storage, lut_filter=lut_filter, prefix=prefix,
                   options={"dense": {"i8_texels": "unorm"}})
    images = texture_files(gen.resources, engine, prefix)
    ins = pins(bundle.inputs)
    outs = pins(bundle.outputs, taken={p.name for p in ins} | {r.name for r in gen.resources})
    chunk = HLSLPrinter(textures_as_arguments=True).module(gen.module) if images else gen.chunk
    declarations = HLSLPrinter().texture_declarations(gen.module)
    text, check_source, node = ENGINE_TEXT[engine].write(bundle, gen, chunk, ins, outs, [f for f, _ in images],
                                                         declarations)
    return DropIn(engine, text, check_source, gen, ins, outs, node, images)


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
    out = evaluate(imported(d), x, "hlsl", code=code)
    parts = per_input(bundle, x)
    ref = source_outputs(source, parts, bundle)
    result = compare(out, ref, device_name("hlsl"), "inline", time.perf_counter() - start)
    return judge(dataclasses.replace(result, language=f"hlsl ({d.engine})"), source, parts, bundle, out, ref)


def readme(d: DropIn, code_file: str) -> str:
    """The README of a drop-in whose weights are image files: the setup, and each image's import settings."""
    engine = ENGINE_TEXT[d.engine]
    lines = [f"# {d.generated.prefix}: an inshade network for {d.engine.capitalize()}", "",
             f"`{code_file}` and {len(d.images)} images. {d.node}.", "",
             *(f"{k}. {step}" for k, step in enumerate(engine.SETUP, 1)), "",
             "| image | size | import settings |", "|---|---|---|"]
    for f, _ in d.images:
        side = 1 << (max(f.width, f.height) - 1).bit_length()   # the import's size cap, a power of two
        common = engine.IMPORT_COMMON.format(filter=engine.FILTER[f.filtered], wrap=engine.WRAP[f.wrap], side=side)
        lines.append(f"| `{f.file}` ({f.name}) | {f.width} x {f.height} | {engine.IMPORT[f.format]}; {common} |")
    rows = "bottom-up (the engine's texture origin is the bottom left)" if BOTTOM_UP[d.engine] else "top-down"
    lines += ["", f"The images hold data, not colours: RGBA, the channels a texture lacks 0 and alpha 1, rows {rows}. "
                  "Checked by inshade through an HLSL driver as written here; not run in the engine."]
    return "\n".join(lines) + "\n"


def imported(d: DropIn):
    """``d``'s network with the textures the engine makes of its image files: each file written, read back
    and laid in memory as the engine does (engines/textures.py), so the check reads what the engine would."""
    import dataclasses
    import tempfile
    from pathlib import Path

    if not d.images:
        return d.generated
    with tempfile.TemporaryDirectory() as tmp:
        by_name = {}
        for record, pixels in d.images:
            path = Path(tmp) / record.file
            path.write_bytes(image_bytes(record, pixels))
            by_name[record.name] = (record, path)
        resources = [engine_texture(*by_name[r.name], d.engine, r) for r in d.generated.resources]
    return dataclasses.replace(d.generated, resources=resources)
