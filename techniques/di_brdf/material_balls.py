"""Material-ball grid: the torch reference renderer of shaders/passes/material_balls.frag.glsl.

A full-screen grid of analytically ray-traced spheres (orthographic camera looking down -z, no
mesh), each lit by 1-4 point lights, shaded by a BRDF callback. The same operations in the same
order as the GLSL (lib/material_balls.glsl is folded into the pass), so the two agree to float32
rounding (tests/techniques/di_brdf/test_di_brdf.py).

Layout. Pixel centre -> uv = view.xy + (frag / size) * view.zw (the plane2d camera; uv (0, 0)
bottom-left). With `halves` = 2 (analytic | learned side by side) uv.x is split in two and each
half holds the whole grid: side = floor(2 uv.x). Inside a half, X = gx * cols, Y = uv.y * rows give
the ball (col, row) = floor and the in-cell point (x, y) = 2 fract - 1. A ball has radius
BALL_RADIUS; its normal is (x, y, sqrt(R^2 - x^2 - y^2)) / R, the view direction +z, the tangent
(anisotropy axis) (n.z, 0, -n.x) normalised, bitangent n x t. Lights are `LIGHTS` (position in
cell units relative to the ball centre, intensity); radiance = sum_i f(l_i, v) E_i / |L_i - P|^2.

Ball (col, row) reads its material at the grid coordinate (col / (cols - 1), row / (rows - 1)):
exactly the cell corners of a [cols, rows] lookup array (techniques/di_brdf/model.py's `material_textures`).
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.metrics import mse, srgb_oetf

BALL_RADIUS = 0.9
BACKGROUND = 0.02
# (x, y, z, intensity): key (upper left), rim (behind, upper right: grazing light shows sheen and
# Fresnel), fill (lower front), front; cell units, ball at the origin.
LIGHTS = ((-2.0, 2.5, 3.0, 30.0), (2.5, 1.5, -2.0, 20.0), (0.5, -3.0, 2.5, 10.0), (-1.0, -0.5, 4.0, 8.0))
MAX_LIGHTS = len(LIGHTS)


def _f32(x):
    return torch.as_tensor(x, dtype=torch.float32)


def ball_geometry(width: int, height: int, cols: int, rows: int, halves: int = 1, view=(0.0, 0.0, 1.0, 1.0)):
    """Per pixel (image orientation, row 0 = top): dict of side, col, row, inside mask, surface
    point P, frame t, b, n (world) and the grid coordinate of the ball. All float32 / long."""
    j, i = torch.meshgrid(torch.arange(height, dtype=torch.float32), torch.arange(width, dtype=torch.float32),
                          indexing="ij")
    fx, fy = i + 0.5, (height - 1 - j) + 0.5          # gl_FragCoord of image row j
    vw = _f32(view)
    u = vw[0] + (fx / float(width)) * vw[2]
    v = vw[1] + (fy / float(height)) * vw[3]
    inside = (u >= 0.0) & (u <= 1.0) & (v >= 0.0) & (v <= 1.0)
    gx = u * float(halves)
    side = torch.floor(gx)
    gx = gx - side
    X, Y = gx * float(cols), v * float(rows)
    col, row = torch.floor(X), torch.floor(Y)
    x = (X - col) * 2.0 - 1.0
    y = (Y - row) * 2.0 - 1.0
    col = col.clamp(0, cols - 1)
    row = row.clamp(0, rows - 1)
    rr = x * x + y * y
    r2 = BALL_RADIUS * BALL_RADIUS
    inside = inside & (rr < r2)
    z = torch.sqrt(torch.clamp(r2 - rr, min=0.0))
    inv_r = 1.0 / BALL_RADIUS
    n = torch.stack([x * inv_r, y * inv_r, z * inv_r], -1)
    tl = torch.rsqrt(torch.clamp(n[..., 2] * n[..., 2] + n[..., 0] * n[..., 0], min=1e-30))
    t = torch.stack([n[..., 2] * tl, torch.zeros_like(tl), -n[..., 0] * tl], -1)
    b = torch.stack([n[..., 1] * t[..., 2], n[..., 2] * t[..., 0] - n[..., 0] * t[..., 2], -n[..., 1] * t[..., 0]], -1)
    gu = col / float(max(cols - 1, 1))
    gv = row / float(max(rows - 1, 1))
    return {"side": side.long().clamp(0, halves - 1), "col": col.long(), "row": row.long(), "inside": inside,
            "P": torch.stack([x, y, z], -1), "t": t, "b": b, "n": n, "grid": torch.stack([gu, gv], -1)}


def to_local(w, t, b, n):
    return torch.stack([w[..., 0] * t[..., 0] + w[..., 1] * t[..., 1] + w[..., 2] * t[..., 2],
                        w[..., 0] * b[..., 0] + w[..., 1] * b[..., 1] + w[..., 2] * b[..., 2],
                        w[..., 0] * n[..., 0] + w[..., 1] * n[..., 1] + w[..., 2] * n[..., 2]], -1)


def render(width: int, height: int, cols: int, rows: int, shade, lights: int = 1, halves: int = 1,
           view=(0.0, 0.0, 1.0, 1.0)) -> np.ndarray:
    """Linear RGB [H, W, 3]. `shade(geom_masked, l_local, v_local, light_index)` -> f [M, 3] for the
    M covered pixels (geom entries already masked); f includes |n.l| (models/brdf.py convention)."""
    if not 1 <= lights <= MAX_LIGHTS:
        raise ValueError(f"lights must be in 1..{MAX_LIGHTS}, got {lights}")
    g = ball_geometry(width, height, cols, rows, halves, view)
    mask = g["inside"]
    sel = {k: val[mask] for k, val in g.items() if k != "inside"}
    vloc = to_local(torch.tensor([0.0, 0.0, 1.0]).expand_as(sel["n"]), sel["t"], sel["b"], sel["n"])
    acc = torch.zeros(sel["P"].shape[0], 3)
    for k in range(lights):
        lx, ly, lz, e = LIGHTS[k]
        d = torch.tensor([lx, ly, lz], dtype=torch.float32) - sel["P"]
        dist2 = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]
        lw = d * torch.rsqrt(dist2)[..., None]
        lloc = to_local(lw, sel["t"], sel["b"], sel["n"])
        with torch.no_grad():
            f = shade(sel, lloc, vloc, k)
        acc = acc + f * (e / dist2)[..., None]
    out = torch.full((height, width, 3), BACKGROUND)
    out[mask] = acc
    return out.numpy()


def ball_masks(width: int, height: int, cols: int, rows: int, halves: int = 1):
    """(inside [H, W] bool, ball id [H, W] = side * cols * rows + row * cols + col)."""
    g = ball_geometry(width, height, cols, rows, halves)
    ids = g["side"] * cols * rows + g["row"] * cols + g["col"]
    return g["inside"].numpy(), ids.numpy()


def display(linear: np.ndarray) -> np.ndarray:
    """The PSNR domain of the BRDF figures: what a screen shows -- linear radiance clamped to
    [0, 1], sRGB-encoded (float, no 8-bit rounding)."""
    return srgb_oetf(np.clip(linear, 0.0, 1.0))


def ball_psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    """PSNR (dB, peak 1) of two renders over the masked pixels, in the `display` domain."""
    m = mse(display(a), display(b), mask)
    # np.log10, not metrics.psnr_from_mse's math.log10: they can differ in the last bit, and the
    # recorded di_brdf metrics stay bit-identical this way.
    return float("inf") if m == 0 else 10.0 * np.log10(1.0 / m)
