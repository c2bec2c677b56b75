"""A glTF material's values on the CPU: what trainers learn from and exporters write.

- ``sample_texture(asset, ref, uv, colour=False)``: a material texture at glTF uv [N, 2] (v down)
  through its KHR_texture_transform and the sampler's wrap modes, bilinear (the base level: trainers
  sample at the texture's own resolution), [N, 4] float64 in [0, 1]: as stored, or with ``colour``
  the texels' RGB sRGB-decoded before filtering (as the GPU's linear-light image array filters).
- ``material_channels(asset, m, uv, uv1=None)``: material ``m`` at those uv (and a texture that
  reads TEXCOORD_1 at ``uv1``, the same points' second set), factors applied, colours linear:
  ``base_color`` [N, 3], ``alpha``, ``metallic``, ``roughness``, ``normal`` (tangent space, unit,
  normal scale applied; +y along the project's +v), ``occlusion`` (strength applied), ``emissive``
  [N, 3], ``clearcoat``, ``clearcoat_roughness``, ``sheen_color`` [N, 3], ``sheen_roughness``,
  ``anisotropy`` (strength) and ``anisotropy_direction`` [N, 2] (tangent space, rotation applied).
  The same reading as shaders/lib/gltf_material.glsl ``gltf_surface`` (which filters with mip maps).
- ``texel_uv(size)``: the uv of a ``size`` x ``size`` texture's texel centres in the project's
  convention (row 0 = v near 1), so ``bake(asset, m, size)`` gives every channel as images.
- ``textured_size(asset, m)``: the largest texture side the material uses (a natural bake size).

numpy only.
"""
from __future__ import annotations

import math

import numpy as np

from .gltf import GltfAsset, GltfError, TextureRef, gltf_uv, srgb_to_linear


def _wrap(x: np.ndarray, mode: str) -> np.ndarray:
    if mode == "clamp":
        return np.clip(x, 0.0, 1.0)
    if mode == "mirror":
        t = np.mod(x, 2.0)
        return np.where(t > 1.0, 2.0 - t, t)
    return x


def sample_texture(asset: GltfAsset, ref: TextureRef, uv_gltf: np.ndarray, colour: bool = False) -> np.ndarray:
    """[N, 4] float64 in [0, 1]: bilinear at the transformed, wrapped glTF uv (texel centres at (i + 0.5) / W);
    ``colour``: the RGB of each texel sRGB-decoded first, so light is what gets filtered."""
    image = asset.images[ref.image].astype(np.float64) / 255.0
    if colour:
        image[..., :3] = srgb_to_linear(image[..., :3])
    h, w = image.shape[:2]
    uv = np.asarray(uv_gltf, np.float64)
    t = uv @ ref.transform[:2, :2].T + ref.transform[:2, 2]
    s, tt = _wrap(t[:, 0], ref.wrap[0]), _wrap(t[:, 1], ref.wrap[1])
    x, y = s * w - 0.5, tt * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]

    def index(i, n, mode):
        i = i.astype(np.int64)
        if mode == "repeat":
            return np.mod(i, n)
        if mode == "mirror":
            period = np.mod(i, 2 * n)
            return np.where(period >= n, 2 * n - 1 - period, period)
        return np.clip(i, 0, n - 1)

    xa, xb = index(x0, w, ref.wrap[0]), index(x0 + 1, w, ref.wrap[0])
    ya, yb = index(y0, h, ref.wrap[1]), index(y0 + 1, h, ref.wrap[1])
    top = image[ya, xa] * (1 - fx) + image[ya, xb] * fx
    bottom = image[yb, xa] * (1 - fx) + image[yb, xb] * fx
    return top * (1 - fy) + bottom * fy


def material_channels(asset: GltfAsset, m: int, uv: np.ndarray, uv1: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Material ``m``'s channels at the project's uv [N, 2] (v up), and ``uv1`` the same points'
    second uv set where a texture reads TEXCOORD_1 (a GltfError without it: the caller samples
    in the first set's space only); see the module docstring."""
    mat = asset.materials[m]
    sets = [gltf_uv(uv), None if uv1 is None else gltf_uv(uv1)]
    n = len(sets[0])

    def tex(ref, default, colour=False):
        if ref is None:
            return np.tile(np.asarray(default, np.float64), (n, 1))
        if sets[ref.texcoord] is None:
            slot = next(k for k, t in mat.textures().items() if t is ref)
            raise GltfError(f"{asset.path}: materials ({mat.name}).{slot}: reads TEXCOORD_{ref.texcoord}; "
                            "this is sampled in TEXCOORD_0's space only (the reference pass draws it)")
        return sample_texture(asset, ref, sets[ref.texcoord], colour)

    base = tex(mat.base_color_texture, (1, 1, 1, 1), colour=True)
    mr = tex(mat.metallic_roughness_texture, (1, 1, 1, 1))
    out = {"base_color": np.asarray(mat.base_color[:3]) * base[:, :3],
           "alpha": mat.base_color[3] * base[:, 3],
           "metallic": np.clip(mat.metallic * mr[:, 2], 0, 1), "roughness": np.clip(mat.roughness * mr[:, 1], 0, 1)}
    nt = tex(mat.normal_texture, (0.5, 0.5, 1.0, 1.0))[:, :3] * 2.0 - 1.0
    nt[:, :2] *= mat.normal_texture.scale if mat.normal_texture is not None else 1.0
    out["normal"] = nt / np.maximum(np.linalg.norm(nt, axis=1, keepdims=True), 1e-300)
    ao = tex(mat.occlusion_texture, (1, 1, 1, 1))[:, 0]
    strength = mat.occlusion_texture.scale if mat.occlusion_texture is not None else 1.0
    out["occlusion"] = 1.0 + strength * (ao - 1.0)
    out["emissive"] = np.asarray(mat.emissive) * tex(mat.emissive_texture, (1, 1, 1, 1), colour=True)[:, :3]
    out["clearcoat"] = mat.clearcoat * tex(mat.clearcoat_texture, (1, 1, 1, 1))[:, 0]
    out["clearcoat_roughness"] = mat.clearcoat_roughness * tex(mat.clearcoat_roughness_texture, (1, 1, 1, 1))[:, 1]
    out["sheen_color"] = np.asarray(mat.sheen_color) * tex(mat.sheen_color_texture, (1, 1, 1, 1), colour=True)[:, :3]
    out["sheen_roughness"] = mat.sheen_roughness * tex(mat.sheen_roughness_texture, (1, 1, 1, 1))[:, 3]
    an = tex(mat.anisotropy_texture, (1.0, 0.5, 1.0, 1.0))
    out["anisotropy"] = mat.anisotropy_strength * an[:, 2]
    d = an[:, :2] * 2.0 - 1.0
    c, s = math.cos(mat.anisotropy_rotation), math.sin(mat.anisotropy_rotation)
    out["anisotropy_direction"] = np.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]], 1)
    return out


def require_first_uv_set(asset: GltfAsset) -> None:
    """A GltfError naming the first texture of a drawn material that reads another set than
    TEXCOORD_0: for learners that sample a material over the first set's space."""
    for i in asset.used_materials():
        m = asset.materials[i]
        for slot, t in m.textures().items():
            if t.texcoord != 0:
                raise GltfError(f"{asset.path}: materials ({m.name}).{slot}: reads TEXCOORD_{t.texcoord}; a learnt "
                                "material is sampled over TEXCOORD_0 (gltf_pbr draws the file as it is)")


def texel_uv(size: int) -> np.ndarray:
    """[size * size, 2] uv (v up) of the texel centres, row-major from the image's top row."""
    c = (np.arange(size) + 0.5) / size
    u, v = np.meshgrid(c, 1.0 - c)
    return np.stack([u.reshape(-1), v.reshape(-1)], 1)


def bake(asset: GltfAsset, m: int, size: int) -> dict[str, np.ndarray]:
    """``material_channels`` at every texel of a ``size`` x ``size`` texture: [size, size(, k)]."""
    return {k: v.reshape(size, size, *v.shape[1:]) for k, v in material_channels(asset, m, texel_uv(size)).items()}


def textured_size(asset: GltfAsset, m: int, default: int = 256) -> int:
    """The largest side among the textures material ``m`` uses (``default`` without textures)."""
    sides = [max(asset.images[t.image].shape[:2]) for t in asset.materials[m].textures().values()]
    return max(sides, default=default)
