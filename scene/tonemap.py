"""Tone mappers: linear scene values -> display values in [0, 1], applied where a picture is made
for eyes (the window's and the page's present pass, PNGs), never to the float image or an EXR.

One table is the single source: ``glsl_chunk()`` writes ``#define TONEMAP_NONE 0`` etc. for
``lib/tonemap`` in the order of ``TONEMAPS``, and each numpy twin here computes what its GLSL does.
"""
from __future__ import annotations

import numpy as np


def _none(rgb: np.ndarray) -> np.ndarray:
    return rgb


def _reinhard(rgb: np.ndarray) -> np.ndarray:
    return rgb / (1.0 + rgb)


# Khronos PBR Neutral: colours stay as authored up to 0.76 (a base colour lit at 1 shows as itself),
# brighter ones are compressed towards white, and the desaturation keeps hue under compression.
PBR_NEUTRAL_START = 0.8 - 0.04
PBR_NEUTRAL_DESATURATION = 0.15


def _pbr_neutral(rgb: np.ndarray) -> np.ndarray:
    x = rgb.min(axis=-1, keepdims=True)
    offset = np.where(x < 0.08, x - 6.25 * x * x, 0.04)
    c = rgb - offset
    peak = c.max(axis=-1, keepdims=True)
    d = 1.0 - PBR_NEUTRAL_START
    new_peak = 1.0 - d * d / (peak + d - PBR_NEUTRAL_START)
    scaled = c * (new_peak / np.maximum(peak, 1e-30))
    g = 1.0 - 1.0 / (PBR_NEUTRAL_DESATURATION * (peak - new_peak) + 1.0)
    compressed = scaled + (new_peak - scaled) * g
    return np.where(peak < PBR_NEUTRAL_START, c, compressed)


TONEMAP_FUNCTIONS = {"none": _none, "reinhard": _reinhard, "pbr_neutral": _pbr_neutral}
TONEMAPS = tuple(TONEMAP_FUNCTIONS)


def check_tonemap(name) -> str:
    if name not in TONEMAP_FUNCTIONS:
        raise ValueError(f"unknown tonemap {name!r}; expected one of {', '.join(TONEMAPS)}")
    return name


def tonemap(rgb, name: str) -> np.ndarray:
    """``name``'s operator on linear RGB [..., 3] (non-negative), float64."""
    return TONEMAP_FUNCTIONS[check_tonemap(name)](np.asarray(rgb, np.float64))


def glsl_chunk() -> str:
    lines = ["// generated from inshade.scene.tonemap.TONEMAPS; do not edit"]
    lines += [f"#define TONEMAP_{name.upper()} {i}" for i, name in enumerate(TONEMAPS)]
    return "\n".join(lines) + "\n"


# Display modes that show the scene as a picture; the error views and the raw lanes are data and are
# presented as they are.
TONEMAPPED_MODES = ("final", "reference", "split")


def presented_tonemap(settings: dict, mode: str) -> str:
    """The tone mapper a picture in display ``mode`` is presented with, by the ``tonemap`` setting."""
    return settings.get("tonemap", "none") if mode in TONEMAPPED_MODES else "none"
