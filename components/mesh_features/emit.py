"""The UV-free feature hierarchy as texture fetches: the emitter (lowered code calling the functions of
shaders/lib/mesh_features.glsl and its .wgsl / .hlsl versions); torch twin in torch_twin.py (the rules:
models/mesh_features.py).

Resources, each a 2D texture whose rows are 2^n texels wide (the largest power of two that fits
GL_MAX_TEXTURE_SIZE, or less for small data), item `index` at (index & (W-1), index >> n):
- topology: one RGB32UI texture of the face's corner and edge owner ids, fetched once per call.
  When every id is < PACK16_LIMIT: 1 texel per face (12 bytes), two 16-bit ids per channel:
  (c0 | c1 << 16, c2 | e0 << 16, e1 | e2 << 16). Else, up to OWNERS16_LIMIT faces: 1 RGBA32UI
  texel (16 bytes), the ids' owner faces two to a channel and their slot bits in the fourth.
  Otherwise 2 texels per face (24 bytes): texel 2k = corners[k], texel 2k+1 = edges[k] (the row
  width is even, so both share a row);
- table: rows l*T + h of the [levels * T, F] feature table, one texture per 4 features (F = 8:
  two RGBA, 4: RGBA, 2: RG, 1: R), RGBA16F-family for precision f16 (the bundle's values are
  fp16-representable: checked at load), 32F for f32, unorm RGBA8-family for u8 (the uint8 codes q;
  value = offset + scale * q / 255 per lane, applied once per level after the blend, as
  `offset + scale * blend` with the bundle's float32 scale/offset as vec4 literals: the blend's
  weights sum to 1, so the affine map commutes with it); always texelFetch (nearest).

Input: the node's inputs as they are (separate_inputs): triangle id (a uint lane, or a float one
holding an exact integer) then t0, t1. Levels are unrolled (L <= 16).
"""
from __future__ import annotations

import numpy as np

from inshade.codegen import ir
from inshade.codegen.glsl import PlanRow, TextureResource
from inshade.codegen.registry import emitter
from inshade.codegen.texture_rows import (feature_textures, row_layout, rows_data, store_group,
                                          texture_formats, unorm_decoded)
from inshade.codegen.values import declare
from inshade.geometry.mesh_topology import check_tables

# Owner ids are face << 2 | slot (corners) and face << 4 | slots (edges). Small meshes pack them
# tighter than a full uint32 each: below PACK16_LIMIT every id fits 16 bits, two to a channel;
# below OWNERS16_LIMIT faces every owner face fits 16 bits and the 18 slot bits fill a fourth channel.
PACK16_LIMIT = 1 << 16
OWNERS16_LIMIT = 1 << 16


def _pack16(corners, edges):
    ids = np.concatenate([corners, edges], 1).astype(np.uint32)     # [faces, 6]
    return ids[:, 0::2] | (ids[:, 1::2] << 16)


def _owners16(corners, edges):
    c, e = corners.astype(np.uint32), edges.astype(np.uint32)
    owners = np.concatenate([c >> 2, e >> 4], 1)                     # [faces, 6] face numbers
    slots = (c[:, 0] & 3) | (c[:, 1] & 3) << 2 | (c[:, 2] & 3) << 4 \
        | (e[:, 0] & 15) << 6 | (e[:, 1] & 15) << 10 | (e[:, 2] & 15) << 14
    return np.concatenate([owners[:, 0::2] | (owners[:, 1::2] << 16), slots[:, None]], 1)


def _pack32(corners, edges):
    return np.stack([corners, edges], 1).astype(np.uint32).reshape(-1, 3)


# layout -> (texels per face, GLSL function, packer to [faces * texels, channels] uint32), smallest first
TOPOLOGY_LAYOUTS = {"pack16": (1, "mf_face_tables16", _pack16), "owners16": (1, "mf_face_owners16", _owners16),
                    "pack32": (2, "mf_face_tables", _pack32)}


def topology_layout(corners, edges) -> str:
    if max(corners.max(), edges.max()) < PACK16_LIMIT:
        return "pack16"
    return "owners16" if len(corners) <= OWNERS16_LIMIT else "pack32"


@emitter("mesh_features", separate_inputs=True, lowered=True)
def emit_mesh_features(ctx, node, srcs, bundle):
    ctx.include("lib/mesh_features")
    p = node.params
    levels, feats, size, faces = p["levels"], p["features"], p["table_size"], p["faces"]
    corners, edges = bundle.tensor(node, "corners"), bundle.tensor(node, "edges")
    check_tables(corners, edges, faces)
    table = bundle.tensor(node, "table")

    lanes = [(v, i) for v in srcs for i in range(v.dim)]
    (kv, ki), (t0v, t0i), (t1v, t1i) = lanes
    as_float = lambda v, i: v.lane_ir(i) if v.kind == "float" else ir.Convert("float", v.lane_ir(i))  # noqa: E731
    k_expr = kv.lane_ir(ki) if kv.kind == "uint" else ir.Convert("uint", kv.lane_ir(ki))

    texels, face_tables, pack = TOPOLOGY_LAYOUTS[topology_layout(corners, edges)]
    per_face = f"{texels} texel{'s' * (texels > 1)} per face"
    topo_log2w, topo_rows = row_layout(node.id, f"topology texture ({per_face})", texels * faces, ctx.limits)
    topo = ctx.name(node.id, "topology")
    ctx.globals.append(ir.Texture(topo, f"{node.id}: corner/edge owners of {faces} faces, {per_face}", integer=True))
    packed = pack(corners, edges)
    ctx.resources.append(TextureResource(topo, rows_data(packed, topo_log2w, topo_rows), "u4"))

    tab_log2w, tab_rows = row_layout(node.id, "feature table", levels * size, ctx.limits)
    groups = feature_textures(ctx, node.id, table, p["precision"], tab_log2w, tab_rows,
                              f"{levels} levels x {size} rows")
    u8 = p["precision"] == "u8"

    out = declare(ctx, f"v_{node.id}", node.out_dim)
    k, t, c, e = (ctx.name(node.id, s) for s in ("k", "t", "corners", "edges"))
    idx, wt, s = ctx.name(node.id, "index"), ctx.name(node.id, "weight"), ctx.name(node.id, "s")
    ctx.body += [ir.Declare("uint", k, init=k_expr),
                 ir.Declare("vec2", t, init=ir.Vector("vec2", (as_float(t0v, t0i), as_float(t1v, t1i)))),
                 ir.Group((ir.Declare("uvec3", c), ir.Declare("uvec3", e)), one_line=True),
                 ir.Do(ir.Call(face_tables, (ir.TextureArg(topo), ir.Var(k), ir.Int(str(topo_log2w)),
                                             ir.Out(ir.Var(c)), ir.Out(ir.Var(e))), "void")),
                 ir.Group((ir.Declare("uint", idx, 3), ir.Declare("vec3", wt), ir.Declare("vec4", s)), one_line=True)]
    for level in range(levels):
        ctx.body.append(ir.Do(ir.Call("mf_level_taps", (
            ir.Var(k), ir.Var(t), ir.Int(str(level)), ir.Int(f"{size}u"), ir.Var(c), ir.Var(e),
            ir.Out(ir.Var(idx)), ir.Out(ir.Var(wt))), "void")))
        for g, (name, width) in enumerate(groups):
            blend = ir.Call("mf_blend", (ir.TextureArg(name), ir.Int(str(tab_log2w)), ir.Var(idx), ir.Var(wt)))
            if u8:
                blend = unorm_decoded(blend, bundle.tensor(node, "scale"), bundle.tensor(node, "offset"), 4 * g)
            store_group(ctx, out, level * feats + 4 * g, width, blend, s)

    tex_bytes = sum(r.nbytes for r in ctx.resources[-1 - len(groups):])
    fmt = texture_formats(groups, p["precision"])
    ctx.plan.append(PlanRow(node.id, "mesh_features",
                            f"{levels} levels x {size} rows x {feats} ({p['precision']}), {faces} faces",
                            "texture/exact", f"{'RGBA' if packed.shape[1] == 4 else 'RGB'}32UI topology ({per_face}) + {fmt} table, "
                            f"rows of {1 << tab_log2w} texels", params=int(table.size),
                            flops=levels * (3 * 2 * feats + 40 + (2 * feats if u8 else 0)),
                            fetches=texels + 3 * levels * len(groups),
                            texture_bytes=tex_bytes))
    return out
