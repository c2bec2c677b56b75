"""Multiresolution grid encodings as texture fetches: the emitter (lowered code calling the level lookup
of hash_grid.glsl and its .wgsl / .hlsl versions); torch twin in torch_twin.py (the rules in
inshade/grid_layout.py).

Resources: the [rows, F] table (all levels, level l from row offset_l) as 2D textures in rows of 2^n
texels (codegen/texture_rows.py: a table longer than GL_MAX_TEXTURE_SIZE wraps into rows), one
texture per 4 features (F = 8: two RGBA; 4: RGBA; 2: RG; 1: R), RGBA16F-family for precision f16
(the bundle's values are fp16-representable: checked at load), 32F for f32, unorm RGBA8-family for
u8 (the codes q, decoded per level after the blend: offset + scale * blend, components/unorm.py);
texelFetch only.
Levels are unrolled with their constants (scale, resolution, rows, offset, dense or hashed) as
literals; each level reads 2^dims texels per texture.
"""
from __future__ import annotations

from inshade.codegen import ir
from inshade.codegen.glsl import PlanRow
from inshade.codegen.registry import emitter
from inshade.codegen.texture_rows import feature_textures, row_layout, store_group, texture_formats, unorm_decoded
from inshade.codegen.values import declare
from inshade.components import grid_node_levels
from inshade.grid_layout import HASH_PRIMES

@emitter("hash_grid", "dense_grid", lowered=True)
def emit_grid(ctx, node, src, bundle):
    ctx.include("grids/hash_grid")
    p, dims = node.params, node.in_dim
    levels = grid_node_levels(node.type, p, dims)
    feats = p["features"]
    table = bundle.tensor(node, "table")
    log2w, n_rows = row_layout(node.id, "grid table", table.shape[0], ctx.limits)
    groups = feature_textures(ctx, node.id, table, p["precision"], log2w, n_rows,
                              f"{len(levels)} levels, {table.shape[0]} rows")

    primes = ir.Vector("uvec3", tuple(ir.Int(f"{q}u") for q in HASH_PRIMES[p.get("hash", "coherent_prime")]))
    x, s = ctx.name(node.id, "x"), ctx.name(node.id, "s")
    lanes = tuple(src.lane_ir(i) for i in range(dims)) + ((ir.Lit(0.0),) if dims == 2 else ())
    ctx.body += [ir.Declare("vec3", x, init=ir.Vector("vec3", lanes)), ir.Declare("vec4", s)]
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    for li, lv in enumerate(levels):
        for g, (name, width) in enumerate(groups):
            call = ir.Call("hg_level", (ir.TextureArg(name), ir.Int(str(log2w)), ir.Var(x), ir.Int(str(dims)),
                                        ir.Lit(float(lv.scale)), ir.Int(f"{lv.resolution}u"), ir.Int(f"{lv.rows}u"),
                                        ir.Int(f"{lv.offset}u"), ir.Bool(bool(lv.dense)), primes))
            if p["precision"] == "u8":
                call = unorm_decoded(call, bundle.tensor(node, "scale"), bundle.tensor(node, "offset"), 4 * g)
            store_group(ctx, out, li * feats + 4 * g, width, call, s)

    tex_bytes = sum(r.nbytes for r in ctx.resources[-len(groups):])
    fmt = texture_formats(groups, p["precision"])
    hashed = sum(not lv.dense for lv in levels)
    corners = 1 << dims
    ctx.plan.append(PlanRow(node.id, node.type,
                            f"{dims}D, {len(levels)} levels x {feats} ({p['precision']}), {hashed} hashed, "
                            f"{table.shape[0]} rows", "texture/exact",
                            f"{fmt} table, rows of {1 << log2w} texels", params=int(table.size),
                            flops=len(levels) * (corners * (2 * feats + dims + 6)
                                                 + (2 * feats if p["precision"] == "u8" else 0)),
                            fetches=len(levels) * corners * len(groups), texture_bytes=tex_bytes))
    return out
