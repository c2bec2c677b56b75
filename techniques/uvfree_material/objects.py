"""Procedural uv-textured objects: the training targets and references of the UV-free material.

Every object is a uv-mapped ``trimesh.Trimesh`` plus three material textures in UV space, made
from seeded noise with no downloads; the same (name, resolution, seed) gives identical arrays.

- ``rock``: a displaced, slightly flattened sphere (fBm value noise), grey-brown with mineral
  specks, lichen patches and darker crevices; mostly dielectric (sparse mica flecks).
- ``fruit``: an apple: a sphere with dimples at the stem and the calyx, red-yellow streaks and
  pale speckles, low roughness, and a small gold-foil label (so metallic is not constant).
- ``stump_low`` / ``stump_high``: one tree stump (bark ridges on the side, growth rings on the
  cut caps) tessellated at ~1.2k and ~15k faces. Textures and uv layout are identical (a function
  of uv only) and every low-poly vertex is a high-poly vertex (same uv, same position).

Conventions (shared by ``make_object``, the PNGs and ``sample_textures``):

- Texture arrays are [H, W, 3] float32, image order: row 0 is the TOP of the picture (v = 1), the
  same order as the PNG files, and the order ``runtime/renderer.py _scene_texture`` uploads
  (it flips rows so GL's uv (0, 0) is the bottom-left texel). Texel (row i, column j) has its
  centre at uv ((j + 0.5) / W, 1 - (i + 0.5) / H).
- ``albedo``: linear RGB; ``normal``: tangent-space normal stored as n * 0.5 + 0.5 (x along the
  tangent = +u, y along the bitangent = +v, z out of the surface); ``rma``: roughness, metallic,
  ambient occlusion. All meshes are right-handed in uv: cross(dP/du, dP/dv) points outward (the
  handedness ``inshade.mesh.vertex_tangents`` reports is +1 everywhere).
- Values are exactly what the 8-bit PNGs hold: albedo = srgb_eotf(k / 255) (stored sRGB-encoded),
  normal and rma = k / 255 (stored linearly), so writing and reading back loses nothing.
- ``normal`` comes from a uv-space height field by finite differences (``normal_from_height``).
- Meshes: centred, y up, inside the unit sphere, faces wound counter-clockwise seen from outside;
  no zero-area faces. uv seams duplicate vertices (equal positions, different uv), as real meshes
  do; welded by position each mesh is closed.

numpy + trimesh + Pillow; no torch.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

from inshade.files import atomic_files
from inshade.mesh import mesh_uv, obj_text
from inshade.metrics import srgb_eotf, srgb_oetf

OBJECTS = ("rock", "fruit", "stump_low", "stump_high")
TEXTURES = ("albedo", "normal", "rma")
FILES = {"mesh": "mesh.obj", "albedo": "albedo.png", "normal": "normal.png", "rma": "rma.png"}
MIN_RESOLUTION, MAX_RESOLUTION = 8, 8192

# (columns around, rows or rings, cap rings): low-poly counts divide the high-poly ones, so every
# low-poly vertex is also a high-poly vertex
_STUMP_TESSELLATION = {"stump_low": (32, 12, 4), "stump_high": (96, 48, 16)}
_SPHERE_TESSELLATION = {"rock": (80, 40), "fruit": (72, 36)}
_SEED_SALT = {"rock": 1, "fruit": 2, "stump": 3}   # the stump's two tessellations share one stream


class ObjectError(ValueError):
    """A bad argument to this module; the message names the field."""


@dataclass
class TexturedObject:
    name: str
    mesh: trimesh.Trimesh        # per-vertex uv in mesh.visual.uv (TextureVisuals)
    textures: dict               # "albedo" / "normal" / "rma": [H, W, 3] float32 (see module doc)


# ---------------------------------------------------------------------------------------------
# noise

class _ValueNoise:
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


def _fbm(noise: _ValueNoise, p: np.ndarray, octaves: int, gain: float = 0.5) -> np.ndarray:
    """Sum of octaves (frequency doubling, amplitude * gain), normalised to about [-1, 1]."""
    total, amp, norm = 0.0, 1.0, 0.0
    for k in range(octaves):
        # a per-octave shift keeps the lattices of successive octaves from lining up
        total = total + amp * noise(p * (2.0 ** k) + 17.31 * k)
        norm += amp
        amp *= gain
    return total / norm


def _smoothstep(a: float, b: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - a) / (b - a), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _mix(a, b, t):
    """Colour blend: a, b [..., 3] (or [3]), t a scalar field [...]."""
    t = np.asarray(t)[..., None] if np.ndim(t) else t
    return np.asarray(a) * (1.0 - t) + np.asarray(b) * t


def _lerp(a, b, t):
    """Scalar-field blend: a, b and t all [...] (or scalars)."""
    return a * (1.0 - t) + b * t


# ---------------------------------------------------------------------------------------------
# uv grids and the texture finishing step

def _texel_uv(resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) [R, R] at the texel centres, image order (row 0 = v near 1)."""
    c = (np.arange(resolution) + 0.5) / resolution
    return np.meshgrid(c, 1.0 - c)


def _latlong_dir(u: np.ndarray, v: np.ndarray) -> np.ndarray:
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


def _quantised(albedo, normal, rough, metal, ao) -> dict:
    """The textures as the 8-bit PNGs will hold them (see the module doc)."""
    def q(x):
        return np.round(np.clip(x, 0.0, 1.0) * 255.0) / 255.0

    return {"albedo": srgb_eotf(q(srgb_oetf(albedo))).astype(np.float32),
            "normal": q(normal * 0.5 + 0.5).astype(np.float32),
            "rma": q(np.stack([rough, metal, ao], -1)).astype(np.float32)}


# ---------------------------------------------------------------------------------------------
# meshes

def _latlong_mesh(nu: int, nv: int, position) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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


def _make_mesh(verts, uv, faces) -> trimesh.Trimesh:
    return trimesh.Trimesh(np.asarray(verts, np.float64), np.asarray(faces, np.int64),
                           visual=trimesh.visual.TextureVisuals(uv=np.asarray(uv, np.float64)), process=False)


# ---------------------------------------------------------------------------------------------
# rock

class _Rock:
    """Shape r(d) = 1 + broad lumps + mid-scale knobs, squashed in y and z; the textures read the
    same fields at the point's direction, so crevices in the mesh are dark in the AO."""

    ANISO = np.array([1.0, 0.74, 0.88])

    def __init__(self, rng):
        self.shape_noise, self.knob_noise = _ValueNoise(rng), _ValueNoise(rng)
        self.tex = [_ValueNoise(rng) for _ in range(6)]
        # the scale and centre come from a fixed dense sampling, not from the mesh or texture size
        uu, vv = np.meshgrid(np.linspace(0, 1, 129), np.linspace(0, 1, 65))
        p = self._raw(_latlong_dir(uu, vv))
        lo, hi = p.reshape(-1, 3).min(0), p.reshape(-1, 3).max(0)
        self.centre = 0.5 * (lo + hi)
        self.scale = 0.92 / np.linalg.norm(p.reshape(-1, 3) - self.centre, axis=1).max()

    def knobs(self, d):
        return _fbm(self.knob_noise, 3.2 * d + 5.0, 3)

    def radius(self, d):
        return 1.0 + 0.30 * _fbm(self.shape_noise, 1.1 * d, 3) + 0.07 * self.knobs(d)

    def _raw(self, d):
        return d * self.radius(d)[..., None] * self.ANISO

    def position(self, u, v):
        return (self._raw(_latlong_dir(u, v)) - self.centre) * self.scale

    def textures(self, resolution):
        u, v = _texel_uv(resolution)
        d = _latlong_dir(u, v)
        n_base, n_speck, n_lichen, n_lichen_edge, n_detail, n_tint = self.tex
        radius = self.radius(d) * self.scale * float(self.ANISO.mean())
        crevice = _smoothstep(0.0, 0.35, -self.knobs(d))                  # where the knobs dip in
        fine = _fbm(n_detail, 22.0 * d, 4)
        height = 0.006 * fine + 0.0025 * _fbm(n_detail, 70.0 * d + 3.0, 2)
        lichen = _smoothstep(0.12, 0.22, _fbm(n_lichen, 3.5 * d, 3) + 0.18 * _fbm(n_lichen_edge, 24.0 * d, 2)
                             + 0.12 * d[..., 1])
        height = height + 0.0015 * lichen
        speck = n_speck(32.0 * d)
        grey, brown = np.array([0.30, 0.29, 0.27]), np.array([0.36, 0.27, 0.19])
        albedo = _mix(grey, brown, _smoothstep(-0.4, 0.4, _fbm(n_base, 2.0 * d, 3)))
        albedo = albedo * (1.0 + 0.08 * np.sin(28.0 * d[..., 1] + 4.0 * _fbm(n_base, 3.0 * d, 2)))[..., None]
        albedo = _mix(albedo, np.array([0.58, 0.56, 0.52]), _smoothstep(0.45, 0.6, speck))     # light minerals
        albedo = _mix(albedo, np.array([0.06, 0.06, 0.06]), _smoothstep(-0.55, -0.7, speck))   # dark grains
        lichen_rgb = _mix(np.array([0.42, 0.48, 0.16]), np.array([0.62, 0.38, 0.10]),
                          _smoothstep(-0.2, 0.2, n_tint(6.0 * d)))
        albedo = _mix(albedo, lichen_rgb, lichen)
        ao = np.clip(1.0 - 0.65 * crevice - 0.35 * _smoothstep(0.0, 0.6, -fine), 0.0, 1.0)
        albedo = albedo * (0.7 + 0.3 * ao)[..., None]                    # dirt collects in crevices
        mica = _smoothstep(0.55, 0.7, speck) * _smoothstep(0.2, 0.5, n_tint(40.0 * d))
        rough = 0.78 + 0.08 * _fbm(n_tint, 9.0 * d, 2) + 0.1 * lichen - 0.4 * mica
        metal = 0.6 * mica * (1.0 - lichen)
        s = np.sin(np.pi * v)
        normal = normal_from_height(height, 2.0 * np.pi * radius * s, np.pi * radius)
        return _quantised(albedo, normal, rough, metal, ao)


# ---------------------------------------------------------------------------------------------
# fruit

class _Fruit:
    """An apple: polar profile with a deep stem dimple (top) and a shallower calyx (bottom),
    five soft lobes near the bottom, slight irregularity."""

    LABEL_DIR = np.array([math.cos(0.5), 0.15, -math.sin(0.5)]) / math.hypot(1.0, 0.15)

    def __init__(self, rng):
        self.shape_noise = _ValueNoise(rng)
        self.tex = [_ValueNoise(rng) for _ in range(5)]

    def radius(self, d):
        t = np.arccos(np.clip(d[..., 1], -1.0, 1.0))                   # 0 at the stem
        phi = np.arctan2(-d[..., 2], d[..., 0])
        r = 1.0 - 0.32 * np.exp(-(t / 0.33) ** 2) - 0.2 * np.exp(-((np.pi - t) / 0.36) ** 2)
        r = r + 0.035 * np.cos(5.0 * phi) * _smoothstep(1.6, 2.6, t) + 0.025 * _fbm(self.shape_noise, 1.5 * d, 2)
        return 0.8 * r * (1.0 + 0.06 * d[..., 1])                       # wider shoulders

    def position(self, u, v):
        d = _latlong_dir(u, v)
        return d * self.radius(d)[..., None] * np.array([1.0, 0.92, 1.0])

    def textures(self, resolution):
        u, v = _texel_uv(resolution)
        d = _latlong_dir(u, v)
        n_blush, n_streak, n_speck, n_grain, n_print = self.tex
        t = np.pi * (1.0 - v)                                           # polar angle from the stem
        radius = self.radius(d)
        # streaks run stem to calyx: the noise is stretched along y (sampled on a circle in u)
        a = 2.0 * np.pi * u
        streak = _fbm(n_streak, np.stack([7.0 * np.cos(a), 7.0 * np.sin(a), 1.2 * t], -1), 3)
        blush = _fbm(n_blush, 1.6 * d, 3) + 0.35 * d[..., 0]
        red_amount = np.clip(_smoothstep(-0.35, 0.25, blush) + 0.45 * streak, 0.0, 1.0)
        albedo = _mix(np.array([0.62, 0.42, 0.05]), np.array([0.42, 0.03, 0.025]), red_amount)
        albedo = _mix(albedo, np.array([0.22, 0.26, 0.05]), np.exp(-(t / 0.3) ** 2))   # green-brown stem cavity
        speck = _smoothstep(0.6, 0.72, n_speck(28.0 * d)) * _smoothstep(0.3, 0.8, t) * _smoothstep(0.3, 0.8, np.pi - t)
        albedo = _mix(albedo, np.array([0.75, 0.62, 0.32]), 0.8 * speck)
        # the label: a rounded oval of gold foil with a dark printed ring
        cos_l = np.clip(np.sum(d * self.LABEL_DIR, -1), -1.0, 1.0)
        dist = np.arccos(cos_l) / 0.2                                    # 1 at the label's edge
        label = _smoothstep(1.0, 0.93, dist)
        ring = label * _smoothstep(0.06, 0.03, np.abs(dist - 0.62))
        ink = label * _smoothstep(0.35, 0.5, n_print(np.array([80.0, 20.0, 80.0]) * d)) * _smoothstep(0.4, 0.3, dist)
        printed = np.maximum(ring, ink)
        albedo = _mix(albedo, np.array([0.9, 0.68, 0.3]), label)
        albedo = _mix(albedo, np.array([0.04, 0.05, 0.08]), printed)
        height = 0.003 * _fbm(n_grain, 20.0 * d, 3) + 0.001 * speck + 0.0008 * label
        rough = 0.28 + 0.06 * _fbm(n_grain, 12.0 * d + 7.0, 2) + 0.25 * speck
        rough = _lerp(rough, 0.22, label)
        rough = _lerp(rough, 0.6, printed)
        metal = label * (1.0 - printed)
        ao = 1.0 - 0.55 * np.exp(-(t / 0.32) ** 2) - 0.35 * np.exp(-((np.pi - t) / 0.3) ** 2)
        normal = normal_from_height(height, 2.0 * np.pi * radius * np.sin(np.pi * v), np.pi * radius)
        return _quantised(albedo, normal, rough, metal, ao)


# ---------------------------------------------------------------------------------------------
# stump

class _Stump:
    """A sawn tree stump: a wobbly cylinder with a root flare, flat-ish cut caps on both ends.

    uv atlas: the side is the strip v in [SIDE_V0, SIDE_V1] (u around, seam at u = 0 / 1, y up);
    the top and bottom caps are disks of radius CAP_R at TOP_C and BOTTOM_C. The texture is split
    at v = SPLIT (side below, the nearer cap above) so each chart's pattern continues a few texels
    past its edge and bilinear lookups near an edge do not pick up a neighbour's colours."""

    Y0, Y1 = -0.45, 0.38
    SIDE_V0, SIDE_V1, SPLIT = 0.01, 0.55, 0.5625
    CAP_R, TOP_C, BOTTOM_C = 0.2, (0.25, 0.775), (0.75, 0.775)

    def __init__(self, rng):
        self.shape_noise = _ValueNoise(rng)
        self.tex = [_ValueNoise(rng) for _ in range(6)]

    def radius(self, u, y):
        a = 2.0 * np.pi * u
        p = np.stack([1.3 * np.cos(a), 1.3 * np.sin(a), 2.2 * y], -1)
        base = 0.46 * (1.0 + 0.06 * _fbm(self.shape_noise, p, 3))
        foot = np.exp(-(y - self.Y0) / 0.12)
        roots = np.maximum(np.cos(5.0 * a + 0.8 * np.sin(3.0 * a)), 0.0) ** 2
        return base + foot * (0.08 + 0.07 * roots)

    def side_position(self, u, y):
        r = self.radius(u, y)
        a = 2.0 * np.pi * u
        return np.stack([r * np.cos(a), y, -r * np.sin(a)], -1)

    def mesh(self, ns: int, nh: int, nr: int):
        u = np.arange(ns + 1) / ns
        y = self.Y0 + (self.Y1 - self.Y0) * (np.arange(nh + 1) / nh)
        uu, yy = np.meshgrid(u, y, indexing="ij")                 # [ns + 1, nh + 1]
        side = self.side_position(uu, yy)
        side[ns] = side[0]                                          # the seam: equal positions exactly
        side_v = self.SIDE_V0 + (self.SIDE_V1 - self.SIDE_V0) * (yy - self.Y0) / (self.Y1 - self.Y0)
        side_uv = np.stack([uu, side_v], -1)
        verts, uvs, faces = [side.reshape(-1, 3)], [side_uv.reshape(-1, 2)], []
        i, j = np.meshgrid(np.arange(ns), np.arange(nh), indexing="ij")
        i, j = i.ravel(), j.ravel()
        v00, v10, v01, v11 = i * (nh + 1) + j, (i + 1) * (nh + 1) + j, i * (nh + 1) + j + 1, (i + 1) * (nh + 1) + j + 1
        faces += [np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)]
        base = (ns + 1) * (nh + 1)
        for top in (True, False):
            rim = side[:ns, nh if top else 0]                       # the rim is the side's end row, exactly
            y_cap = self.Y1 if top else self.Y0
            centre_uv = np.array(self.TOP_C if top else self.BOTTOM_C)
            rho = np.arange(1, nr + 1) / nr
            a = 2.0 * np.pi * np.arange(ns) / ns
            dome = (0.012 if top else -0.006) * (1.0 - rho ** 2)
            ring = rho[:, None, None] * rim[None] * np.array([1.0, 0.0, 1.0])       # [nr, ns, 3]: x, z scaled
            ring[..., 1] = (y_cap + dome)[:, None]
            ring[-1] = rim
            sgn = 1.0 if top else -1.0                              # the bottom cap mirrors v: right-handed from below
            ring_uv = centre_uv + self.CAP_R * rho[:, None, None] * np.stack([np.cos(a), sgn * np.sin(a)], -1)[None]
            centre = np.array([[0.0, y_cap + (0.012 if top else -0.006), 0.0]])
            verts += [centre, ring.reshape(-1, 3)]
            uvs += [centre_uv[None], ring_uv.reshape(-1, 2)]
            c = np.arange(ns)
            cn = (c + 1) % ns

            def rid(k, idx):                                        # ring k (0 = innermost), column idx
                return base + 1 + k * ns + idx

            fan = np.stack([np.full(ns, base), rid(0, c), rid(0, cn)], 1)
            k, cc = np.meshgrid(np.arange(nr - 1), c, indexing="ij")
            k, cc = k.ravel(), cc.ravel()
            ccn = (cc + 1) % ns
            quads = [np.stack([rid(k, cc), rid(k + 1, cc), rid(k + 1, ccn)], 1),
                     np.stack([rid(k, cc), rid(k + 1, ccn), rid(k, ccn)], 1)]
            tri = np.concatenate([fan, *quads])
            faces.append(tri if top else tri[:, ::-1])
            base += 1 + nr * ns
        return np.concatenate(verts), np.concatenate(uvs), np.concatenate(faces)

    def textures(self, resolution):
        u, v = _texel_uv(resolution)
        n_ridge, n_crack, n_moss, n_ring, n_grain, n_tint = self.tex
        # --- side: bark (below SPLIT) ---
        y = self.Y0 + (v - self.SIDE_V0) / (self.SIDE_V1 - self.SIDE_V0) * (self.Y1 - self.Y0)
        a = 2.0 * np.pi * u
        circle = np.stack([np.cos(a), np.sin(a)], -1)

        def on_side(scale_around, scale_up):                       # 3D noise points, periodic in u
            return np.concatenate([scale_around * circle, scale_up * y[..., None]], -1)

        warp = _fbm(n_ridge, on_side(1.5, 3.0), 2)
        ridge_phase = 23.0 * u + 1.2 * warp                        # ~23 vertical ridges around
        ridge = np.abs(np.sin(np.pi * ridge_phase))                # 0 in the furrows
        cracks = _smoothstep(0.55, 0.7, np.abs(n_crack(on_side(9.0, 1.0))))
        bark_h = 0.008 * ridge ** 0.6 - 0.004 * cracks + 0.0015 * _fbm(n_grain, on_side(20.0, 25.0), 2)
        moss = _smoothstep(0.0, 0.25, _fbm(n_moss, on_side(2.5, 5.0), 3) - 1.6 * (y - self.Y0) + 0.15)
        bark_rgb = _mix(np.array([0.10, 0.07, 0.05]), np.array([0.24, 0.19, 0.14]), ridge ** 0.8)
        bark_rgb = bark_rgb * (0.85 + 0.15 * _fbm(n_tint, on_side(14.0, 18.0), 2))[..., None]
        bark_rgb = _mix(bark_rgb, np.array([0.18, 0.26, 0.08]), moss)
        bark_ao = np.clip(0.45 + 0.55 * ridge ** 0.5 - 0.3 * cracks, 0.0, 1.0)
        bark_rough = 0.9 - 0.08 * ridge + 0.05 * moss
        len_side_u = 2.0 * np.pi * self.radius(u, np.clip(y, self.Y0, self.Y1))
        len_side_v = (self.Y1 - self.Y0) / (self.SIDE_V1 - self.SIDE_V0)
        # --- caps: growth rings (above SPLIT; the nearer of the two disks) ---
        top = u < 0.5
        cu = np.where(top, self.TOP_C[0], self.BOTTOM_C[0])
        rx, ry = (u - cu) / self.CAP_R, (v - self.TOP_C[1]) / self.CAP_R     # 1 at the disk's edge
        rho = np.hypot(rx, ry)
        ang = np.arctan2(ry, rx)
        circ = np.stack([np.cos(ang), np.sin(ang)], -1)
        wobble = 0.04 * _fbm(n_ring, np.stack([2.0 * circ[..., 0], 2.0 * circ[..., 1], 4.0 * rho + 5.0 * top], -1), 2)
        rings = 0.5 + 0.5 * np.cos(2.0 * np.pi * 14.0 * (rho + wobble + 0.03 * rho * rho))
        late_wood = _smoothstep(0.75, 0.95, rings)
        crack_noise = n_crack(np.stack([6.0 * np.cos(ang), 6.0 * np.sin(ang), 0.8 * rho + 9.0], -1))
        radial_crack = _smoothstep(0.75, 0.85, np.abs(crack_noise)) * _smoothstep(0.15, 0.4, rho)
        bark_band = _smoothstep(0.9, 0.95, rho)
        wood = _mix(np.array([0.62, 0.46, 0.28]), np.array([0.42, 0.27, 0.14]), late_wood)
        wood = wood * (0.9 + 0.1 * n_tint(np.stack([30.0 * rx, 30.0 * ry, top * 3.0], -1)))[..., None]
        wood = np.where(top[..., None], wood, wood * np.array([0.72, 0.70, 0.66]))   # the bottom: weathered, dirtier
        wood = _mix(wood, np.array([0.06, 0.04, 0.03]), radial_crack)
        wood = _mix(wood, np.array([0.14, 0.10, 0.07]), bark_band)
        cap_h = -0.0008 * late_wood - 0.003 * radial_crack - 0.002 * bark_band
        cap_ao = np.clip(1.0 - 0.6 * radial_crack - 0.15 * bark_band, 0.0, 1.0)
        cap_rough = 0.62 + 0.15 * late_wood + 0.2 * bark_band
        len_cap = 0.5 / self.CAP_R                                  # ~ world radius per uv radius
        # --- assemble ---
        side = v < self.SPLIT
        albedo = np.where(side[..., None], bark_rgb, wood)
        height = np.where(side, bark_h, cap_h)
        len_u = np.where(side, len_side_u, len_cap)
        len_v = np.where(side, len_side_v, len_cap)
        rough = np.where(side, bark_rough, cap_rough)
        ao = np.where(side, bark_ao, cap_ao)
        normal = normal_from_height(height, len_u, len_v)
        return _quantised(albedo, normal, rough, np.zeros_like(rough), ao)


# ---------------------------------------------------------------------------------------------
# the API

def make_object(name: str, resolution: int = 512, seed: int = 0) -> TexturedObject:
    """The object ``name`` (one of ``OBJECTS``) with textures of ``resolution`` x ``resolution``
    (a power of two); deterministic in (name, resolution, seed)."""
    if name not in OBJECTS:
        raise ObjectError(f"name: unknown object {name!r} (known: {', '.join(OBJECTS)})")
    if (isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer))
            or not MIN_RESOLUTION <= resolution <= MAX_RESOLUTION or resolution & (resolution - 1)):
        raise ObjectError(f"resolution: {resolution!r} must be a power of two in {MIN_RESOLUTION}..{MAX_RESOLUTION}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ObjectError(f"seed: {seed!r} must be a non-negative integer")
    family = "stump" if name.startswith("stump") else name
    rng = np.random.default_rng([int(seed), _SEED_SALT[family]])
    if family == "stump":
        stump = _Stump(rng)
        verts, uv, faces = stump.mesh(*_STUMP_TESSELLATION[name])
        textures = stump.textures(int(resolution))
    else:
        shape = (_Rock if family == "rock" else _Fruit)(rng)
        verts, uv, faces = _latlong_mesh(*_SPHERE_TESSELLATION[name], shape.position)
        textures = shape.textures(int(resolution))
    return TexturedObject(name, _make_mesh(verts, uv, faces), textures)


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
