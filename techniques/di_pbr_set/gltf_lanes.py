"""A glTF material as the eight lanes di_pbr_set compresses with ``--gltf FILE``, and the stretch of
the mesh's uv those lanes cover.

The lanes (``LANES``): albedo RGB (the linear base colour, factor applied, sRGB-encoded), the
tangent-space normal's x and y stored as 0.5 + 0.5 n (normal scale applied, +y along +v; z is
rebuilt as sqrt(1 - x^2 - y^2), the two-channel normal-map layout), roughness, occlusion (strength
applied) and metallic. Eight is what one DI cascade holds (models/texture_cascade.py MAX_CHANNELS),
so the normal keeps two lanes and metallic gets the third one back. What the lanes do not hold
(emission, alpha, clearcoat, sheen, anisotropy, ior) stays the file's: the pass reads it from the
glTF's own textures, as the reference does.

The uv domain (``UvDomain``): DI sees a square image baked over a rectangle of the mesh's uv, not
the file's textures: a KHR_texture_transform (scale, rotation) or several textures with different
transforms have no common texture space, and their content repeats over mesh uv only when every
transform maps a whole step of u (or v) onto whole texture periods. Per axis:

- repeating: the smallest such period P (1..``MAX_PERIOD``) when it is shorter than the mesh's
  uv extent; the pass evaluates DI at fract((uv - origin) / P), as the bricks set is at fract(uv);
- spanning: otherwise the mesh's uv extent rounded out to whole units, [floor(min), ceil(max)];
  the pass evaluates DI at clamp((uv - origin) / extent, 0, 1).

The bake's side (``bake_size``) keeps every lane texture's resolution over that rectangle: per axis
the texels a texture advances per unit of mesh uv (its transform included) times the extent, the
largest over textures and axes, rounded up to a multiple of 8. A square image over a non-square
rectangle oversamples the shorter side.

Every problem with the file is one ``GltfError`` reading ``FILE: FIELD: problem``, like the reader's.
numpy only, no torch (the technique record's chunk hook reads ``UvDomain`` at render time).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.geometry.gltf import GltfError
from inshade.metrics import srgb_oetf

# lane groups: name -> (first lane, width); order is lib/pbr_set_gltf.glsl's
LANES = {"albedo": (0, 3), "normal": (3, 2), "roughness": (5, 1), "occlusion": (6, 1), "metallic": (7, 1)}
CHANNELS = 8
# the material slots the lanes are read from (others stay the file's)
SLOTS = ("base_color", "metallic_roughness", "normal", "occlusion")
MAX_PERIOD = 8              # the longest repeat looked for along an axis, in uv units
MAX_BAKE = 2048             # the largest bake side chosen from the textures (--size may ask for more)
PERIOD_TOLERANCE = 1e-6


@dataclass(frozen=True)
class UvDomain:
    """Which material the lanes replace and where in mesh uv the bake lies: bake coordinate
    x = (uv - origin) / extent, wrapped (``repeat``) or clamped per axis."""
    material: int
    origin: tuple[float, float]
    extent: tuple[float, float]
    repeat: tuple[bool, bool]

    def to_bake(self, uv: np.ndarray) -> np.ndarray:
        """Mesh uv [N, 2] -> bake coordinates in [0, 1] (what the pass feeds the network)."""
        x = (np.asarray(uv, np.float64) - self.origin) / self.extent
        return np.stack([x[:, a] - np.floor(x[:, a]) if self.repeat[a] else np.clip(x[:, a], 0.0, 1.0)
                         for a in range(2)], 1)

    def from_bake(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(self.origin) + np.asarray(x, np.float64) * np.asarray(self.extent)

    def as_dict(self) -> dict:
        return {"material": self.material, "origin": list(self.origin), "extent": list(self.extent),
                "repeat": list(self.repeat)}

    @classmethod
    def from_dict(cls, d, where: str) -> "UvDomain":
        """The bundle's ``render.uv_domain``; ValueError naming the field."""
        field = f"{where}: render.uv_domain"
        if not isinstance(d, dict):
            raise ValueError(f"{field}: missing (the glTF mode's bundle says which material and uv rectangle "
                             "its lanes cover)")

        def pair(key, ok, what):
            v = d.get(key)
            if not isinstance(v, list) or len(v) != 2 or not all(ok(x) for x in v):
                raise ValueError(f"{field}.{key}: must be two {what}, got {v!r}")
            return tuple(v)

        def number(x):
            return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)

        m = d.get("material")
        if isinstance(m, bool) or not isinstance(m, int) or m < 0:
            raise ValueError(f"{field}.material: must be a material index >= 0, got {m!r}")
        origin = pair("origin", number, "numbers")
        extent = pair("extent", lambda x: number(x) and x > 0, "positive numbers")
        repeat = pair("repeat", lambda x: isinstance(x, bool), "booleans")
        return cls(m, tuple(float(x) for x in origin), tuple(float(x) for x in extent), repeat)


def _error(path, field: str, problem: str) -> GltfError:
    return GltfError(f"{path}: {field}: {problem}")


def choose_material(asset, path, material: int | None) -> int:
    """``material`` checked against the file, or (None) the material with lane textures that covers
    the most faces."""
    used = np.bincount(asset.face_material, minlength=len(asset.materials))
    textured = [i for i, m in enumerate(asset.materials) if used[i] and any(s in m.textures() for s in SLOTS)]
    if material is None:
        if not textured:
            raise _error(path, "materials", "no material has a base colour, metallic-roughness, normal or "
                         "occlusion texture: nothing for di_pbr_set to compress")
        return max(textured, key=lambda i: used[i])
    if not 0 <= material < len(asset.materials):
        raise _error(path, "materials", f"--material {material}: the file has {len(asset.materials)} "
                     f"material(s) (0..{len(asset.materials) - 1})")
    if used[material] == 0:
        raise _error(path, f"materials[{material}]", "no triangle uses it (used: "
                     f"{', '.join(str(i) for i in np.flatnonzero(used))})")
    if material not in textured:
        raise _error(path, f"materials[{material}] ({asset.materials[material].name or 'unnamed'})",
                     "has no base colour, metallic-roughness, normal or occlusion texture: nothing for di_pbr_set "
                     f"to compress (with textures: {', '.join(map(str, textured)) or 'none'})")
    return material


def material_uv(asset, path, material: int) -> np.ndarray:
    """The uv [3F, 2] of the material's triangles' corners (project convention, v up)."""
    from inshade.geometry.mesh import mesh_uv

    uv = mesh_uv(asset.mesh)
    if uv is None:
        raise _error(path, "meshes", "no primitive has TEXCOORD_0: di_pbr_set compresses a material in uv space")
    corners = uv[np.asarray(asset.mesh.faces)[asset.face_material == material].reshape(-1)]
    if np.ptp(corners, axis=0).max() == 0.0:
        raise _error(path, f"materials[{material}]", "its triangles have no TEXCOORD_0 (every uv is the same)")
    return corners


def _period(refs, asset, axis: int) -> int | None:
    """The smallest whole number of uv units along ``axis`` after which every texture repeats."""
    for p in range(1, MAX_PERIOD + 1):
        ok = True
        for ref in refs:
            for i in range(2):
                step = p * ref.transform[i, axis]
                whole = round(step)
                if abs(step - whole) > PERIOD_TOLERANCE * max(1.0, abs(step)):
                    ok = False
                elif whole != 0 and ref.wrap[i] != "repeat" and not (ref.wrap[i] == "mirror" and whole % 2 == 0):
                    ok = False
        if ok:
            return p
    return None


def lane_textures(asset, material: int) -> list:
    tex = asset.materials[material].textures()
    return [tex[s] for s in SLOTS if s in tex]


def uv_domain(asset, path, material: int) -> UvDomain:
    """The rectangle of mesh uv the bake covers (see the module docstring)."""
    corners = material_uv(asset, path, material)
    refs = lane_textures(asset, material)
    lo, hi = np.floor(corners.min(0)), np.ceil(corners.max(0))
    origin, extent, repeat = [], [], []
    for axis in range(2):
        span = max(float(hi[axis] - lo[axis]), 1.0)
        period = _period(refs, asset, axis)
        if period is not None and period < span:
            origin.append(0.0), extent.append(float(period)), repeat.append(True)
        else:
            origin.append(float(lo[axis])), extent.append(span), repeat.append(False)
    return UvDomain(material, tuple(origin), tuple(extent), tuple(repeat))


def texels_per_uv(asset, material: int) -> tuple[float, float]:
    """Per mesh-uv axis, the most texels any lane texture advances per unit (transform included)."""
    rates = [0.0, 0.0]
    for ref in lane_textures(asset, material):
        h, w = asset.images[ref.image].shape[:2]
        for axis in range(2):
            rates[axis] = max(rates[axis], float(np.hypot(ref.transform[0, axis] * w, ref.transform[1, axis] * h)))
    return rates[0], rates[1]


def bake_size(asset, material: int, domain: UvDomain) -> tuple[int, bool]:
    """(the bake's side, whether ``MAX_BAKE`` cut it): every lane texture's resolution kept over the domain."""
    rates = texels_per_uv(asset, material)
    need = max(r * e for r, e in zip(rates, domain.extent))
    side = max(8, int(math.ceil(need / 8.0 - 1e-9)) * 8)
    return min(side, MAX_BAKE), side > MAX_BAKE


def bake_lanes(asset, material: int, domain: UvDomain, size: int) -> np.ndarray:
    """The eight lanes [size, size, 8] float32 at 8-bit values (k / 255), row 0 = top (bake v = 1):
    ``material_channels`` (geometry/gltf_sample.py, what ``bake`` evaluates) at the texel centres
    of the domain."""
    from inshade.geometry.gltf_sample import material_channels, texel_uv

    c = material_channels(asset, material, domain.from_bake(texel_uv(size)))
    lanes = np.concatenate([srgb_oetf(np.clip(c["base_color"], 0.0, 1.0)), 0.5 + 0.5 * c["normal"][:, :2],
                            c["roughness"][:, None], c["occlusion"][:, None], c["metallic"][:, None]], 1)
    lanes = np.round(np.clip(lanes, 0.0, 1.0) * 255.0) / 255.0
    return lanes.reshape(size, size, CHANNELS).astype(np.float32)


def unit_normals(lanes: np.ndarray) -> np.ndarray:
    """The tangent-space normals [..., 3] the pass rebuilds from the two normal lanes (z >= 0)."""
    xy = np.asarray(lanes, np.float64)[..., 3:5] * 2.0 - 1.0
    z = np.sqrt(np.maximum(1.0 - np.sum(xy * xy, -1), 0.0))
    n = np.concatenate([xy, z[..., None]], -1)
    return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)


def decoded_channels(lanes: np.ndarray) -> dict[str, np.ndarray]:
    """Decoded lanes [S, S, 8] as the material channels the pass shades with (lib/pbr_set_gltf.glsl
    pbr_set_gltf_decode): linear base colour, the rebuilt normal, roughness, occlusion, metallic."""
    from inshade.geometry.gltf import srgb_to_linear

    lanes = np.asarray(lanes, np.float64)
    return {"base_color": srgb_to_linear(np.clip(lanes[..., 0:3], 0.0, 1.0)), "normal": unit_normals(lanes),
            "roughness": np.clip(lanes[..., 5], 0.0, 1.0), "occlusion": np.clip(lanes[..., 6], 0.0, 1.0),
            "metallic": np.clip(lanes[..., 7], 0.0, 1.0)}


def source_bytes(asset, material: int) -> int:
    """The lane textures' size as RGBA8 (each image counted once)."""
    images = {ref.image for ref in lane_textures(asset, material)}
    return int(sum(asset.images[i].shape[0] * asset.images[i].shape[1] * 4 for i in images))


def load(path, material: int | None):
    """(asset, material, domain) of a glTF file, or one ``FILE: FIELD: problem`` error."""
    from inshade.geometry.gltf import load_gltf
    from inshade.geometry.gltf_sample import require_first_uv_set

    path = Path(path)
    asset = load_gltf(path)             # GltfError: FILE: FIELD: problem
    require_first_uv_set(asset)
    m = choose_material(asset, path, material)
    return asset, m, uv_domain(asset, path, m)
