"""Unreal's Custom expression node: the text is the node's Code. Unreal pastes it as the body of a
function of the node's inputs (named as the node's input pins) that returns the node's Output Type;
more outputs are the node's Additional Outputs (UE 5), written by name. A body cannot define
functions, so the network's functions are members of a struct declared in it (the usual way to bring
helpers into a Custom node); the library guards are lifted first, since each node's struct needs its
own copy. A network whose weights or tables are textures takes each as a Texture Object input after
the pins (in the Code: the Texture2D of the input's name, and ``<name>Sampler`` where it filters).
"""
from __future__ import annotations

from inshade.codegen.glsl import SAMPLER_SUFFIX
from inshade.codegen.printers.base import library_chunks, library_guard

from .pins import pack, unpack

INDENT = "    "
# members of a library chunk a struct's user sets (INSHADE_MEMBERS): chunk -> ((member, value), ...)
MEMBERS = {"lib/activations": (("inshade_nan_bits", "INSHADE_NAN_BITS"), ("inshade_inf_bits", "INSHADE_INF_BITS"))}
OUTPUT_TYPE = {1: "CMOT Float 1", 2: "CMOT Float 2", 3: "CMOT Float 3", 4: "CMOT Float 4"}
# how each image file is imported so the texture holds the texels as written (the texture's Details)
IMPORT = {
    "exr float": "Compression Settings HDR High Precision (RGBA32F) (UE 5.1 and later; HDR (RGBA16F) would round "
                 "the weights to half)",
    "exr half": "Compression Settings HDR (RGBA16F, no compression)",
    "png 8-bit": "Compression Settings VectorDisplacementmap (RGBA8)",
}
IMPORT_COMMON = ("sRGB off; Mip Gen Settings NoMipmaps; Filter {filter}; X-axis and Y-axis Tiling Method {wrap}; "
                 "Never Stream on")
FILTER = {False: "Nearest", True: "Bilinear"}
WRAP = {"clamp": "Clamp", "repeat": "Wrap"}
SETUP = ["Import this folder's images (drag them into the Content Browser) and set each one's Details as listed "
         "below (the defaults would compress, filter or colour-convert the texels).",
         "Add a Custom node, paste the .hlsl file's whole text into its Code, and set it up as the line above; "
         "wire a Texture Object node holding each image into the input of its name."]


def write(bundle, gen, chunk, ins, outs, textures, declarations) -> tuple[str, str, str]:
    """(the Code, the check's wrapping of it as Unreal's material compiler writes it, the node's setup).
    ``chunk``: the network's HLSL, its ``textures`` (engines/textures.py) taken as arguments;
    ``declarations``: those textures as the check binds them."""
    name, up = gen.prefix, gen.prefix.upper()
    first, extra = outs[0], outs[1:]
    inputs = [p.name for p in ins] + [f"{f.name} (Texture Object)" for f in textures]
    node = (f"Custom node: Output Type {OUTPUT_TYPE[first.dim]}; Inputs {', '.join(inputs)}"
            + (f"; Additional Outputs {', '.join(f'{p.name} ({OUTPUT_TYPE[p.dim][5:]})' for p in extra)}"
               if extra else "") + f"; returns {first.name}")
    library = [n for n, _ in library_chunks(gen.library, (".hlsl",))]
    struct = f"{name}_network"
    code = [f"// {bundle.name}: an inshade network as an Unreal Custom node's Code, from bundle "
            f"{bundle.digest()[:16]}.",
            f"// {node}. " + (f"The weights are in {len(textures)} textures (README.md)." if textures
                              else "The weights are literals."),
            *(f"#undef {library_guard(n)}" for n in library),
            "#define INSHADE_MEMBERS",
            f"struct {struct} {{", chunk.rstrip("\n"), "};",
            "#undef INSHADE_MEMBERS",
            f"{struct} {name}_net;",
            *(f"{name}_net.{member} = {value};" for n in library for member, value in MEMBERS.get(n, ())),
            f"float4 inshade_x[{up}_IN_BLOCKS];", *pack(ins, "inshade_x", gen.in_blocks),
            f"float4 inshade_y[{up}_OUT_BLOCKS];",
            f"{name}_net.{name}_eval({', '.join(['inshade_x', 'inshade_y', *_texture_arguments(textures)])});",
            f"{first.type} {first.name};", *unpack(outs, "inshade_y"),
            f"return {first.name};"]
    text = "\n".join(code) + "\n"
    # what Unreal's material compiler writes around the Code: a function of the pins (a Texture Object as
    # its texture and sampler; here a sampler only where the network filters, since the check binds no
    # other; Additional Outputs as inout), called with the pins' values
    params = ", ".join(["FMaterialPixelParameters Parameters", *(f"{p.type} {p.name}" for p in ins),
                        *(f"{t} {n}" for t, n, _ in _texture_parameters(textures)),
                        *(f"inout {p.type} {p.name}" for p in extra)])
    args = ["Parameters", *(p.name for p in ins), *(b for _, _, b in _texture_parameters(textures)),
            *(p.name for p in extra)]
    check = "\n".join([
        "struct FMaterialPixelParameters { float4 SvPosition; };", *declarations,
        f"{first.type} CustomExpression0({params}) {{", text.rstrip("\n"), "}",
        "#define EVAL_FUNCTION inshade_engine_check", f"#define EVAL_IN_BLOCKS {up}_IN_BLOCKS",
        f"#define EVAL_OUT_BLOCKS {up}_OUT_BLOCKS",
        f"void inshade_engine_check(float4 inshade_cx[{up}_IN_BLOCKS], out float4 inshade_cy[{up}_OUT_BLOCKS]) {{",
        INDENT + "FMaterialPixelParameters Parameters = (FMaterialPixelParameters)0;",
        *(INDENT + f"{p.type} {p.name};" for p in ins),
        *(INDENT + f"{p.type} {p.name} = ({p.type})0;" for p in outs),
        *(INDENT + s for s in unpack(ins, "inshade_cx")),
        INDENT + f"{first.name} = CustomExpression0({', '.join(args)});",
        *(INDENT + s for s in pack(outs, "inshade_cy", gen.out_blocks)),
        "}"]) + "\n"
    return text, check, node


def _texture_arguments(textures) -> list[str]:
    """What the network's eval takes of each Texture Object input: its texture, and a filtered one's sampler."""
    return [a for f in textures for a in [f.name, *([f"{f.name}Sampler"] if f.filtered else [])]]


def _texture_parameters(textures) -> list[tuple[str, str, str]]:
    """(type, name, what the check binds to it) of the wrapper's parameter for each texture argument: the
    check declares the textures and samplers under the network's names (codegen's sampler suffix)."""
    return [p for f in textures for p in [("Texture2D<float4>", f.name, f.name),
                                          *([("SamplerState", f"{f.name}Sampler", f.name + SAMPLER_SUFFIX)]
                                            if f.filtered else [])]]
