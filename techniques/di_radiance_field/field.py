"""The procedural radiance field (numpy, deterministic; no downloads): a soft analytic SDF scene
baked into a DVGO-style density grid and a 12-channel colour grid of degree-1 SH.

Scene ("trinket", inside the unit box [0, 1]^3, the grids' domain):
  - a tilted torus (orange with cream stripes, gold sheen),
  - a smooth union of two spheres (teal, darker toward the bottom, white sheen),
  - a rounded slab with three round holes through it (lilac stone with a soft check, faint sheen).
Materials blend by a soft-min of the primitives' distances, so colour is smooth everywhere.

Density (DVGO-like softness): sigma = SIGMA_SCALE * sigmoid(-sdf / eps), eps = SOFTNESS voxels of
the grid (eps = SOFTNESS / (N - 1)); sigma is stored directly (non-negative, world units^-1: the
march's alpha over a step dt is 1 - exp(-sigma dt)).

Colour: the paper's DVGO with the RGB MLP replaced by "PE + summation + sigmoid" (Datta
et al. 2023, §4.4): per voxel 4 SH coefficients (bands l = 0, 1; inshade.sh basis, index l^2 + l + m) per RGB,
colour(d) = sigmoid(sum_k c_k Y_k(d)) for the ray direction d. The baked logit is
    logit(albedo) + sheen * dot(-d, n)
(n the SDF's unit gradient: brighter where the surface faces the eye, a view-dependent tint),
which is linear in d and so exactly degree-1 SH: c is solved from four tetrahedral directions.
Channel layout: coefficient-major, lane 3 k + c is coefficient k of colour channel c (RGB).

Grid convention: corner-aligned like the lookup arrays (cell i at x = i / (N - 1)), arrays
[N_z, N_y, N_x, C] (x fastest), so a grid is a LookupArray's table as is.
"""
from __future__ import annotations

import numpy as np

from inshade.sh import sh_basis

SIGMA_SCALE = 100.0     # density inside an object (world units^-1)
SOFTNESS = 1.5          # eps in voxels of the grid
SH_DEGREE = 2           # bands: 4 coefficients
COLOUR_CHANNELS = 12    # 4 SH coefficients x RGB
SCENES = ("trinket",)


class FieldError(ValueError):
    """A grid size or scene the field cannot bake (the message names the option)."""


def _torus(p, centre, tilt_deg, major, minor):
    q = p - np.asarray(centre)
    a = np.radians(tilt_deg)
    c, s = np.cos(a), np.sin(a)
    # rotate about x: the torus's axis is y tilted toward z
    y = c * q[..., 1] - s * q[..., 2]
    z = s * q[..., 1] + c * q[..., 2]
    x = q[..., 0]
    ring = np.sqrt(x * x + z * z) - major
    d = np.sqrt(ring * ring + y * y) - minor
    phi = np.arctan2(z, x)
    return d, phi


def _sphere(p, centre, r):
    return np.linalg.norm(p - np.asarray(centre), axis=-1) - r


def _smin(a, b, k):
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return b * (1 - h) + a * h - k * h * (1 - h)


def _slab(p, centre, half, round_r, holes, hole_r):
    q = np.abs(p - np.asarray(centre)) - (np.asarray(half) - round_r)
    box = np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(-1), 0.0) - round_r
    cyl = np.full(p.shape[:-1], np.inf)
    for hx, hz in holes:
        cyl = np.minimum(cyl, np.hypot(p[..., 0] - hx, p[..., 2] - hz) - hole_r)
    return np.maximum(box, -cyl)


def primitives(p: np.ndarray):
    """(distances [3, ...], torus angle [...]) of the scene's three primitives at points p [..., 3]."""
    torus, phi = _torus(p, (0.5, 0.56, 0.5), 28.0, 0.22, 0.062)
    blob = _smin(_sphere(p, (0.5, 0.55, 0.5), 0.105), _sphere(p, (0.63, 0.69, 0.44), 0.065), 0.04)
    slab = _slab(p, (0.5, 0.2, 0.5), (0.34, 0.055, 0.3), 0.02, ((0.29, 0.5), (0.5, 0.38), (0.71, 0.5)), 0.06)
    return np.stack([torus, blob, slab]), phi


def sdf(p: np.ndarray) -> np.ndarray:
    d, _ = primitives(p)
    return d.min(0)


def _normal(p: np.ndarray, h: float = 1e-3) -> np.ndarray:
    g = np.stack([sdf(p + e) - sdf(p - e) for e in np.eye(3) * h], -1)
    return g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-12)


def materials(p: np.ndarray, blend: float = 0.03):
    """(albedo [..., 3] in (0, 1), sheen [..., 3]) at p: each primitive's material blended by a
    soft-min of the distances (weights exp(-d / blend))."""
    d, phi = primitives(p)
    stripe = 0.5 + 0.5 * np.sin(6.0 * phi)
    torus_a = np.stack([0.85 - 0.0 * stripe, 0.32 + 0.45 * stripe, 0.1 + 0.55 * stripe], -1)
    height = np.clip((p[..., 1] - 0.45) / 0.3, 0.0, 1.0)[..., None]
    blob_a = np.array([0.06, 0.3, 0.38]) * (1 - height) + np.array([0.2, 0.7, 0.72]) * height
    check = 0.5 + 0.5 * np.sin(18.0 * p[..., 0]) * np.sin(18.0 * p[..., 2])
    slab_a = np.stack([0.5 + 0.1 * check, 0.42 + 0.08 * check, 0.6 + 0.1 * check], -1)
    sheens = np.array([[1.4, 1.0, 0.35], [1.0, 1.0, 1.0], [0.3, 0.3, 0.3]])
    w = np.exp(-(d - d.min(0)) / blend)
    w = w / w.sum(0)
    albedo = w[0, ..., None] * torus_a + w[1, ..., None] * blob_a + w[2, ..., None] * slab_a
    sheen = np.einsum("k...,kc->...c", w, sheens)
    return albedo, sheen


def _sh_solver() -> tuple[np.ndarray, np.ndarray]:
    """(dirs [4, 3], M [4, 4]) with c = M @ f(dirs) for any f linear in d (exact in degree-1 SH)."""
    dirs = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], np.float64) / np.sqrt(3.0)
    return dirs, np.linalg.inv(sh_basis(dirs, SH_DEGREE))


def colour_coefficients(p: np.ndarray) -> np.ndarray:
    """[..., 12] coefficient-major SH of the colour logit at p (module docstring)."""
    albedo, sheen = materials(p)
    n = _normal(p)
    logit = np.log(albedo / (1.0 - albedo))
    dirs, m = _sh_solver()
    # f_j = logit + sheen * dot(-dir_j, n), c_k = sum_j M[k, j] f_j
    f = logit[..., None, :] + sheen[..., None, :] * (-(n @ dirs.T))[..., None]     # [..., 4 dirs, 3]
    c = np.einsum("kj,...jc->...kc", m, f)                                         # [..., 4 coeffs, 3]
    return c.reshape(*p.shape[:-1], COLOUR_CHANNELS)


def grid_points(n: int) -> np.ndarray:
    """[N, N, N, 3] cell positions (x, y, z) of an N^3 corner-aligned grid, arrays [z, y, x]."""
    a = np.linspace(0.0, 1.0, n)
    z, y, x = np.meshgrid(a, a, a, indexing="ij")
    return np.stack([x, y, z], -1)


def check_resolution(n, where: str = "--grid") -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 8 <= int(n) <= 512:
        raise FieldError(f"{where}: the grid side must be an int in 8..512, got {n!r}")
    return int(n)


def bake(n: int, scene: str = "trinket", chunk: int = 1 << 18):
    """(density [N, N, N] float32, colour [N, N, N, 12] float32) of the scene on an N^3 grid."""
    n = check_resolution(n)
    if scene not in SCENES:
        raise FieldError(f"--scene: unknown scene {scene!r} (known: {', '.join(SCENES)})")
    pts = grid_points(n).reshape(-1, 3)
    eps = SOFTNESS / (n - 1)
    density = np.empty(len(pts), np.float32)
    colour = np.empty((len(pts), COLOUR_CHANNELS), np.float32)
    for s in range(0, len(pts), chunk):
        p = pts[s:s + chunk]
        d = sdf(p)
        density[s:s + chunk] = SIGMA_SCALE / (1.0 + np.exp(np.clip(d / eps, -60.0, 60.0)))
        colour[s:s + chunk] = colour_coefficients(p)
    return density.reshape(n, n, n), colour.reshape(n, n, n, COLOUR_CHANNELS)


def shell_mask(density: np.ndarray, lo: float = 1e-2, hi: float = 0.999) -> np.ndarray:
    """Voxels in the soft surface shell: lo < sigma / SIGMA_SCALE < hi (where renders see colour and
    the density's edge), as a bool [N, N, N]."""
    s = density / SIGMA_SCALE
    return (s > lo) & (s < hi)
