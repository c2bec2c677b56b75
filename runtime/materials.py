"""glTF materials on the GPU: the two textures shaders/lib/gltf_material.glsl reads.

- ``u_material_params`` (RGBA32F, one row per material, ``TEXELS`` texels): the factors in
  ``SCALARS`` order, then per texture slot (``SLOTS``) three texels: (image layer or -1, wrap s,
  wrap t, the slot's scale), (m00, m01, m02, m10), (m11, m12, uv set, 0): the KHR_texture_transform
  rows on glTF uv, and the TEXCOORD_n the slot reads (0 or 1: G-buffer "uv" or "uv1"). ``pack`` writes it; the GLSL reads the same offsets (MATERIAL_* there).
- ``u_material_images`` (RGBA16F 2D array, mipmapped, trilinear (``ANISOTROPY``), repeat): every image
  the materials use, in linear light: a colour slot's image (``COLOUR_SLOTS``, sRGB-encoded in the
  file) decoded before upload, so filtering and the mip chain average light as the spec asks (an
  8-bit sRGB texture filtered first and decoded after darkens minified detail: a texel checker of
  black and white reads 0.22 instead of 0.5); a data slot's values as stored; alpha as stored. One
  layer per (image, colour or data) pair in use. Rows as stored (glTF's v = 0 is the first row, so
  the shader samples at glTF uv). Layers share one size, the largest image's side (capped by
  GL_MAX_TEXTURE_SIZE and ``IMAGE_BUDGET``); images of another size are resampled (Lanczos) to it and
  the renderer says so. Clamp and mirror wraps are applied to the uv in the shader. Half floats hold
  every decoded 8-bit level apart (their spacing is under a tenth of the levels').

numpy + Pillow + moderngl; no torch.
"""
from __future__ import annotations

import numpy as np

SCALARS = ("base_color", "emissive_alpha_mode", "metallic_roughness_f0_cutoff", "coat_sheen_anisotropy",
           "sheen_color_rotation", "double_sided")
SLOTS = ("base_color", "metallic_roughness", "normal", "occlusion", "emissive", "clearcoat", "clearcoat_roughness",
         "clearcoat_normal", "sheen_color", "sheen_roughness", "anisotropy")
TEXELS = len(SCALARS) + 3 * len(SLOTS)
# slots whose images hold sRGB-encoded colour (the glTF spec's base colour, emissive and sheen colour)
COLOUR_SLOTS = ("base_color", "emissive", "sheen_color")
WRAP_CODES = {"repeat": 0.0, "clamp": 1.0, "mirror": 2.0}
ALPHA_CODES = {"OPAQUE": 0.0, "MASK": 1.0, "BLEND": 2.0}
IMAGE_BUDGET = 512 << 20      # bytes of the image array with its mip chain
TEXEL_BYTES = 8               # RGBA16F
# Trilinear only, as glTF's samplers say: anisotropic filtering is each driver's own (16x made the
# same page 29 dB apart between llvmpipe and SwiftShader, and llvmpipe's blends past the bilinear
# footprint when magnifying).
ANISOTROPY = 1.0


def _f0(ior: float) -> float:
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def image_layers(materials) -> dict[tuple[int, bool], int]:
    """{(image, colour slot): layer} of the images the materials sample, in order of first use."""
    out = {}
    for m in materials:
        for slot, t in m.textures().items():
            out.setdefault((t.image, slot in COLOUR_SLOTS), len(out))
    return out


def pack(materials, layer_of: dict[tuple[int, bool], int] | None = None) -> np.ndarray:
    """[M, TEXELS, 4] float32 of ``geometry.gltf.Material`` records (the layout above); ``layer_of``:
    ``image_layers(materials)`` (the array layer of each slot's image)."""
    layer_of = image_layers(materials) if layer_of is None else layer_of
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
            out[i, at] = (layer_of[t.image, slot in COLOUR_SLOTS], WRAP_CODES[t.wrap[0]], WRAP_CODES[t.wrap[1]],
                          t.scale)
            out[i, at + 1] = (t.transform[0, 0], t.transform[0, 1], t.transform[0, 2], t.transform[1, 0])
            out[i, at + 2] = (t.transform[1, 1], t.transform[1, 2], float(t.texcoord), 0.0)
    return out


def layer_side(images, max_side: int, layers: int | None = None, budget: int = IMAGE_BUDGET) -> int:
    """The side every layer gets: the largest image side, halved until it fits ``max_side`` and the
    budget for ``layers`` layers (default one per image)."""
    layers = len(images) if layers is None else layers
    side = max((max(im.shape[:2]) for im in images), default=1)
    while side > 1 and (side > max_side or side * side * TEXEL_BYTES * layers * 4 // 3 > budget):
        side //= 2
    return side


def resampling_notes(images, used, side: int) -> list[str]:
    """One line per image the array resamples: enlarged ones keep their detail, reduced ones lose it."""
    notes = []
    for i in used:
        h, w = images[i].shape[:2]
        if (h, w) == (side, side):
            continue
        what = (f"reduced (detail is lost: GL_MAX_TEXTURE_SIZE or the {IMAGE_BUDGET >> 20} MB budget caps the "
                "layers)" if max(h, w) > side else "enlarged (no detail lost)")
        notes.append(f"image {i} ({w}x{h}) resampled to the {side}x{side} layers of one array: {what}")
    return notes


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """sRGB EOTF of values in [0, 1] (lib/colour's srgb_eotf), float64."""
    c = np.asarray(encoded, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def layers(images, side: int, layer_of: dict[tuple[int, bool], int] | None = None) -> np.ndarray:
    """[L, side, side, 4] float16 in linear light: each (image, colour) pair of ``layer_of`` (default:
    every image as data) resampled to side x side where it differs (Lanczos, on the 8-bit image), a
    colour image's RGB sRGB-decoded."""
    from PIL import Image

    layer_of = {(i, False): i for i in range(len(images))} if layer_of is None else layer_of
    out = np.zeros((max(len(layer_of), 1), side, side, 4), np.float16)
    for (i, colour), layer in layer_of.items():
        im = images[i]
        if im.shape[:2] != (side, side):
            im = np.asarray(Image.fromarray(im).resize((side, side), Image.Resampling.LANCZOS), np.uint8)
        values = im.astype(np.float64) / 255.0
        if colour:
            values[..., :3] = srgb_decode(values[..., :3])
        out[layer] = values
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
        layer_of = image_layers(asset.materials)
        if len(layer_of) > max_layers:
            raise ValueError(f"{asset.path.name}: {len(layer_of)} image layers; GL_MAX_ARRAY_TEXTURE_LAYERS is {max_layers}")
        used = sorted({i for i, _ in layer_of})
        side = layer_side([images[i] for i in used], limit(gl, "GL_MAX_TEXTURE_SIZE"), len(layer_of))
        self.notes += resampling_notes(images, used, side)
        data = layers(images, side, layer_of)
        params = pack(asset.materials, layer_of)
        self.arrays = {"u_material_params": params, "u_material_images": data}   # what was uploaded
        self.params = ctx.texture((TEXELS, len(asset.materials)), 4, params.tobytes(), dtype="f4")
        self.params.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.images = ctx.texture_array((side, side, len(data)), 4, data.tobytes(), dtype="f2")
        self.images.build_mipmaps()
        self.images.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        self.images.anisotropy = min(ANISOTROPY, ctx.max_anisotropy)
        self.images.repeat_x = self.images.repeat_y = True
        self.textures = {"u_material_params": self.params, "u_material_images": self.images}
        self.masked = any(m.alpha_mode == "MASK" for m in asset.materials)   # the G-buffer cuts them out
        self.blended = any(m.alpha_mode == "BLEND" for m in asset.materials)   # peeled layers (runtime/geometry.py)

    def release(self) -> None:
        for t in self.textures.values():
            t.release()
        self.textures = {}
