"""Tables as 2D textures whose rows are 2^n texels wide (the largest power of two that fits
GL_MAX_TEXTURE_SIZE, or less for small data): item `index` is texel (index & (W-1), index >> n)
(shaders/lib/texture_rows.glsl reads them), so a table longer than one texture row still fits."""
from __future__ import annotations

import numpy as np

from . import ir
from .glsl import TextureResource
from .limits import LimitError, limit, source

# precision -> texels (moderngl dtype, numpy dtype, format suffix); "u8": unorm8, the shader reads q / 255
FLOAT_FORMATS = {"f16": ("f2", np.float16, "16F"), "f32": ("f4", np.float32, "32F"), "u8": ("f1", np.uint8, "8")}
CHANNELS = {1: "R", 2: "RG", 4: "RGBA"}


def row_layout(node_id: str, what: str, items: int, limits: dict) -> tuple[int, int]:
    """(log2 of the row width, rows) for `items` texels; LimitError when they cannot fit."""
    name = "GL_MAX_TEXTURE_SIZE"
    cap = limit(limits, name)
    log2w = min(cap.bit_length() - 1, max(1, (items - 1).bit_length()))
    rows = -(-items // (1 << log2w))
    if rows > cap:
        raise LimitError(f"node {node_id}: the {what} needs {items} texels, {1 << log2w}x{rows} in rows; "
                         f"{name} is {cap} ({source(limits, name)})")
    return log2w, rows


def rows_data(data: np.ndarray, log2w: int, rows: int) -> np.ndarray:
    """[items, C] -> [rows, 2^log2w, C], zero-padded."""
    out = np.zeros((rows << log2w, data.shape[1]), data.dtype)
    out[:data.shape[0]] = data
    return out.reshape(rows, 1 << log2w, data.shape[1])


def feature_textures(ctx, node_id: str, table: np.ndarray, precision: str, log2w: int, rows: int,
                     what: str) -> list[tuple[str, int]]:
    """A [items, F] feature table as one texture per 4 features (F = 8: two RGBA; 4: RGBA; 2: RG;
    1: R) in rows of 2^log2w texels, RGBA16F-family for precision f16, 32F for f32, unorm RGBA8
    for u8 (the table is then the uint8 codes; the caller applies its affine decode): declared and
    added to ctx's resources. Returns (sampler name, channels) per texture."""
    fdtype, np_dtype, _ = FLOAT_FORMATS[precision]
    feats, groups = table.shape[1], []
    for g in range(-(-feats // 4)):
        width = min(4, feats - 4 * g)
        name = ctx.name(node_id, f"table{g}")
        data = np.ascontiguousarray(table[:, 4 * g:4 * g + width], dtype=np_dtype)
        ctx.globals.append(ir.Texture(name, f"{node_id}: features {4 * g}..{4 * g + width - 1} of {what}, {precision}"))
        ctx.resources.append(TextureResource(name, rows_data(data, log2w, rows), fdtype))
        groups.append((name, width))
    return groups


def texture_formats(groups, precision: str) -> str:
    """e.g. "RG16F" or "RGBA32F + RGBA32F" for the plan."""
    return " + ".join(f"{CHANNELS[w]}{FLOAT_FORMATS[precision][2]}" for _, w in groups)


def unorm_decoded(fetch: ir.Expr, scale: np.ndarray, offset: np.ndarray, first: int) -> ir.Expr:
    """A u8 table's lanes ``first``..``first + 3`` decoded from ``fetch`` (a vec4 of unit values q / 255,
    or their convex blend): offset + scale * fetch, the bundle's float32 range as vec4 literals."""
    lanes = lambda a: np.pad(a[first:first + 4], (0, 4 - len(a[first:first + 4])))  # noqa: E731
    return ir.Bin("+", ir.Vec4.of(lanes(offset)), ir.Bin("*", ir.Vec4.of(lanes(scale)), fetch))


def store_group(ctx, out, first: int, width: int, fetch: ir.Expr, scratch: str) -> None:
    """Lanes ``first``.. of ``out`` from one texture's ``fetch`` (a vec4 expression): a whole block
    where the texture is RGBA (``first`` is then a multiple of 4), else through the vec4 ``scratch``."""
    if width == 4:
        ctx.body.append(ir.Assign(out.block_ir(first // 4), fetch))
        return
    ctx.body.append(ir.Assign(ir.Var(scratch), fetch))
    ctx.body += [ir.Assign(out.lane_ir(first + ch), ir.Lane(ir.Var(scratch), ch)) for ch in range(width)]
