"""The procedural objects' files and texture lookups: ``write_object`` (mesh.obj + the three
textures as 8-bit PNGs, written together), ``read_textures`` (the arrays back, exactly) and
``sample_textures`` (GL's bilinear lookup with clamp-to-edge). The conventions are objects.py's.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from inshade.files import atomic_files
from inshade.geometry.mesh import mesh_uv, obj_text
from inshade.metrics import srgb_eotf, srgb_oetf

from .objects import FILES, TEXTURES, ObjectError, TexturedObject


def _encode(name: str, values: np.ndarray) -> np.ndarray:
    """8-bit PNG pixels of a texture: albedo sRGB-encoded, the others linear."""
    x = srgb_oetf(values) if name == "albedo" else values
    return np.round(np.clip(x, 0.0, 1.0) * 255.0).astype(np.uint8)


def _decode(name: str, pixels: np.ndarray) -> np.ndarray:
    x = pixels.astype(np.float64) / 255.0
    return (srgb_eotf(x) if name == "albedo" else x).astype(np.float32)


def write_object(obj: TexturedObject, folder) -> dict:
    """Write ``folder/mesh.obj`` (v, vt, f v/vt) and the three textures as 8-bit RGB PNGs (image
    order, albedo sRGB-encoded, normal and rma linear), all four atomically together. Returns
    {"mesh" | "albedo" | "normal" | "rma": file name}."""
    missing = [k for k in TEXTURES if k not in obj.textures]
    if missing:
        raise ObjectError(f"textures: missing {', '.join(missing)} (need {', '.join(TEXTURES)})")
    if mesh_uv(obj.mesh) is None:
        raise ObjectError("mesh: has no per-vertex uv (TextureVisuals)")
    for k in TEXTURES:
        _check_texture(k, obj.textures[k])
    folder = Path(folder)
    paths = [folder / FILES[k] for k in ("mesh", *TEXTURES)]
    with atomic_files(*paths) as temps:
        temps[0].write_text(obj_text(obj.mesh))
        for k, tmp in zip(TEXTURES, temps[1:]):
            Image.fromarray(_encode(k, obj.textures[k][..., :3])).save(tmp, format="PNG")
    return dict(FILES)


def read_textures(folder) -> dict:
    """The textures ``write_object`` wrote, as float32 arrays equal to the ones it was given."""
    folder = Path(folder)
    out = {}
    for k in TEXTURES:
        path = folder / FILES[k]
        if not path.is_file():
            raise ObjectError(f"{k}: {path} does not exist")
        out[k] = _decode(k, np.asarray(Image.open(path).convert("RGB"), np.uint8))
    return out


def _check_texture(key: str, tex) -> np.ndarray:
    tex = np.asarray(tex)
    if tex.ndim != 3 or tex.shape[0] < 1 or tex.shape[1] < 1 or tex.shape[2] < 1:
        raise ObjectError(f"textures[{key!r}]: expected [H, W, C], got shape {tex.shape}")
    return tex


def sample_textures(textures: dict, uv) -> dict:
    """Bilinear lookups of every texture at ``uv`` [N, 2]: GL's LINEAR filter with clamp-to-edge
    and no mipmaps, for textures in image order (row 0 = v near 1). Texel (row i, column j) is
    hit exactly at uv ((j + 0.5) / W, 1 - (i + 0.5) / H). Returns {key: [N, C] float32}; the
    weights are float64."""
    uv = np.asarray(uv, np.float64)
    if uv.ndim != 2 or uv.shape[1] != 2:
        raise ObjectError(f"uv: expected [N, 2], got shape {uv.shape}")
    if not np.isfinite(uv).all():
        raise ObjectError(f"uv: {int((~np.isfinite(uv).all(1)).sum())} rows are NaN or infinite")
    out = {}
    for key, tex in textures.items():
        tex = _check_texture(key, tex)
        h, w = tex.shape[:2]
        x = uv[:, 0] * w - 0.5
        y = (1.0 - uv[:, 1]) * h - 0.5                   # image rows count down from v = 1
        x0, y0 = np.floor(x), np.floor(y)
        fx, fy = (x - x0)[:, None], (y - y0)[:, None]
        xa, xb = np.clip(x0, 0, w - 1).astype(np.int64), np.clip(x0 + 1, 0, w - 1).astype(np.int64)
        ya, yb = np.clip(y0, 0, h - 1).astype(np.int64), np.clip(y0 + 1, 0, h - 1).astype(np.int64)
        t = tex.astype(np.float64)
        out[key] = ((1.0 - fy) * ((1.0 - fx) * t[ya, xa] + fx * t[ya, xb])
                    + fy * ((1.0 - fx) * t[yb, xa] + fx * t[yb, xb])).astype(np.float32)
    return out
