"""Differentiable Indirection arrays as textures: the emitter (lowered code calling the lookups of
lookup_array.glsl and its .wgsl / .hlsl / .vulkan.glsl versions); torch twin in torch_twin.py.

Each group of 4 channels is one texture: 1D and 2D arrays are 2D textures (a 1D array is
N x 1, since ES has no sampler1D), 3D arrays are 3D textures, 4D arrays are 3D textures of
N0 x N1 x (N2 * N3) read with two fetches and a mix. Texel format follows the quantisation:
8 bits -> unorm8, 16 -> unorm16, 32 -> float32; quantised cells are rescaled after the lookup
(offset + scale * t commutes with interpolation).

Layouts are chosen against the context's limits (codegen/limits.py, ``choose_layout``): the
natural layout above whenever it fits; a 4D array whose folded depth exceeds
GL_MAX_3D_TEXTURE_SIZE folds its w blocks along y or x instead (both paths); on the exact path,
any array whose texture would exceed its limit is wrapped, cells in C order, into rows of a 2D
texture (index math in lookup_array.glsl, *_wrapped); otherwise LimitError. The fast path
never wraps: hardware filtering would mix cells across the wrap seam.

Option ``lookup_array.filter`` (``lut_filter`` for short): "exact" = texelFetch + fp32 mix (matches torch to fp32 rounding);
"fast" = hardware linear filtering (fewer instructions; filter weights may have as few as
8 fractional bits, see tests/components/test_lookup_array.py for the measured bound).
"""
from __future__ import annotations

import numpy as np

from inshade.codegen import ir
from inshade.codegen.glsl import PlanRow, TextureResource
from inshade.codegen.limits import LimitError, limit, source
from inshade.codegen.registry import emitter
from inshade.codegen.values import declare, swizzle
from inshade.components.lookup_array.spec import FILTERS

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


def _dims(res) -> str:
    return "x".join(map(str, res))


def _native_shape(res) -> tuple:
    """Texture size (w, h[, depth]) of the natural layout: 1D -> N0 x 1, 2D -> N0 x N1,
    3D -> N0 x N1 x N2, 4D -> N0 x N1 x (N2 * N3)."""
    d = len(res)
    if d == 1:
        return (res[0], 1)
    if d == 2:
        return (res[0], res[1])
    if d == 3:
        return tuple(res)
    return (res[0], res[1], res[2] * res[3])


def choose_layout(node_id: str, res, lut_filter: str, limits: dict) -> dict:
    """The texture layout of one lookup array under the context's limits.

    kind "native": the natural layout (module docstring), when it fits.
    kind "fold":   4D only, the w slice blocks stacked along x or y instead of z (both paths).
    kind "wrap":   exact path only, cells in C order wrapped into rows of a 2D texture.
    Raises LimitError when nothing fits (the fast path cannot wrap: hardware filtering would
    mix cells across the wrap seam)."""
    d = len(res)
    max2, max3 = limit(limits, "GL_MAX_TEXTURE_SIZE"), limit(limits, "GL_MAX_3D_TEXTURE_SIZE")
    name, cap = ("GL_MAX_3D_TEXTURE_SIZE", max3) if d >= 3 else ("GL_MAX_TEXTURE_SIZE", max2)
    native = _native_shape(res)
    if max(native) <= cap:
        return dict(kind="native", shape=native, why="")
    axes = "xyz"[:len(native)]
    over = ", ".join(f"{a} = {v}" for a, v in zip(axes, native) if v > cap)
    cells = _dims(res) + ("" if d == 1 else f" = {int(np.prod(res))}")
    need = (f"node {node_id}: {d}D lookup array of {cells} cells needs a "
            f"{'x'.join(map(str, native))} texture ({over}); {name} is {cap} ({source(limits, name)})")
    if d == 4:
        for axis in (1, 0):   # fold the w blocks along y, then x
            shape = list(res[:3])
            shape[axis] *= res[3]
            if max(shape) <= cap:
                return dict(kind="fold", shape=tuple(shape), axis=axis,
                            why=f"{need}: w blocks folded along {'xy'[axis]} instead, "
                                f"{'x'.join(map(str, shape))} texture")
    if lut_filter != "exact":
        raise LimitError(f"{need}; the {lut_filter} path filters in hardware and cannot wrap the "
                         "array across texture rows (use lookup_array.filter='exact', which can)")
    total = int(np.prod(res))
    width = min(total, max2)
    height = -(-total // width)
    if height > max2:
        raise LimitError(f"{need}; wrapped into rows of a 2D texture it would need {width}x{height}, "
                         f"and GL_MAX_TEXTURE_SIZE is {max2} ({source(limits, 'GL_MAX_TEXTURE_SIZE')})")
    return dict(kind="wrap", shape=(width, height),
                why=f"{need}: cells wrapped into {height} rows of a {width}x{height} 2D texture")


def layout_groups(cells: np.ndarray, layout: dict):
    """texture_groups for a layout from choose_layout."""
    if layout["kind"] == "native":
        return texture_groups(cells)
    c = cells.shape[-1]
    if layout["kind"] == "fold":
        n3, n2, n1, n0 = cells.shape[:4]
        if layout["axis"] == 1:   # [N2, N3 * N1, N0]: y = i3 * N1 + i1
            cells = cells.transpose(1, 0, 2, 3, 4).reshape(n2, n3 * n1, n0, c)
        else:                     # [N2, N1, N3 * N0]: x = i3 * N0 + i0
            cells = cells.transpose(1, 2, 0, 3, 4).reshape(n2, n1, n3 * n0, c)
    else:
        width, height = layout["shape"]
        flat = np.zeros((width * height, c), cells.dtype)
        flat[:cells.size // c] = cells.reshape(-1, c)
        cells = flat.reshape(height, width, c)
    return [np.ascontiguousarray(cells[..., g:g + 4]) for g in range(0, c, 4)]


def _ints(values) -> ir.Expr:
    """An int (one value) or ivecN of integer literals."""
    items = tuple(ir.Int(str(v)) for v in values)
    return items[0] if len(items) == 1 else ir.Vector(f"ivec{len(items)}", items)


@emitter("lookup_array", options={"filter": (FILTERS, "exact")}, lowered=True)
def emit_lookup_array(ctx, node, src, bundle):
    ctx.include("lookup_array/lookup_array")
    lut_filter = ctx.option("lookup_array", "filter")
    p = node.params
    res, d, bits = p["resolution"], len(p["resolution"]), p["bits"]
    layout = choose_layout(node.id, res, lut_filter, ctx.limits)
    cells = bundle.tensor(node, "cells")
    out = declare(ctx, f"v_{node.id}", node.out_dim)
    dims = 3 if d >= 3 and layout["kind"] != "wrap" else 2
    fn = f"inshade_lut{d}_{lut_filter}"
    size = [_ints(res)]
    if layout["kind"] == "fold":
        fn += "_fold"
        size.append(_ints(int(a == layout["axis"]) for a in range(3)))
    elif layout["kind"] == "wrap":
        fn += "_wrapped"
        size.append(ir.Int(str(layout["shape"][0])))
    coord = swizzle(src, d)
    if bits != 32:
        scale, offset = bundle.tensor(node, "scale"), bundle.tensor(node, "offset")
    tex_bytes = 0
    groups = layout_groups(cells, layout)
    filtered = lut_filter == "fast"
    for g, data in enumerate(groups):
        tname = ctx.name(node.id, f"t{g}")
        ctx.globals.append(ir.Texture(tname, f"{node.id}: {'x'.join(map(str, res))} cells, "
                                      f"channels {4 * g}..{4 * g + data.shape[-1] - 1}, {bits}-bit"
                                      + ("" if layout["kind"] == "native"
                                         else f", {layout['kind']} {'x'.join(map(str, layout['shape']))}"),
                                      dims, filtered))
        ctx.resources.append(TextureResource(tname, data, _DTYPE[bits], "linear" if filtered else "nearest"))
        tex_bytes += data.size * _BYTES[bits]
        expr = ir.Call(fn, (ir.TextureArg(tname, filtered), *size, coord))
        if bits != 32:
            sl = np.zeros(4, np.float32)
            ol = np.zeros(4, np.float32)
            k = data.shape[-1]
            sl[:k], ol[:k] = scale[4 * g:4 * g + k], offset[4 * g:4 * g + k]
            expr = ir.Bin("+", ir.Vec4.of(ol), ir.Bin("*", ir.Vec4.of(sl), expr))
        ctx.body.append(ir.Assign(out.block_ir(g), expr))
    fetches = {"exact": 1 << d, "fast": 2 if d == 4 else 1}[lut_filter] * len(groups)
    storage = f"texture/{lut_filter}" + ("" if layout["kind"] == "native" else f" ({layout['kind']})")
    ctx.plan.append(PlanRow(node.id, "lookup_array", f"{'x'.join(map(str, res))}x{p['channels']} ({bits}-bit)",
                            storage, layout["why"] or f"{bits}-bit cells -> {_DTYPE[bits]} texels",
                            params=int(cells.size), flops=(2 ** d) * 2 * node.out_dim,
                            fetches=fetches, texture_bytes=tex_bytes))
    return out
