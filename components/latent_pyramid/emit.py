"""Latent texture pyramids as mipmapped textures: the GLSL emitter; torch twin in torch_twin.py.

Each group of 4 channels is one RGBA texture holding the whole pyramid as its mip chain
(level k = the bundle's `level{k}`, uploaded as given, never GL-built), RGBA16F for precision
f16 (the bundle's values are fp16-representable: checked at load), RGBA32F for f32 and RGBA8
(unorm) for u8, whose lookups decode offset + scale * blend per channel (components/unorm.py); the
sampler wraps with repeat.

Option ``latent_pyramid.filter``: "exact" = 4 texelFetch at the chosen level with integer
repeat wrap + fp32 mix (matches torch to fp32 rounding); "fast" = textureLod at the integer
level (hardware bilinear within it; see tests/components/test_latent_pyramid.py for the measured bound).

The code is lowered (codegen/ir.py): the lookups live in latent_pyramid.glsl and its .vulkan.glsl,
.wgsl and .hlsl versions; the fast path hands each texture's sampler beside it where a language keeps
samplers apart.
"""
from __future__ import annotations

import numpy as np

from inshade.codegen import ir
from inshade.codegen.glsl import PlanRow, TextureResource
from inshade.codegen.registry import emitter
from inshade.codegen.texture_rows import FLOAT_FORMATS, unorm_decoded
from inshade.codegen.values import declare

FILTERS = ("exact", "fast")


@emitter("latent_pyramid", options={"filter": (FILTERS, "exact")}, lowered=True)
def emit_latent_pyramid(ctx, node, src, bundle):
    ctx.include("latent_pyramid/latent_pyramid")
    mode = ctx.option("latent_pyramid", "filter")
    filtered = mode == "fast"
    p = node.params
    res, levels, channels = p["resolution"], p["levels"], p["channels"]
    dtype, np_dtype, suffix = FLOAT_FORMATS[p["precision"]]
    arrays = [bundle.tensor(node, f"level{k}") for k in range(levels)]
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    lvl = ctx.name(node.id, "level")
    uv = ir.Vector("vec2", (src.lane_ir(0), src.lane_ir(1)))
    ctx.body.append(ir.Declare("int", lvl, init=ir.Call("inshade_latent_level", (src.lane_ir(2), ir.Int(str(levels))),
                                                        "int")))
    tex_bytes = 0
    for g in range(channels // 4):
        tname = ctx.name(node.id, f"t{g}")
        chain = [np.ascontiguousarray(a[..., 4 * g:4 * g + 4], dtype=np_dtype) for a in arrays]
        ctx.globals.append(ir.Texture(tname, f"{node.id}: {res}x{res} latents, {levels} levels, "
                                      f"channels {4 * g}..{4 * g + 3}, {p['precision']}", 2, filtered))
        ctx.resources.append(TextureResource(tname, chain[0], dtype, "linear" if filtered else "nearest",
                                             mips=tuple(chain[1:]), wrap="repeat"))
        tex_bytes += sum(c.nbytes for c in chain)
        texture = ir.TextureArg(tname, filtered)
        args = (texture, uv, ir.Var(lvl)) if filtered else (texture, ir.Int(str(res)), uv, ir.Var(lvl))
        lookup = ir.Call(f"inshade_latent_{mode}", args)
        if p["precision"] == "u8":
            lookup = unorm_decoded(lookup, bundle.tensor(node, "scale"), bundle.tensor(node, "offset"), 4 * g)
        ctx.body.append(ir.Assign(out.block_ir(g), lookup))
    ctx.plan.append(PlanRow(node.id, "latent_pyramid", f"{res}x{res}x{channels}, {levels} levels ({p['precision']})",
                            f"texture/{mode}", f"{channels // 4} RGBA{suffix} mip chains",
                            params=int(sum(a.size for a in arrays)),
                            flops=3 * 2 * channels + (2 * channels if p["precision"] == "u8" else 0),
                            fetches=(4 if mode == "exact" else 1) * (channels // 4), texture_bytes=tex_bytes))
    return out
