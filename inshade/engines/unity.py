"""Unity Shader Graph's Custom Function node, File mode: an HLSL file whose ``<Name>_float`` (and
``<Name>_half``, which Shader Graph calls at half precision) takes the node's inputs and writes its
outputs as ``out`` parameters, in the order of the node's ports. The network computes in float at
either precision. Shader Graph includes the file once per shader; a guard keeps a second include
of it harmless, and the library functions two networks share are guarded too.
"""
from __future__ import annotations

from .pins import pack, unpack

INDENT = "    "


def _signature(ins, outs, half: bool = False) -> str:
    def t(p):
        return p.type.replace("float", "half") if half else p.type
    return ", ".join([f"{t(p)} {p.name}" for p in ins] + [f"out {t(p)} {p.name}" for p in outs])


def write(bundle, gen, ins, outs) -> tuple[str, str, str]:
    """(the file, the file with a call of it as Shader Graph writes one (the check's module), the node's setup)."""
    name, up = gen.prefix, gen.prefix.upper()
    ports = (f"inputs {', '.join(f'{p.name} (Vector {p.dim})' for p in ins)}; outputs "
             f"{', '.join(f'{p.name} (Vector {p.dim})' for p in outs)}")
    node = f"Custom Function node: Type File, Source this file, Name {name}; {ports}"
    head = [f"// {bundle.name}: an inshade network as a Unity Shader Graph Custom Function, from bundle "
            f"{bundle.digest()[:16]}.",
            f"// {node}.",
            "// Vector 1 ports are float; the weights are literals; it computes in float at either precision.",
            f"#ifndef INSHADE_{up}_INCLUDED", f"#define INSHADE_{up}_INCLUDED"]
    body = [f"void {name}_float({_signature(ins, outs)}) {{",
            *(INDENT + s for s in [f"float4 inshade_x[{up}_IN_BLOCKS];", *pack(ins, "inshade_x", gen.in_blocks),
                                   f"float4 inshade_y[{up}_OUT_BLOCKS];", f"{name}_eval(inshade_x, inshade_y);", *unpack(outs, "inshade_y")]),
            "}",
            f"void {name}_half({_signature(ins, outs, half=True)}) {{",
            *(INDENT + f"{p.type} {p.name}_f;" for p in outs),
            INDENT + f"{name}_float({', '.join([f'({p.type}){p.name}' for p in ins] + [p.name + '_f' for p in outs])});",
            *(INDENT + f"{p.name} = ({p.type.replace('float', 'half')}){p.name}_f;" for p in outs),
            "}", "#endif"]
    text = "\n".join([*head, gen.chunk.rstrip("\n"), *body]) + "\n"
    # what Shader Graph's generated code amounts to: the pins as locals, a call of NAME_float
    check = "\n".join([
        text.rstrip("\n"),
        "#define EVAL_FUNCTION inshade_engine_check", f"#define EVAL_IN_BLOCKS {up}_IN_BLOCKS",
        f"#define EVAL_OUT_BLOCKS {up}_OUT_BLOCKS",
        f"void inshade_engine_check(float4 inshade_cx[{up}_IN_BLOCKS], out float4 inshade_cy[{up}_OUT_BLOCKS]) {{",
        *(INDENT + f"{p.type} {p.name};" for p in ins + outs),
        *(INDENT + s for s in unpack(ins, "inshade_cx")),
        INDENT + f"{name}_float({', '.join(p.name for p in ins + outs)});",
        *(INDENT + s for s in pack(outs, "inshade_cy", gen.out_blocks)),
        "}"]) + "\n"
    return text, check, node
