"""The channels a UV-free decoder learns from a glTF file's materials, and how it stores them.

A glTF asset's decoder outputs the metallic-roughness model's channels the file has, in this
order (``CHANNELS``): ``base_color`` (3), ``metallic``, ``roughness`` always; ``normal`` (3, tangent
space) when a material has a normal texture; ``occlusion`` when one has an occlusion texture;
``emissive`` (3) when one emits. A channel the file does not have stays the file's value in the
shader (lib/gltf_material's ``gltf_surface``), and so do alpha, the specular factor (ior) and the KHR
lobes (clearcoat, sheen, anisotropy): the decoder replaces only what it learnt.

Stored as a texture would hold them, so one network output spends its precision where the eye
does: base colour sRGB-encoded; the normal as n * 0.5 + 0.5; metallic, roughness, occlusion as
they are; emissive divided by ``emissive_scale`` (the largest emissive factor, at least 1: emissive
strength may exceed 1) and sRGB-encoded. ``encode`` turns ``geometry.gltf_sample.material_channels``
into these values, ``render_meta`` records the layout in the bundle's ``render`` field and
``layout_chunk`` makes the pass's ``<uvf_gltf_channels>`` from it (offsets ``UVG_LANE_*``, -1 where a
channel is not decoded). numpy only (the runtime's hooks use it).
"""
from __future__ import annotations

import math

import numpy as np

from inshade.geometry.gltf import linear_to_srgb

CHANNELS = {"base_color": 3, "metallic": 1, "roughness": 1, "normal": 3, "occlusion": 1, "emissive": 3}
ALWAYS = ("base_color", "metallic", "roughness")
CHUNK = "uvf_gltf_channels"


def channels_of(asset) -> tuple[str, ...]:
    """The channels the decoder of ``asset`` (a ``GltfAsset``) outputs, in ``CHANNELS`` order."""
    used = [asset.materials[m] for m in asset.used_materials()]
    has = {"normal": any(m.normal_texture is not None for m in used),
           "occlusion": any(m.occlusion_texture is not None for m in used),
           "emissive": any(max(m.emissive) > 0.0 for m in used)}
    return tuple(c for c in CHANNELS if c in ALWAYS or has[c])


def emissive_scale(asset) -> float:
    """The largest emissive factor component of the used materials, at least 1."""
    return max([1.0] + [float(max(asset.materials[m].emissive)) for m in asset.used_materials()])


def lanes(channels) -> dict[str, tuple[int, int]]:
    """{channel: (first output lane, width)} of a decoder outputting ``channels`` in order."""
    out, at = {}, 0
    for c in channels:
        out[c] = (at, CHANNELS[c])
        at += CHANNELS[c]
    return out


def width(channels) -> int:
    return sum(CHANNELS[c] for c in channels)


def encode(values: dict, channels, scale: float) -> np.ndarray:
    """[N, width] float32: ``material_channels`` values as the decoder stores them (module docstring)."""
    cols = []
    for c in channels:
        v = np.asarray(values[c], np.float64)
        if c == "base_color":
            v = linear_to_srgb(v)
        elif c == "normal":
            v = v * 0.5 + 0.5
        elif c == "emissive":
            v = linear_to_srgb(v / scale)
        cols.append(v.reshape(len(v), -1))
    return np.concatenate(cols, 1).astype(np.float32)


def render_meta(channels, scale: float) -> dict:
    return {"channels": list(channels), "emissive_scale": float(scale)}


def read_render_meta(render, where: str) -> tuple[tuple[str, ...], float]:
    """(channels, emissive scale) from a bundle's ``render`` field; ValueError naming the field."""
    render = render if isinstance(render, dict) else {}
    channels = render.get("channels")
    if (not isinstance(channels, list) or not all(isinstance(c, str) for c in channels)
            or [c for c in CHANNELS if c in channels] != channels or not set(ALWAYS) <= set(channels)):
        raise ValueError(f"{where}: render.channels: must list, in the order {', '.join(CHANNELS)}, "
                         f"{', '.join(ALWAYS)} and any of the others, got {channels!r}")
    scale = render.get("emissive_scale")
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not (math.isfinite(scale) and scale >= 1.0):
        raise ValueError(f"{where}: render.emissive_scale: must be a finite number >= 1, got {scale!r}")
    return tuple(channels), float(scale)


def layout_chunk(channels, scale: float) -> str:
    """The pass's ``<uvf_gltf_channels>``: each channel's first lane (-1: not decoded), the lane count
    and the emissive scale."""
    from inshade.codegen.glsl import flt

    at = lanes(channels)
    lines = ["// the decoder's output lanes (techniques/uvfree_material/gltf_channels.py; -1: the file's value)"]
    lines += [f"#define UVG_LANE_{c.upper()} {at[c][0] if c in at else -1}" for c in CHANNELS]
    lines += [f"#define UVG_LANES {width(channels)}", f"#define UVG_EMISSIVE_SCALE {flt(scale)}", ""]
    return "\n".join(lines)
