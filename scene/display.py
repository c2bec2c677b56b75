"""Display modes: one Python enum, generated into GLSL ``#define`` constants (chunk ``display_modes``).

The composite pass (``passes/display.frag``) switches on ``u_mode`` (a uniform, so changing the mode
never recompiles the expensive network program). The enum is the single source: ``glsl_chunk()``
writes ``#define DISPLAY_FINAL 0`` etc., so Python and GLSL cannot drift apart.
"""
from __future__ import annotations

import enum


class DisplayMode(enum.IntEnum):
    FINAL = 0           # network output, exposure applied (what `inshade render` writes)
    NETWORK = 1         # raw network output lanes, no exposure
    REFERENCE = 2       # the scene's reference image, same view
    ERROR = 3           # heat map of mean |network - reference| * error_scale
    SPLIT = 4           # network left of the split line, reference right of it
    SQUARED_ERROR = 5   # internal: (network - reference)^2 per channel, alpha = coverage (PSNR)

    @property
    def label(self) -> str:
        return self.name.lower().replace("_", " ")


UI_MODES = tuple(m for m in DisplayMode if m is not DisplayMode.SQUARED_ERROR)


def parse_mode(value) -> DisplayMode:
    """``"final"``, ``"FINAL"``, ``0`` or a DisplayMode -> DisplayMode; ValueError naming the choices."""
    if isinstance(value, DisplayMode):
        return value
    if isinstance(value, str):
        try:
            return DisplayMode[value.strip().upper().replace(" ", "_")]
        except KeyError:
            pass
    elif isinstance(value, int) and not isinstance(value, bool):
        try:
            return DisplayMode(value)
        except ValueError:
            pass
    raise ValueError(f"unknown display mode {value!r} (choose from {', '.join(m.name.lower() for m in DisplayMode)})")


def glsl_chunk() -> str:
    lines = ["// generated from inshade.scene.display.DisplayMode; do not edit"]
    lines += [f"#define DISPLAY_{m.name} {int(m)}" for m in DisplayMode]
    return "\n".join(lines) + "\n"
