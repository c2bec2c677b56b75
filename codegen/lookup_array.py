"""Differentiable Indirection arrays as textures; torch twin in models/lookup_array.py.

Each group of 4 channels is one texture: 1D and 2D arrays are 2D textures (a 1D array is
N x 1, since ES has no sampler1D), 3D arrays are 3D textures, 4D arrays are 3D textures of
N0 x N1 x (N2 * N3) read with two fetches and a mix. Texel format follows the quantisation:
8 bits -> unorm8, 16 -> unorm16, 32 -> float32; quantised cells are rescaled after the lookup
(offset + scale * t commutes with interpolation).

Option ``lookup_array.filter`` (``lut_filter`` for short): "exact" = texelFetch + fp32 mix (matches torch to fp32 rounding);
"fast" = hardware linear filtering (fewer instructions; filter weights may have as few as
8 fractional bits, see tests/test_lookup_array.py for the measured bound).
"""
from __future__ import annotations

import numpy as np

from .glsl import PlanRow, TextureResource, vec4
from .registry import emitter
from .values import declare, swizzle_vec

FILTERS = ("exact", "fast")
_DTYPE = {8: "f1", 16: "nu2", 32: "f4"}
_BYTES = {8: 1, 16: 2, 32: 4}


def texture_groups(cells: np.ndarray):
    """cells [N_{d-1}..N_0, C] -> list of texel arrays (<= 4 channels each), 4D folded to 3D."""
    d = cells.ndim - 1
    if d == 1:
        cells = cells[None]                       # [1, N0, C]
    elif d == 4:
        n3, n2, n1, n0, c = cells.shape
        cells = cells.reshape(n3 * n2, n1, n0, c)  # z = i3 * N2 + i2
    return [np.ascontiguousarray(cells[..., g:g + 4]) for g in range(0, cells.shape[-1], 4)]


@emitter("lookup_array", options={"filter": (FILTERS, "exact")})
def emit_lookup_array(ctx, node, src, bundle):
    ctx.include("lib/lookup_array")
    lut_filter = ctx.option("lookup_array", "filter")
    p = node.params
    res, d, bits = p["resolution"], len(p["resolution"]), p["bits"]
    cells = bundle.tensor(node, "cells")
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    sampler = "sampler3D" if d >= 3 else "sampler2D"
    fn = f"inshade_lut{d}_{lut_filter}"
    n = ", ".join(str(v) for v in res)
    size = str(res[0]) if d == 1 else f"ivec{d}({n})"
    coord = swizzle_vec(src, d)
    if bits != 32:
        scale, offset = bundle.tensor(node, "scale"), bundle.tensor(node, "offset")
    tex_bytes = 0
    for g, data in enumerate(texture_groups(cells)):
        tname = ctx.name(node.id, f"t{g}")
        ctx.globals.append(f"uniform {sampler} {tname};  // {node.id}: {'x'.join(map(str, res))} cells, "
                           f"channels {4 * g}..{4 * g + data.shape[-1] - 1}, {bits}-bit")
        filt = "linear" if lut_filter == "fast" else "nearest"
        ctx.resources.append(TextureResource(tname, data, _DTYPE[bits], filt))
        tex_bytes += data.size * _BYTES[bits]
        expr = f"{fn}({tname}, {size}, {coord})"
        if bits != 32:
            sl = np.zeros(4, np.float32)
            ol = np.zeros(4, np.float32)
            k = data.shape[-1]
            sl[:k], ol[:k] = scale[4 * g:4 * g + k], offset[4 * g:4 * g + k]
            expr = f"{vec4(ol)} + {vec4(sl)} * {expr}"
        ctx.body.append(f"{out.array}[{g}] = {expr};")
    fetches = {"exact": 1 << d, "fast": 2 if d == 4 else 1}[lut_filter] * len(texture_groups(cells))
    ctx.plan.append(PlanRow(node.id, "lookup_array", f"{'x'.join(map(str, res))}x{p['channels']} ({bits}-bit)",
                            f"texture/{lut_filter}", f"{bits}-bit cells -> {_DTYPE[bits]} texels",
                            params=int(cells.size), flops=(2 ** d) * 2 * node.out_dim,
                            fetches=fetches, texture_bytes=tex_bytes))
    return out
