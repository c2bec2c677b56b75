"""An 8-lane PBR texture set, the layout every technique that compresses or shades one reads:
albedo RGB (sRGB-encoded), the tangent-space normal stored as 0.5 + 0.5 n (x along +u, y along
+v), roughness and ambient occlusion (``LANES``).

- ``bricks(size)``: the procedural material (no downloads here): a running-bond brick wall,
  periodic in both axes (it tiles on the torus), with per-brick colour, bevelled edges, mortar,
  FFT-filtered noise; normal and AO derived from its height field.
- ``split_rgba8``: the set as the two RGBA8 textures it ships in uncompressed (lanes 0-3, 4-7).
- ``unpack``: the torch twin of lib/pbr_set.glsl pbr_set_unpack (same operations in the same
  order, float32): lanes -> linear albedo, unit tangent-space normal, roughness, AO.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from inshade.metrics import srgb_oetf

# lane groups: name -> (first lane, width); order is the shader's (lib/pbr_set.glsl)
LANES = {"albedo": (0, 3), "normal": (3, 3), "roughness": (6, 1), "ao": (7, 1)}
CHANNELS = 8


class PbrSetError(ValueError):
    """A PBR set or setting that cannot be used; the message says what to change."""


# ---------------------------------------------------------------------------------------------
# the procedural material

@dataclass(frozen=True)
class Bricks:
    rows: int = 8                 # brick courses per tile
    columns: int = 4              # bricks per course
    mortar: float = 0.07          # mortar half-width, in brick heights
    bevel: float = 0.09           # edge rounding, in brick heights
    depth: float = 0.45           # mortar depth relative to the brick face (height units)
    bump: float = 3.0             # normal-map strength (height units per tile -> slope)
    seed: int = 7


def periodic_noise(size: int, scale: float, gen: np.random.Generator) -> np.ndarray:
    """Band-limited noise that tiles: white noise filtered by a Gaussian in the FFT domain
    (features about ``scale`` texels), normalised to zero mean and unit std."""
    f = np.fft.fftfreq(size)
    r2 = f[:, None] ** 2 + f[None, :] ** 2
    spectrum = np.fft.fft2(gen.standard_normal((size, size))) * np.exp(-r2 * (math.pi * scale) ** 2)
    n = np.real(np.fft.ifft2(spectrum))
    return (n - n.mean()) / max(n.std(), 1e-12)


def periodic_blur(a: np.ndarray, sigma: float) -> np.ndarray:
    size = a.shape[0]
    f = np.fft.fftfreq(size)
    kernel = np.exp(-2.0 * (math.pi * sigma) ** 2 * (f[:, None] ** 2 + f[None, :] ** 2))
    return np.real(np.fft.ifft2(np.fft.fft2(a) * kernel))


def bricks(size: int = 256, recipe: Bricks = Bricks()) -> np.ndarray:
    """The set [size, size, 8] float32 in [0, 1], 8-bit values (k / 255), row 0 = top of the
    picture (v = 1); tiles in u and v."""
    if size < 32 or size % recipe.rows:
        raise PbrSetError(f"size {size}: must be >= 32 and a multiple of the {recipe.rows} brick courses")
    gen = np.random.default_rng(recipe.seed)
    # texel centres in [0, 1), v up (row 0 = top)
    u = (np.arange(size) + 0.5) / size
    v = 1.0 - (np.arange(size) + 0.5) / size
    uu, vv = np.meshgrid(u, v)
    course = np.floor(vv * recipe.rows)
    xs = uu * recipe.columns + 0.5 * (course % 2)
    brick_id = (course * recipe.columns + np.floor(xs) % recipe.columns).astype(int)
    fx, fy = xs - np.floor(xs), vv * recipe.rows - course
    aspect = recipe.rows / recipe.columns          # brick width in brick heights
    edge = np.minimum(np.minimum(fx, 1.0 - fx) * aspect, np.minimum(fy, 1.0 - fy))   # in brick heights
    face = np.clip((edge - recipe.mortar) / recipe.bevel, 0.0, 1.0)
    face = face * face * (3.0 - 2.0 * face)        # smoothstep: rounded brick edges
    n_bricks = recipe.rows * recipe.columns
    brick_tilt = gen.normal(0.0, 0.04, n_bricks)[brick_id] * (fx - 0.5)
    grain = periodic_noise(size, 1.5, gen)
    blotch = periodic_noise(size, 12.0, gen)
    height = face * (1.0 + brick_tilt + 0.04 * blotch + 0.004 * grain) + (1.0 - face) * (
        1.0 - recipe.depth + 0.01 * grain)
    height = height - height.min()
    # albedo: per-brick hue/value variation, darker burnt spots, light mortar
    base = np.array([0.55, 0.22, 0.14])
    tint = gen.normal(0.0, 1.0, (n_bricks, 3)) * [0.06, 0.03, 0.02] + gen.normal(0.0, 0.12, (n_bricks, 1))
    brick_rgb = np.clip(base + tint[brick_id] * base / base.max() + 0.05 * blotch[..., None], 0.02, 1.0)
    brick_rgb *= (1.0 - 0.25 * np.clip(periodic_noise(size, 4.0, gen), 0.0, None))[..., None]
    mortar_rgb = np.array([0.62, 0.6, 0.55]) + 0.04 * grain[..., None]
    albedo = face[..., None] * brick_rgb + (1.0 - face[..., None]) * mortar_rgb
    # normal (tangent space, x along +u, y along +v) from periodic central differences
    dh_du = (np.roll(height, -1, 1) - np.roll(height, 1, 1)) * (size / 2.0)
    dh_dv = (np.roll(height, 1, 0) - np.roll(height, -1, 0)) * (size / 2.0)   # row - 1 is +v
    k = recipe.bump / recipe.rows
    n = np.stack([-k * dh_du, -k * dh_dv, np.ones_like(height)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    # AO: cavities below the locally blurred height; roughness: rough mortar, smoother worn faces
    ao = np.clip(1.0 - 2.5 * np.clip(periodic_blur(height, 3.0) - height, 0.0, None), 0.0, 1.0)
    roughness = np.clip(face * (0.55 + 0.12 * blotch + 0.05 * grain) + (1.0 - face) * 0.92, 0.05, 1.0)
    out = np.concatenate([srgb_oetf(albedo), 0.5 + 0.5 * n, roughness[..., None], ao[..., None]], -1)
    return (np.round(np.clip(out, 0.0, 1.0) * 255.0) / 255.0).astype(np.float32)


def split_rgba8(lanes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eight lanes [H, W, 8] in [0, 1] -> the two RGBA8 images (lanes 0-3, 4-7)."""
    a8 = np.round(np.clip(lanes, 0.0, 1.0) * 255.0).astype(np.uint8)
    return np.ascontiguousarray(a8[..., :4]), np.ascontiguousarray(a8[..., 4:])


# ---------------------------------------------------------------------------------------------
# torch twin of lib/pbr_set.glsl pbr_set_unpack

def dot3(a, b):
    """The dot product over the last axis of 3-vectors, in the shaders' operation order."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def srgb_eotf_t(e: torch.Tensor) -> torch.Tensor:
    """lib/colour.glsl srgb_eotf in float32."""
    lo = e / 12.92
    hi = torch.pow((torch.clamp(e, min=0.0) + 0.055) / 1.055, 2.4)
    return torch.where(e <= 0.04045, lo, hi)


def unpack(a: torch.Tensor, b: torch.Tensor) -> dict:
    """pbr_set_unpack: lanes (a = 0-3, b = 4-7, [N, 4] each) -> albedo (linear), unit tangent-space
    normal, roughness, ao."""
    n = torch.stack([a[:, 3], b[:, 0], b[:, 1]], -1) * 2.0 - 1.0
    len2 = dot3(n, n)
    unit = n * torch.rsqrt(torch.clamp(len2, min=1e-30))[:, None]
    up = torch.tensor([0.0, 0.0, 1.0], device=n.device).expand_as(n)
    return {"albedo": srgb_eotf_t(torch.clamp(a[:, :3], 0.0, 1.0)),
            "normal_ts": torch.where((len2 > 1e-12)[:, None], unit, up),
            "roughness": torch.clamp(b[:, 2], 0.0, 1.0), "ao": torch.clamp(b[:, 3], 0.0, 1.0)}
