"""glTF materials on the GPU: the two textures shaders/lib/gltf_material.glsl reads.

- ``u_material_params`` (RGBA32F, one row per material, ``TEXELS`` texels): the factors in
  ``SCALARS`` order, then per texture slot (``SLOTS``) three texels: (image layer or -1, wrap s,
  wrap t, the slot's scale), (m00, m01, m02, m10), (m11, m12, 0, 0), the KHR_texture_transform
  rows on glTF uv. ``pack`` writes it; the GLSL reads the same offsets (MATERIAL_* there).
- ``u_material_images`` (RGBA8 2D array, mipmapped, trilinear (``ANISOTROPY``), repeat): every image the materials
  use, one layer each, rows as stored (glTF's v = 0 is the first row, so the shader samples at glTF
  uv). Layers share one size, the largest image's side (capped by GL_MAX_TEXTURE_SIZE and
  ``IMAGE_BUDGET``); images of another size are resampled (Lanczos) to it and the renderer says so.
  Clamp and mirror wraps are applied to the uv in the shader.

numpy + Pillow + moderngl; no torch.
"""
from __future__ import annotations

import numpy as np

SCALARS = ("base_color", "emissive_alpha_mode", "metallic_roughness_f0_cutoff", "coat_sheen_anisotropy",
           "sheen_color_rotation", "double_sided")
SLOTS = ("base_color", "metallic_roughness", "normal", "occlusion", "emissive", "clearcoat", "clearcoat_roughness",
         "clearcoat_normal", "sheen_color", "sheen_roughness", "anisotropy")
TEXELS = len(SCALARS) + 3 * len(SLOTS)
WRAP_CODES = {"repeat": 0.0, "clamp": 1.0, "mirror": 2.0}
ALPHA_CODES = {"OPAQUE": 0.0, "MASK": 1.0, "BLEND": 2.0}
IMAGE_BUDGET = 512 << 20      # bytes of the image array with its mip chain
# Trilinear only, as glTF's samplers say: anisotropic filtering is each driver's own (16x made the
# same page 29 dB apart between llvmpipe and SwiftShader, and llvmpipe's blends past the bilinear
# footprint when magnifying).
ANISOTROPY = 1.0


def _f0(ior: float) -> float:
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def pack(materials) -> np.ndarray:
    """[M, TEXELS, 4] float32 of ``geometry.gltf.Material`` records (the layout above)."""
    out = np.zeros((len(materials), TEXELS, 4), np.float32)
    for i, m in enumerate(materials):
        out[i, 0] = m.base_color
        out[i, 1] = (*m.emissive, ALPHA_CODES[m.alpha_mode])
        out[i, 2] = (m.metallic, m.roughness, _f0(m.ior), m.alpha_cutoff)
        out[i, 3] = (m.clearcoat, m.clearcoat_roughness, m.sheen_roughness, m.anisotropy_strength)
        out[i, 4] = (*m.sheen_color, m.anisotropy_rotation)
        out[i, 5] = (float(m.double_sided), 0.0, 0.0, 0.0)
        textures = m.textures()
        for k, slot in enumerate(SLOTS):
            at = len(SCALARS) + 3 * k
            t = textures.get(slot)
            if t is None:
                out[i, at] = (-1.0, 0.0, 0.0, 1.0)
                out[i, at + 1] = (1.0, 0.0, 0.0, 0.0)
                out[i, at + 2] = (1.0, 0.0, 0.0, 0.0)
                continue
            out[i, at] = (t.image, WRAP_CODES[t.wrap[0]], WRAP_CODES[t.wrap[1]], t.scale)
            out[i, at + 1] = (t.transform[0, 0], t.transform[0, 1], t.transform[0, 2], t.transform[1, 0])
            out[i, at + 2] = (t.transform[1, 1], t.transform[1, 2], 0.0, 0.0)
    return out


def layer_side(images, max_side: int, budget: int = IMAGE_BUDGET) -> int:
    """The side every layer gets: the largest image side, halved until it fits ``max_side`` and the budget."""
    side = max((max(im.shape[:2]) for im in images), default=1)
    while side > 1 and (side > max_side or side * side * 4 * len(images) * 4 // 3 > budget):
        side //= 2
    return side


def layers(images, side: int) -> np.ndarray:
    """[L, side, side, 4] uint8: each image resampled to side x side where it differs (Lanczos)."""
    from PIL import Image

    out = np.zeros((max(len(images), 1), side, side, 4), np.uint8)
    for i, im in enumerate(images):
        if im.shape[:2] != (side, side):
            im = np.asarray(Image.fromarray(im).resize((side, side), Image.Resampling.LANCZOS), np.uint8)
        out[i] = im
    return out


class MaterialTextures:
    """The two textures of a glTF asset's materials, made in ``ctx``; ``textures`` = {uniform: texture}."""

    def __init__(self, ctx, asset, gl: dict):
        import moderngl

        from inshade.codegen.limits import limit

        self.notes = []
        images = asset.images
        max_layers = limit(gl, "GL_MAX_ARRAY_TEXTURE_LAYERS")
        if len(images) > max_layers:
            raise ValueError(f"{asset.path.name}: {len(images)} images; GL_MAX_ARRAY_TEXTURE_LAYERS is {max_layers}")
        side = layer_side(images, limit(gl, "GL_MAX_TEXTURE_SIZE"))
        resized = sorted({f"{im.shape[1]}x{im.shape[0]}" for im in images if im.shape[:2] != (side, side)})
        if resized:
            self.notes.append(f"images of {', '.join(resized)} resampled to the {side}x{side} layers of one array")
        data = layers(images, side)
        params = pack(asset.materials)
        self.arrays = {"u_material_params": params, "u_material_images": data}   # what was uploaded
        self.params = ctx.texture((TEXELS, len(asset.materials)), 4, params.tobytes(), dtype="f4")
        self.params.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.images = ctx.texture_array((side, side, len(data)), 4, data.tobytes())
        self.images.build_mipmaps()
        self.images.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        self.images.anisotropy = min(ANISOTROPY, ctx.max_anisotropy)
        self.images.repeat_x = self.images.repeat_y = True
        self.textures = {"u_material_params": self.params, "u_material_images": self.images}
        self.masked = any(m.alpha_mode == "MASK" for m in asset.materials)   # the G-buffer cuts them out

    def release(self) -> None:
        for t in self.textures.values():
            t.release()
        self.textures = {}
