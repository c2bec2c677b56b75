"""A network's textures and their samplers on the compute device, as the generated code binds them
(codegen.glsl.resource_bindings): 2D, 3D and 2D-array textures, mip chains given level by level,
and for each linearly filtered texture a sampler with its wrap."""
from __future__ import annotations

import numpy as np

from inshade.codegen.glsl import INTEGER_DTYPES, SAMPLER_SUFFIX, TextureResource

# texels as wgpu names their formats: moderngl dtype -> (format by channel count, the value of a
# missing alpha: RGB data gains an alpha channel, as GL reads RGB textures)
FORMATS = {
    "f4": ({1: "r32float", 2: "rg32float", 4: "rgba32float"}, 1.0),
    "f2": ({1: "r16float", 2: "rg16float", 4: "rgba16float"}, 1.0),
    "f1": ({1: "r8unorm", 2: "rg8unorm", 4: "rgba8unorm"}, 255),
    "nu2": ({1: "r16unorm", 2: "rg16unorm", 4: "rgba16unorm"}, 65535),
    "u4": ({1: "r32uint", 2: "rg32uint", 4: "rgba32uint"}, 1),
    "u1": ({1: "r8uint", 2: "rg8uint", 4: "rgba8uint"}, 1),
}
# what a device without 16-bit normalised textures (a WebGPU extension) reads instead: the same values as floats
UNORM16_FEATURE = "texture-format16bit-norm"
# device features the textures may need, asked for where the adapter has them
FEATURES = ("float32-filterable", UNORM16_FEATURE)


def _texels(r: TextureResource, features) -> tuple[str, list[np.ndarray]]:
    """The wgpu format and the levels' texel arrays (4 channels for RGB) of one texture."""
    levels = [np.asarray(r.data), *map(np.asarray, r.mips)]
    dtype = r.dtype
    if dtype == "nu2" and UNORM16_FEATURE not in features:
        levels = [(lv.astype(np.float64) / 65535.0).astype(np.float32) for lv in levels]
        dtype = "f4"
    formats, alpha = FORMATS[dtype]
    if levels[0].shape[-1] == 3:
        levels = [np.concatenate([lv, np.full(lv.shape[:-1] + (1,), alpha, lv.dtype)], -1) for lv in levels]
    return formats[levels[0].shape[-1]], [np.ascontiguousarray(lv) for lv in levels]


def texture_view(dev, r: TextureResource):
    """The texture, uploaded level by level, and the view the code reads."""
    wgpu, device = dev.wgpu, dev.device
    fmt, levels = _texels(r, dev.device.features)
    shape = levels[0].shape            # [H, W, C], [D, H, W, C] or [L, H, W, C]
    depth = shape[0] if len(shape) == 4 else 1
    tex = device.create_texture(size=(shape[-2], shape[-3], depth), format=fmt, mip_level_count=len(levels),
                                dimension="3d" if r.dims == 3 else "2d",
                                usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST)
    for k, lv in enumerate(levels):
        h, w, c = lv.shape[-3:]
        d = lv.shape[0] if lv.ndim == 4 else 1
        device.queue.write_texture({"texture": tex, "mip_level": k}, lv.tobytes(),
                                   {"bytes_per_row": w * c * lv.itemsize, "rows_per_image": h}, (w, h, d))
    return tex.create_view(dimension=view_dimension(r))


def view_dimension(r: TextureResource) -> str:
    return "2d-array" if r.array else ("3d" if r.dims == 3 else "2d")


def texture_layout(r: TextureResource) -> dict:
    """How a bind-group layout declares the texture: uint texels, float ones a sampler filters, or float
    ones read texel by texel (any float format)."""
    kind = "uint" if r.dtype in INTEGER_DTYPES else ("float" if r.filter == "linear" else "unfilterable-float")
    return {"texture": {"sample_type": kind, "view_dimension": view_dimension(r)}}


def sampler(dev, r: TextureResource):
    """The sampler of a linearly filtered texture: bilinear within a level, the nearest level, its wrap."""
    mode = "repeat" if r.wrap == "repeat" else "clamp-to-edge"
    return dev.device.create_sampler(address_mode_u=mode, address_mode_v=mode, address_mode_w=mode,
                                     mag_filter="linear", min_filter="linear", mipmap_filter="nearest")


def sampler_entries(dev, resources: list, bindings: dict) -> list[tuple[dict, dict]]:
    """(layout entry, bind-group entry) of each linearly filtered texture's sampler."""
    return [({"binding": bindings[r.name + SAMPLER_SUFFIX], "sampler": {"type": "filtering"}},
             {"binding": bindings[r.name + SAMPLER_SUFFIX], "resource": sampler(dev, r)})
            for r in resources if isinstance(r, TextureResource) and r.filter == "linear"]
