"""Unreal's Custom expression node: the text is the node's Code. Unreal pastes it as the body of a
function of the node's inputs (named as the node's input pins) that returns the node's Output Type;
more outputs are the node's Additional Outputs (UE 5), written by name. A body cannot define
functions, so the network's functions are members of a struct declared in it (the usual way to bring
helpers into a Custom node); the library guards are lifted first, since each node's struct needs its
own copy.
"""
from __future__ import annotations

from inshade.codegen.printers.base import library_chunks, library_guard

from .pins import pack, unpack

INDENT = "    "
# members of a library chunk a struct's user sets (INSHADE_MEMBERS): chunk -> ((member, value), ...)
MEMBERS = {"lib/activations": (("inshade_nan_bits", "INSHADE_NAN_BITS"), ("inshade_inf_bits", "INSHADE_INF_BITS"))}
OUTPUT_TYPE = {1: "CMOT Float 1", 2: "CMOT Float 2", 3: "CMOT Float 3", 4: "CMOT Float 4"}


def write(bundle, gen, ins, outs) -> tuple[str, str, str]:
    """(the Code, the check's wrapping of it as Unreal's material compiler writes it, the node's setup)."""
    name, up = gen.prefix, gen.prefix.upper()
    first, extra = outs[0], outs[1:]
    node = (f"Custom node: Output Type {OUTPUT_TYPE[first.dim]}; Inputs {', '.join(p.name for p in ins)}"
            + (f"; Additional Outputs {', '.join(f'{p.name} ({OUTPUT_TYPE[p.dim][5:]})' for p in extra)}"
               if extra else "") + f"; returns {first.name}")
    library = [n for n, _ in library_chunks(gen.library, (".hlsl",))]
    struct = f"{name}_network"
    code = [f"// {bundle.name}: an inshade network as an Unreal Custom node's Code, from bundle "
            f"{bundle.digest()[:16]}.",
            f"// {node}. The weights are literals.",
            *(f"#undef {library_guard(n)}" for n in library),
            "#define INSHADE_MEMBERS",
            f"struct {struct} {{", gen.chunk.rstrip("\n"), "};",
            "#undef INSHADE_MEMBERS",
            f"{struct} {name}_net;",
            *(f"{name}_net.{member} = {value};" for n in library for member, value in MEMBERS.get(n, ())),
            f"float4 inshade_x[{up}_IN_BLOCKS];", *pack(ins, "inshade_x", gen.in_blocks),
            f"float4 inshade_y[{up}_OUT_BLOCKS];", f"{name}_net.{name}_eval(inshade_x, inshade_y);",
            f"{first.type} {first.name};", *unpack(outs, "inshade_y"),
            f"return {first.name};"]
    text = "\n".join(code) + "\n"
    # what Unreal's material compiler writes around the Code: a function of the pins (Additional
    # Outputs as inout), called with the pins' values
    params = ", ".join(["FMaterialPixelParameters Parameters", *(f"{p.type} {p.name}" for p in ins),
                        *(f"inout {p.type} {p.name}" for p in extra)])
    check = "\n".join([
        "struct FMaterialPixelParameters { float4 SvPosition; };",
        f"{first.type} CustomExpression0({params}) {{", text.rstrip("\n"), "}",
        "#define EVAL_FUNCTION inshade_engine_check", f"#define EVAL_IN_BLOCKS {up}_IN_BLOCKS",
        f"#define EVAL_OUT_BLOCKS {up}_OUT_BLOCKS",
        f"void inshade_engine_check(float4 inshade_cx[{up}_IN_BLOCKS], out float4 inshade_cy[{up}_OUT_BLOCKS]) {{",
        INDENT + "FMaterialPixelParameters Parameters = (FMaterialPixelParameters)0;",
        *(INDENT + f"{p.type} {p.name};" for p in ins),
        *(INDENT + f"{p.type} {p.name} = ({p.type})0;" for p in outs),
        *(INDENT + s for s in unpack(ins, "inshade_cx")),
        INDENT + f"{first.name} = CustomExpression0({', '.join(['Parameters', *(p.name for p in ins + extra)])});",
        *(INDENT + s for s in pack(outs, "inshade_cy", gen.out_blocks)),
        "}"]) + "\n"
    return text, check, node
