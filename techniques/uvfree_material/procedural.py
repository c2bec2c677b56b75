"""The building blocks of the UV-free material's procedural objects (objects.py): seeded 3D
value noise and its fBm, colour and scalar blends, the texel-centre and lat-long uv grids, tangent-
space normals from uv-space height fields, the textures quantised as their 8-bit PNGs hold them,
and the lat-long sphere mesh. The conventions are objects.py's.
"""
from __future__ import annotations

import numpy as np
import trimesh

from inshade.metrics import srgb_eotf, srgb_oetf


# ---------------------------------------------------------------------------------------------
# noise

class ValueNoise:
    """3D value noise in [-1, 1]: random values on the integer lattice (hashed with a seeded
    permutation, period 256), quintic interpolation between them."""

    def __init__(self, rng: np.random.Generator):
        perm = rng.permutation(256)
        self.perm = np.concatenate([perm, perm])
        self.values = rng.uniform(-1.0, 1.0, 256)

    def __call__(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, np.float64)
        cell = np.floor(p)
        f = p - cell
        w = f * f * f * (f * (f * 6.0 - 15.0) + 10.0)
        c = cell.astype(np.int64) & 255
        out = np.zeros(p.shape[:-1])
        for dx in (0, 1):
            hx = self.perm[(c[..., 0] + dx) & 255]
            wx = w[..., 0] if dx else 1.0 - w[..., 0]
            for dy in (0, 1):
                hy = self.perm[hx + ((c[..., 1] + dy) & 255)]
                wy = wx * (w[..., 1] if dy else 1.0 - w[..., 1])
                for dz in (0, 1):
                    h = self.perm[hy + ((c[..., 2] + dz) & 255)]
                    out += wy * (w[..., 2] if dz else 1.0 - w[..., 2]) * self.values[h]
        return out


def fbm(noise: ValueNoise, p: np.ndarray, octaves: int, gain: float = 0.5) -> np.ndarray:
    """Sum of octaves (frequency doubling, amplitude * gain), normalised to about [-1, 1]."""
    total, amp, norm = 0.0, 1.0, 0.0
    for k in range(octaves):
        # a per-octave shift keeps the lattices of successive octaves from lining up
        total = total + amp * noise(p * (2.0 ** k) + 17.31 * k)
        norm += amp
        amp *= gain
    return total / norm


def smoothstep(a: float, b: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - a) / (b - a), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def mix(a, b, t):
    """Colour blend: a, b [..., 3] (or [3]), t a scalar field [...]."""
    t = np.asarray(t)[..., None] if np.ndim(t) else t
    return np.asarray(a) * (1.0 - t) + np.asarray(b) * t


def lerp(a, b, t):
    """Scalar-field blend: a, b and t all [...] (or scalars)."""
    return a * (1.0 - t) + b * t


# ---------------------------------------------------------------------------------------------
# uv grids and the texture finishing step

def texel_uv(resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) [R, R] at the texel centres, image order (row 0 = v near 1)."""
    c = (np.arange(resolution) + 0.5) / resolution
    return np.meshgrid(c, 1.0 - c)


def latlong_dir(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The unit direction for lat-long uv: u around +y (x = cos, z = -sin), v from the south pole
    (v = 0, y = -1) to the north pole; right-handed: cross(d/du, d/dv) points outward."""
    s = np.sin(np.pi * v)
    return np.stack([s * np.cos(2.0 * np.pi * u), -np.cos(np.pi * v), -s * np.sin(2.0 * np.pi * u)], -1)


def normal_from_height(height: np.ndarray, len_u, len_v) -> np.ndarray:
    """Unit tangent-space normals [H, W, 3] (x along +u, y along +v, z out) of a height field
    [H, W] in image order (row 0 = v near 1; world units along the surface normal), by central
    differences on the texel grid: periodic in u (lat-long and the stump side wrap), one-sided at
    the top and bottom rows. ``len_u`` / ``len_v`` (scalars or [H, W]): surface length per unit
    of u / v, so a bump of a given height tilts the normal alike wherever the uv is stretched:
    n = normalize(-dh/du / len_u, -dh/dv / len_v, 1)."""
    rows, cols = height.shape
    dh_du = (np.roll(height, -1, 1) - np.roll(height, 1, 1)) * (cols / 2.0)
    padded = np.pad(height, ((1, 1), (0, 0)), mode="edge")
    dh_dv = (padded[:-2] - padded[2:]) * (rows / 2.0)       # the row above (i - 1) is +v
    dh_dv[[0, -1]] *= 2.0                                  # one-sided there: half the span
    n = np.stack([-dh_du / np.maximum(len_u, 1e-6), -dh_dv / np.maximum(len_v, 1e-6), np.ones_like(height)], -1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def quantised(albedo, normal, rough, metal, ao) -> dict:
    """The textures as the 8-bit PNGs will hold them (see the module doc)."""
    def q(x):
        return np.round(np.clip(x, 0.0, 1.0) * 255.0) / 255.0

    return {"albedo": srgb_eotf(q(srgb_oetf(albedo))).astype(np.float32),
            "normal": q(normal * 0.5 + 0.5).astype(np.float32),
            "rma": q(np.stack([rough, metal, ao], -1)).astype(np.float32)}


# ---------------------------------------------------------------------------------------------
# meshes

def latlong_mesh(nu: int, nv: int, position) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A lat-long sphere of ``nu`` columns and ``nv`` rows, each vertex at ``position(u, v)``.
    The u = 0 / u = 1 seam column is duplicated and each pole is one vertex per column (uv at the
    column's middle), so every face has a proper uv triangle and a non-zero area."""
    u = np.arange(nu + 1) / nu
    v = np.arange(1, nv) / nv
    uu, vv = np.meshgrid(u, v, indexing="ij")                   # [nu + 1, nv - 1]
    pos = position(uu, vv)
    pos[nu] = pos[0]                                            # the seam: equal positions exactly
    ring = (np.arange(nu) + 0.5) / nu
    south = np.repeat(position(np.zeros(1), np.zeros(1)), nu, 0)
    north = np.repeat(position(np.zeros(1), np.ones(1)), nu, 0)
    verts = np.concatenate([pos.reshape(-1, 3), south, north])
    uv = np.concatenate([np.stack([uu, vv], -1).reshape(-1, 2),
                         np.stack([ring, np.zeros(nu)], -1), np.stack([ring, np.ones(nu)], -1)])
    rows = nv - 1

    def vid(i, j):                                              # j: 0 .. nv - 2 (interior rows)
        return i * rows + j

    i, j = np.meshgrid(np.arange(nu), np.arange(rows - 1), indexing="ij")
    i, j = i.ravel(), j.ravel()
    v00, v10, v01, v11 = vid(i, j), vid(i + 1, j), vid(i, j + 1), vid(i + 1, j + 1)
    c = np.arange(nu)
    s0, n0 = (nu + 1) * rows, (nu + 1) * rows + nu
    faces = np.concatenate([
        np.stack([s0 + c, vid(c + 1, 0), vid(c, 0)], 1),            # south cap
        np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1),  # counter-clockwise from outside
        np.stack([vid(c, rows - 1), vid(c + 1, rows - 1), n0 + c], 1),   # north cap
    ])
    return verts, uv, faces


def make_mesh(verts, uv, faces) -> trimesh.Trimesh:
    return trimesh.Trimesh(np.asarray(verts, np.float64), np.asarray(faces, np.int64),
                           visual=trimesh.visual.TextureVisuals(uv=np.asarray(uv, np.float64)), process=False)
