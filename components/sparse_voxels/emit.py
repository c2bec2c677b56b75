"""Sparse multi-scale voxel latents as texture fetches: the emitter (lowered code calling the functions
of sparse_voxels.glsl and its .wgsl / .hlsl versions); torch twin in torch_twin.py.

Resources (P = the network prefix, e.g. "dap"; node id v):
- ``P_v_latents``: the latent table, Z/4 RGBA texels per voxel (texel t = slot * Z/4 + g holds
  channels 4g..4g+3), RGBA16F for precision f16 (the bundle's values are fp16-representable:
  checked at load), RGBA32F for f32, RGBA8 (unorm) for u8 (each texel decoded offset + scale * q / 255
  per channel: components/unorm.py); a 2D texture whose rows are 2^n texels wide (texel t at
  (t & (W-1), t >> n): codegen/texture_rows.py row_layout, within GL_MAX_TEXTURE_SIZE);
- ``P_v_spheres``: spheres (centre, radius), one RGBA32F texel per slot, same row layout;
- the cell -> slot index, as param ``index`` says (codegen/voxel_index.py has the layouts):
  ``dense`` (``P_v_grid``: ONE R32UI 3D texture, mip level L = scale scale_max - L, texel =
  slot + 1, 0 = empty) or ``bricks`` (``P_v_top`` + ``P_v_bricks``: a table of B^3 bricks per
  scale and R32UI bricks where voxels exist). It is built here from `cells`, so every non-zero
  entry is slot + 1 with slot < N: it cannot point past the latent table.

Globals with fixed names, in every shading language (the march pass calls them; constants upper-case,
``#define`` in GLSL and HLSL, ``const`` in WGSL):

    #define P_SCALE_MIN / P_SCALE_MAX / P_VOXELS
    uint P_voxel_slot(int scale, ivec3 cell)   // 0 = empty, outside the grid or the scale range, else slot + 1
    vec4 P_voxel_sphere(uint slot)             // (centre, radius) of row `slot` (= P_voxel_slot(..) - 1u)

A network holds at most one sparse_voxels node (the names are fixed). The node's own input is the
slot (a uint lane, or a float holding an exact integer); out-of-range slots are clamped to
0..N-1 in the shader (a shader cannot raise; torch raises ValueError). P_voxel_sphere clamps alike.
"""
from __future__ import annotations

import numpy as np

from inshade.codegen import ir
from inshade.codegen.glsl import PlanRow, TextureResource
from inshade.codegen.registry import emitter
from inshade.codegen.texture_rows import FLOAT_FORMATS, row_layout, rows_data, unorm_decoded
from inshade.codegen.values import declare
from inshade.codegen.voxel_index import EMIT as INDEX_EMIT
from inshade.components import check_voxel_tables

def _row(table: str, index: ir.Expr, log2w: int) -> ir.Call:
    return ir.Call("sv_row", (ir.TextureArg(table), index, ir.Int(str(log2w))))


def _slot(v, i: int, n: int) -> ir.Expr:
    """The node's input lane as a slot clamped to 0..n-1 (a float holds an exact integer)."""
    if v.kind == "uint":
        return ir.Call("min", (v.lane_ir(i), ir.Int(f"{n - 1}u")), "uint")
    return ir.Convert("uint", ir.Call("clamp", (v.lane_ir(i), ir.Lit(0.0), ir.Lit(float(n - 1))), "float"))


@emitter("sparse_voxels", separate_inputs=True, lowered=True)
def emit_sparse_voxels(ctx, node, srcs, bundle):
    ctx.include("sparse_voxels/sparse_voxels")
    p = node.params
    n, z, smin, smax = p["voxels"], p["channels"], p["scale_min"], p["scale_max"]
    up, slot_fn, sphere_fn = ctx.prefix.upper(), f"{ctx.prefix}_voxel_slot", f"{ctx.prefix}_voxel_sphere"
    if any(isinstance(g, ir.Function) and g.name == slot_fn for g in ctx.globals):
        raise ValueError(f"node {node.id}: a network holds at most one sparse_voxels node "
                         f"({slot_fn} and {sphere_fn} have fixed names)")
    cells, spheres = bundle.tensor(node, "cells"), bundle.tensor(node, "spheres")
    latents = bundle.tensor(node, "latents")
    check_voxel_tables(cells, spheres, smin, smax, latents)
    fdtype, np_dtype, suffix = FLOAT_FORMATS[p["precision"]]
    fmt = f"RGBA{suffix}"
    texels = z // 4

    lat_log2w, lat_rows = row_layout(node.id, f"latent table ({texels} texels per voxel)", n * texels, ctx.limits)
    sph_log2w, sph_rows = row_layout(node.id, "sphere table", n, ctx.limits)
    lat, sph = (ctx.name(node.id, s) for s in ("latents", "spheres"))
    index_resources, index_decls, lookup, index_plan = INDEX_EMIT[p["index"]](ctx, node, cells, up)
    resources = [
        TextureResource(lat, rows_data(np.ascontiguousarray(latents.reshape(n * texels, 4), dtype=np_dtype),
                                   lat_log2w, lat_rows), fdtype),
        TextureResource(sph, rows_data(np.ascontiguousarray(spheres, np.float32), sph_log2w, sph_rows), "f4"),
        *index_resources,
    ]
    ctx.resources += resources
    ctx.globals += [
        ir.Texture(lat, f"{node.id}: {n} voxels x {z} latents, {texels} texels each, {p['precision']}"),
        ir.Texture(sph, f"{node.id}: bounding sphere (centre, radius) per voxel"),
        *index_decls,
        ir.Constant(f"{up}_SCALE_MIN", smin), ir.Constant(f"{up}_SCALE_MAX", smax), ir.Constant(f"{up}_VOXELS", n),
        ir.Function("uint", slot_fn, (("int", "scale"), ("ivec3", "cell")), (ir.Return(lookup),)),
        ir.Function("vec4", sphere_fn, (("uint", "slot"),), (ir.Return(
            _row(sph, ir.Call("min", (ir.Var("slot"), ir.Int(f"{n - 1}u")), "uint"), sph_log2w)),)),
    ]
    (v, i), = [(v, i) for v in srcs for i in range(v.dim)]
    s = ctx.name(node.id, "slot")
    out = declare(ctx, f"v_{node.id}", z)
    ctx.body.append(ir.Declare("uint", s, init=_slot(v, i, n)))
    # channels 4g..4g+3 of the row: texel slot * Z/4 + g of the latent table
    fetches = [_row(lat, ir.Int(f"{s} * {texels}u + {g}u"), lat_log2w) for g in range(texels)]
    if p["precision"] == "u8":
        scale, offset = bundle.tensor(node, "scale"), bundle.tensor(node, "offset")
        fetches = [unorm_decoded(f, scale, offset, 4 * g) for g, f in enumerate(fetches)]
    ctx.body += [ir.Assign(out.block_ir(g), f) for g, f in enumerate(fetches)]
    ctx.plan.append(PlanRow(node.id, "sparse_voxels",
                            f"{n} voxels x {z} ({p['precision']}), scales {smin}..{smax}", "texture/exact",
                            f"{fmt} latents ({texels} texels/voxel, rows of {1 << lat_log2w}) + RGBA32F spheres + "
                            + index_plan,
                            params=int(latents.size), flops=2 * texels, fetches=texels,
                            texture_bytes=sum(r.nbytes for r in resources)))
    return out
