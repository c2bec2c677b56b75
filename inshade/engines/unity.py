"""Unity Shader Graph's Custom Function node, File mode: an HLSL file whose ``<Name>_float`` (and
``<Name>_half``, which Shader Graph calls at half precision) takes the node's inputs and writes its
outputs as ``out`` parameters, in the order of the node's ports. The network computes in float at
either precision. Shader Graph includes the file once per shader; a guard keeps a second include
of it harmless, and the library functions two networks share are guarded too. A network whose
weights or tables are textures takes each as a Texture 2D input after the pins (Shader Graph passes a
``UnityTexture2D``: its ``tex`` is read with ``Load``, its ``samplerstate`` where the network filters).
"""
from __future__ import annotations

from inshade.codegen.glsl import SAMPLER_SUFFIX

from .pins import pack, unpack

INDENT = "    "
# how each image file is imported so the texture holds the texels as written (Texture Importer)
IMPORT = {
    "exr float": "Format RGBA Float",
    "exr half": "Format RGBA Half",
    "png 8-bit": "Format RGBA 32 bit; Alpha Source Input Texture Alpha; Alpha Is Transparency off",
}
IMPORT_COMMON = ("Texture Type Default; sRGB (Color Texture) off; Non-Power of 2 None; Max Size {side} or more; "
                 "Read/Write off; Generate Mip Maps off; Filter Mode {filter}; Wrap Mode {wrap}; Compression None")
FILTER = {False: "Point (no filter)", True: "Bilinear"}
WRAP = {"clamp": "Clamp", "repeat": "Repeat"}
SETUP = ["Put this folder's .hlsl file and images in your project's Assets.",
         "Set each image's import settings as listed below (the defaults would compress, filter or colour-convert "
         "the texels).",
         "Add a Custom Function node: Type File, Source the .hlsl file, Name and ports as the line above; add a "
         "Texture 2D property (or a Sample Texture's texture) per image and wire it into the input of its name."]


def _signature(ins, outs, textures, half: bool = False) -> str:
    def t(p):
        return p.type.replace("float", "half") if half else p.type
    return ", ".join([f"{t(p)} {p.name}" for p in ins] + [f"UnityTexture2D {f.name}" for f in textures]
                     + [f"out {t(p)} {p.name}" for p in outs])


def _texture_arguments(textures) -> list[str]:
    """What the network's eval takes of each Shader Graph texture: its Texture2D, and a filtered one's sampler."""
    return [a for f in textures for a in [f"{f.name}.tex", *([f"{f.name}.samplerstate"] if f.filtered else [])]]


def write(bundle, gen, chunk, ins, outs, textures, declarations) -> tuple[str, str, str]:
    """(the file, the file with a call of it as Shader Graph writes one (the check's module), the node's setup).
    ``chunk``: the network's HLSL, its ``textures`` (engines/textures.py) taken as arguments;
    ``declarations``: those textures as the check binds them."""
    name, up = gen.prefix, gen.prefix.upper()
    inputs = [*(f"{p.name} (Vector {p.dim})" for p in ins), *(f"{f.name} (Texture 2D)" for f in textures)]
    ports = f"inputs {', '.join(inputs)}; outputs {', '.join(f'{p.name} (Vector {p.dim})' for p in outs)}"
    node = f"Custom Function node: Type File, Source this file, Name {name}; {ports}"
    weights = f"the weights are in {len(textures)} textures (README.md)" if textures else "the weights are literals"
    head = [f"// {bundle.name}: an inshade network as a Unity Shader Graph Custom Function, from bundle "
            f"{bundle.digest()[:16]}.",
            f"// {node}.",
            f"// Vector 1 ports are float; {weights}; it computes in float at either precision.",
            f"#ifndef INSHADE_{up}_INCLUDED", f"#define INSHADE_{up}_INCLUDED"]
    call = ", ".join(["inshade_x", "inshade_y", *_texture_arguments(textures)])
    half_args = [f"({p.type}){p.name}" for p in ins] + [f.name for f in textures] + [p.name + "_f" for p in outs]
    body = [f"void {name}_float({_signature(ins, outs, textures)}) {{",
            *(INDENT + s for s in [f"float4 inshade_x[{up}_IN_BLOCKS];", *pack(ins, "inshade_x", gen.in_blocks),
                                   f"float4 inshade_y[{up}_OUT_BLOCKS];", f"{name}_eval({call});",
                                   *unpack(outs, "inshade_y")]),
            "}",
            f"void {name}_half({_signature(ins, outs, textures, half=True)}) {{",
            *(INDENT + f"{p.type} {p.name}_f;" for p in outs),
            INDENT + f"{name}_float({', '.join(half_args)});",
            *(INDENT + f"{p.name} = ({p.type.replace('float', 'half')}){p.name}_f;" for p in outs),
            "}", "#endif"]
    text = "\n".join([*head, chunk.rstrip("\n"), *body]) + "\n"
    return text, _check(text, gen, ins, outs, textures, declarations), node


def _check(text, gen, ins, outs, textures, declarations) -> str:
    """What Shader Graph's generated code amounts to: its UnityTexture2D (Core RP's, reduced to what the
    network reads), the textures bound, the pins as locals, a call of NAME_float."""
    name, up = gen.prefix, gen.prefix.upper()
    sampler = next((f"{f.name}{SAMPLER_SUFFIX}" for f in textures if f.filtered), None)
    stand_in = ["struct UnityTexture2D {", INDENT + "Texture2D<float4> tex;",
                *([INDENT + "SamplerState samplerstate;"] if sampler else []), "};", *declarations] if textures else []
    args = [p.name for p in ins] + [f.name + "_unity" for f in textures] + [p.name for p in outs]
    made = [s for f in textures for s in [f"UnityTexture2D {f.name}_unity;", f"{f.name}_unity.tex = {f.name};",
                                          *([f"{f.name}_unity.samplerstate = {sampler};"] if sampler else [])]]
    return "\n".join([
        *stand_in, text.rstrip("\n"),
        "#define EVAL_FUNCTION inshade_engine_check", f"#define EVAL_IN_BLOCKS {up}_IN_BLOCKS",
        f"#define EVAL_OUT_BLOCKS {up}_OUT_BLOCKS",
        f"void inshade_engine_check(float4 inshade_cx[{up}_IN_BLOCKS], out float4 inshade_cy[{up}_OUT_BLOCKS]) {{",
        *(INDENT + f"{p.type} {p.name};" for p in ins + outs),
        *(INDENT + s for s in made),
        *(INDENT + s for s in unpack(ins, "inshade_cx")),
        INDENT + f"{name}_float({', '.join(args)});",
        *(INDENT + s for s in pack(outs, "inshade_cy", gen.out_blocks)),
        "}"]) + "\n"
