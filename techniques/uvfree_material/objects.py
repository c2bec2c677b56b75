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
  same order as the PNG files, and the order ``runtime/scene_inputs.py scene_texture`` uploads
  (it flips rows so GL's uv (0, 0) is the bottom-left texel). Texel (row i, column j) has its
  centre at uv ((j + 0.5) / W, 1 - (i + 0.5) / H).
- ``albedo``: linear RGB; ``normal``: tangent-space normal stored as n * 0.5 + 0.5 (x along the
  tangent = +u, y along the bitangent = +v, z out of the surface); ``rma``: roughness, metallic,
  ambient occlusion. All meshes are right-handed in uv: cross(dP/du, dP/dv) points outward (the
  handedness ``inshade.geometry.mesh.vertex_tangents`` reports is +1 everywhere).
- Values are exactly what the 8-bit PNGs hold: albedo = srgb_eotf(k / 255) (stored sRGB-encoded),
  normal and rma = k / 255 (stored linearly), so writing and reading back loses nothing.
- ``normal`` comes from a uv-space height field by finite differences (``normal_from_height``).
- Meshes: centred, y up, inside the unit sphere, faces wound counter-clockwise seen from outside;
  no zero-area faces. uv seams duplicate vertices (equal positions, different uv), as real meshes
  do; welded by position each mesh is closed.

The building blocks (noise, uv grids, normals from heights, the lat-long mesh) are in
procedural.py; the files and the texture lookup (``write_object``, ``read_textures``,
``sample_textures``) in object_textures.py. numpy + trimesh; no torch.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from .procedural import (
    ValueNoise, fbm, latlong_dir, latlong_mesh, lerp, make_mesh, mix, normal_from_height, quantised, smoothstep,
    texel_uv)

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
    """A bad argument to the objects or their files (object_textures.py); the message names the field."""


@dataclass
class TexturedObject:
    name: str
    mesh: trimesh.Trimesh        # per-vertex uv in mesh.visual.uv (TextureVisuals)
    textures: dict               # "albedo" / "normal" / "rma": [H, W, 3] float32 (see module doc)


# ---------------------------------------------------------------------------------------------
# rock

class _Rock:
    """Shape r(d) = 1 + broad lumps + mid-scale knobs, squashed in y and z; the textures read the
    same fields at the point's direction, so crevices in the mesh are dark in the AO."""

    ANISO = np.array([1.0, 0.74, 0.88])

    def __init__(self, rng):
        self.shape_noise, self.knob_noise = ValueNoise(rng), ValueNoise(rng)
        self.tex = [ValueNoise(rng) for _ in range(6)]
        # the scale and centre come from a fixed dense sampling, not from the mesh or texture size
        uu, vv = np.meshgrid(np.linspace(0, 1, 129), np.linspace(0, 1, 65))
        p = self._raw(latlong_dir(uu, vv))
        lo, hi = p.reshape(-1, 3).min(0), p.reshape(-1, 3).max(0)
        self.centre = 0.5 * (lo + hi)
        self.scale = 0.92 / np.linalg.norm(p.reshape(-1, 3) - self.centre, axis=1).max()

    def knobs(self, d):
        return fbm(self.knob_noise, 3.2 * d + 5.0, 3)

    def radius(self, d):
        return 1.0 + 0.30 * fbm(self.shape_noise, 1.1 * d, 3) + 0.07 * self.knobs(d)

    def _raw(self, d):
        return d * self.radius(d)[..., None] * self.ANISO

    def position(self, u, v):
        return (self._raw(latlong_dir(u, v)) - self.centre) * self.scale

    def textures(self, resolution):
        u, v = texel_uv(resolution)
        d = latlong_dir(u, v)
        n_base, n_speck, n_lichen, n_lichen_edge, n_detail, n_tint = self.tex
        radius = self.radius(d) * self.scale * float(self.ANISO.mean())
        crevice = smoothstep(0.0, 0.35, -self.knobs(d))                  # where the knobs dip in
        fine = fbm(n_detail, 22.0 * d, 4)
        height = 0.006 * fine + 0.0025 * fbm(n_detail, 70.0 * d + 3.0, 2)
        lichen = smoothstep(0.12, 0.22, fbm(n_lichen, 3.5 * d, 3) + 0.18 * fbm(n_lichen_edge, 24.0 * d, 2)
                             + 0.12 * d[..., 1])
        height = height + 0.0015 * lichen
        speck = n_speck(32.0 * d)
        grey, brown = np.array([0.30, 0.29, 0.27]), np.array([0.36, 0.27, 0.19])
        albedo = mix(grey, brown, smoothstep(-0.4, 0.4, fbm(n_base, 2.0 * d, 3)))
        albedo = albedo * (1.0 + 0.08 * np.sin(28.0 * d[..., 1] + 4.0 * fbm(n_base, 3.0 * d, 2)))[..., None]
        albedo = mix(albedo, np.array([0.58, 0.56, 0.52]), smoothstep(0.45, 0.6, speck))     # light minerals
        albedo = mix(albedo, np.array([0.06, 0.06, 0.06]), smoothstep(-0.55, -0.7, speck))   # dark grains
        lichen_rgb = mix(np.array([0.42, 0.48, 0.16]), np.array([0.62, 0.38, 0.10]),
                          smoothstep(-0.2, 0.2, n_tint(6.0 * d)))
        albedo = mix(albedo, lichen_rgb, lichen)
        ao = np.clip(1.0 - 0.65 * crevice - 0.35 * smoothstep(0.0, 0.6, -fine), 0.0, 1.0)
        albedo = albedo * (0.7 + 0.3 * ao)[..., None]                    # dirt collects in crevices
        mica = smoothstep(0.55, 0.7, speck) * smoothstep(0.2, 0.5, n_tint(40.0 * d))
        rough = 0.78 + 0.08 * fbm(n_tint, 9.0 * d, 2) + 0.1 * lichen - 0.4 * mica
        metal = 0.6 * mica * (1.0 - lichen)
        s = np.sin(np.pi * v)
        normal = normal_from_height(height, 2.0 * np.pi * radius * s, np.pi * radius)
        return quantised(albedo, normal, rough, metal, ao)


# ---------------------------------------------------------------------------------------------
# fruit

class _Fruit:
    """An apple: polar profile with a deep stem dimple (top) and a shallower calyx (bottom),
    five soft lobes near the bottom, slight irregularity."""

    LABEL_DIR = np.array([math.cos(0.5), 0.15, -math.sin(0.5)]) / math.hypot(1.0, 0.15)

    def __init__(self, rng):
        self.shape_noise = ValueNoise(rng)
        self.tex = [ValueNoise(rng) for _ in range(5)]

    def radius(self, d):
        t = np.arccos(np.clip(d[..., 1], -1.0, 1.0))                   # 0 at the stem
        phi = np.arctan2(-d[..., 2], d[..., 0])
        r = 1.0 - 0.32 * np.exp(-(t / 0.33) ** 2) - 0.2 * np.exp(-((np.pi - t) / 0.36) ** 2)
        r = r + 0.035 * np.cos(5.0 * phi) * smoothstep(1.6, 2.6, t) + 0.025 * fbm(self.shape_noise, 1.5 * d, 2)
        return 0.8 * r * (1.0 + 0.06 * d[..., 1])                       # wider shoulders

    def position(self, u, v):
        d = latlong_dir(u, v)
        return d * self.radius(d)[..., None] * np.array([1.0, 0.92, 1.0])

    def textures(self, resolution):
        u, v = texel_uv(resolution)
        d = latlong_dir(u, v)
        n_blush, n_streak, n_speck, n_grain, n_print = self.tex
        t = np.pi * (1.0 - v)                                           # polar angle from the stem
        radius = self.radius(d)
        # streaks run stem to calyx: the noise is stretched along y (sampled on a circle in u)
        a = 2.0 * np.pi * u
        streak = fbm(n_streak, np.stack([7.0 * np.cos(a), 7.0 * np.sin(a), 1.2 * t], -1), 3)
        blush = fbm(n_blush, 1.6 * d, 3) + 0.35 * d[..., 0]
        red_amount = np.clip(smoothstep(-0.35, 0.25, blush) + 0.45 * streak, 0.0, 1.0)
        albedo = mix(np.array([0.62, 0.42, 0.05]), np.array([0.42, 0.03, 0.025]), red_amount)
        albedo = mix(albedo, np.array([0.22, 0.26, 0.05]), np.exp(-(t / 0.3) ** 2))   # green-brown stem cavity
        speck = smoothstep(0.6, 0.72, n_speck(28.0 * d)) * smoothstep(0.3, 0.8, t) * smoothstep(0.3, 0.8, np.pi - t)
        albedo = mix(albedo, np.array([0.75, 0.62, 0.32]), 0.8 * speck)
        # the label: a rounded oval of gold foil with a dark printed ring
        cos_l = np.clip(np.sum(d * self.LABEL_DIR, -1), -1.0, 1.0)
        dist = np.arccos(cos_l) / 0.2                                    # 1 at the label's edge
        label = smoothstep(1.0, 0.93, dist)
        ring = label * smoothstep(0.06, 0.03, np.abs(dist - 0.62))
        ink = label * smoothstep(0.35, 0.5, n_print(np.array([80.0, 20.0, 80.0]) * d)) * smoothstep(0.4, 0.3, dist)
        printed = np.maximum(ring, ink)
        albedo = mix(albedo, np.array([0.9, 0.68, 0.3]), label)
        albedo = mix(albedo, np.array([0.04, 0.05, 0.08]), printed)
        height = 0.003 * fbm(n_grain, 20.0 * d, 3) + 0.001 * speck + 0.0008 * label
        rough = 0.28 + 0.06 * fbm(n_grain, 12.0 * d + 7.0, 2) + 0.25 * speck
        rough = lerp(rough, 0.22, label)
        rough = lerp(rough, 0.6, printed)
        metal = label * (1.0 - printed)
        ao = 1.0 - 0.55 * np.exp(-(t / 0.32) ** 2) - 0.35 * np.exp(-((np.pi - t) / 0.3) ** 2)
        normal = normal_from_height(height, 2.0 * np.pi * radius * np.sin(np.pi * v), np.pi * radius)
        return quantised(albedo, normal, rough, metal, ao)


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
        self.shape_noise = ValueNoise(rng)
        self.tex = [ValueNoise(rng) for _ in range(6)]

    def radius(self, u, y):
        a = 2.0 * np.pi * u
        p = np.stack([1.3 * np.cos(a), 1.3 * np.sin(a), 2.2 * y], -1)
        base = 0.46 * (1.0 + 0.06 * fbm(self.shape_noise, p, 3))
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
        u, v = texel_uv(resolution)
        n_ridge, n_crack, n_moss, n_ring, n_grain, n_tint = self.tex
        # --- side: bark (below SPLIT) ---
        y = self.Y0 + (v - self.SIDE_V0) / (self.SIDE_V1 - self.SIDE_V0) * (self.Y1 - self.Y0)
        a = 2.0 * np.pi * u
        circle = np.stack([np.cos(a), np.sin(a)], -1)

        def on_side(scale_around, scale_up):                       # 3D noise points, periodic in u
            return np.concatenate([scale_around * circle, scale_up * y[..., None]], -1)

        warp = fbm(n_ridge, on_side(1.5, 3.0), 2)
        ridge_phase = 23.0 * u + 1.2 * warp                        # ~23 vertical ridges around
        ridge = np.abs(np.sin(np.pi * ridge_phase))                # 0 in the furrows
        cracks = smoothstep(0.55, 0.7, np.abs(n_crack(on_side(9.0, 1.0))))
        bark_h = 0.008 * ridge ** 0.6 - 0.004 * cracks + 0.0015 * fbm(n_grain, on_side(20.0, 25.0), 2)
        moss = smoothstep(0.0, 0.25, fbm(n_moss, on_side(2.5, 5.0), 3) - 1.6 * (y - self.Y0) + 0.15)
        bark_rgb = mix(np.array([0.10, 0.07, 0.05]), np.array([0.24, 0.19, 0.14]), ridge ** 0.8)
        bark_rgb = bark_rgb * (0.85 + 0.15 * fbm(n_tint, on_side(14.0, 18.0), 2))[..., None]
        bark_rgb = mix(bark_rgb, np.array([0.18, 0.26, 0.08]), moss)
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
        wobble = 0.04 * fbm(n_ring, np.stack([2.0 * circ[..., 0], 2.0 * circ[..., 1], 4.0 * rho + 5.0 * top], -1), 2)
        rings = 0.5 + 0.5 * np.cos(2.0 * np.pi * 14.0 * (rho + wobble + 0.03 * rho * rho))
        late_wood = smoothstep(0.75, 0.95, rings)
        crack_noise = n_crack(np.stack([6.0 * np.cos(ang), 6.0 * np.sin(ang), 0.8 * rho + 9.0], -1))
        radial_crack = smoothstep(0.75, 0.85, np.abs(crack_noise)) * smoothstep(0.15, 0.4, rho)
        bark_band = smoothstep(0.9, 0.95, rho)
        wood = mix(np.array([0.62, 0.46, 0.28]), np.array([0.42, 0.27, 0.14]), late_wood)
        wood = wood * (0.9 + 0.1 * n_tint(np.stack([30.0 * rx, 30.0 * ry, top * 3.0], -1)))[..., None]
        wood = np.where(top[..., None], wood, wood * np.array([0.72, 0.70, 0.66]))   # the bottom: weathered, dirtier
        wood = mix(wood, np.array([0.06, 0.04, 0.03]), radial_crack)
        wood = mix(wood, np.array([0.14, 0.10, 0.07]), bark_band)
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
        return quantised(albedo, normal, rough, np.zeros_like(rough), ao)


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
        verts, uv, faces = latlong_mesh(*_SPHERE_TESSELLATION[name], shape.position)
        textures = shape.textures(int(resolution))
    return TexturedObject(name, make_mesh(verts, uv, faces), textures)
