"""Latent texture pyramids (Real-Time Neural Appearance Models): the bundle-level spec."""
from __future__ import annotations

from inshade.components.spec import ComponentError, ComponentSpec, Param, pos_int, register
from inshade.components.unorm import TABLE_PRECISIONS, range_tensors, table_spec


MAX_LATENT_RES = 1 << 14


def _is_pow2(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_LATENT_RES and v & (v - 1) == 0


def _pyramid_tensors(p, d):
    res, c = p["resolution"], p["channels"]
    levels = {f"level{k}": table_spec((res >> k, res >> k, c), p["precision"]) for k in range(p["levels"])}
    return {**levels, **(range_tensors(c) if p["precision"] == "u8" else {})}


def _pyramid_checks(p, d):
    top = p["resolution"].bit_length()   # log2(res) + 1 levels down to 1x1
    if not 1 <= p["levels"] <= top:
        raise ComponentError(f"param 'levels' of latent_pyramid must be 1..{top} for resolution "
                             f"{p['resolution']}, got {p['levels']}")


register(ComponentSpec(
    "latent_pyramid",
    "latent texture mip pyramid: input (u, v, level); level floored and clamped to [0, levels-1]; "
    "bilinear within that level, texel centres at (i + 0.5) / N, wrap = repeat; "
    "level k is [res >> k, res >> k, channels]",
    {"resolution": Param(int, check=_is_pow2, doc=f"a power of two, at most {MAX_LATENT_RES}"),
     "levels": Param(int, check=pos_int(15)),
     "channels": Param(int, 8, lambda v: isinstance(v, int) and 4 <= v <= 64 and v % 4 == 0,
                       doc="a multiple of 4 from 4 to 64: one RGBA texture per 4"),
     "precision": Param(str, "f32", lambda v: v in TABLE_PRECISIONS,
                        doc="f32, f16 or u8 (8-bit codes, value = offset + scale * q / 255 per channel)")},
    out_dim=lambda p, d: p["channels"],
    tensors=_pyramid_tensors,
    in_dim=lambda p, d: d == 3,
    category="lookup",
    extra_checks=_pyramid_checks,
))
