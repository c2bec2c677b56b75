"""How a scene is looked at and compared: its ``"camera"`` and named ``"bookmarks"`` (scene/camera.py),
the ``"display"`` modes the UI offers (scene/display.py), and the ``"reference"`` image the network is
compared with."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from .camera import camera_from_dict
from .common import SceneError, check_image
from .display import UI_MODES, DisplayMode, parse_mode

REFERENCE_SPACES = ("field", "screen")


@dataclass
class Reference:
    image: Path
    colour: str = "srgb"      # "srgb" (8-bit PNG, decoded to linear) or "linear" (EXR)
    space: str = "field"      # "field": lives in the camera's uv plane; "screen": a render of the same view


def check_camera(value, field: str) -> None:
    """A camera the scene can make, checked when the scene loads: one clear error there, not at draw time."""
    if not isinstance(value, dict) or not isinstance(value.get("type"), str):
        raise SceneError(f"{field}: must be a camera object with a \"type\" name, got {str(value)[:80]}")
    camera_from_dict(value, field)


def parse_bookmarks(bookmarks) -> dict:
    """``"bookmarks"``: {name: camera}, each camera checked."""
    if not isinstance(bookmarks, dict):
        raise SceneError("bookmarks: must be an object {name: camera}")
    for k, v in bookmarks.items():
        check_camera(v, f"bookmarks.{k}")
    return bookmarks


def parse_display(display) -> tuple[DisplayMode, tuple, float]:
    """``"display"``: (the mode shown first, the modes the UI offers, the split position)."""
    if not isinstance(display, dict):
        raise SceneError("display: must be an object")
    if not isinstance(display.get("modes", []), list):
        raise SceneError(f"display.modes: must be a list of mode names, got {display.get('modes')!r}")
    try:
        mode = parse_mode(display.get("mode", "final"))
        modes = tuple(parse_mode(m) for m in display.get("modes", [m.name.lower() for m in UI_MODES]))
    except ValueError as exc:
        raise SceneError(f"display: {exc}") from None
    split = display.get("split", 0.5)
    if isinstance(split, bool) or not isinstance(split, (int, float)) or not 0.0 <= split <= 1.0:
        raise SceneError(f"display.split: must be a number in [0, 1], got {split!r}")
    return mode, modes, float(split)


def parse_reference(ref, root: Path) -> Reference | None:
    """``"reference"``: an image file (or {"image": ..., "colour": ..., "space": ...}) relative to
    the scene file."""
    if ref is None:
        return None
    if isinstance(ref, str):
        ref = {"image": ref}
    if not isinstance(ref, dict) or not isinstance(ref.get("image"), str):
        raise SceneError("reference.image: must name an image file (relative to the scene file)")
    image = (root / ref["image"]).resolve()
    if not image.is_file():
        raise SceneError(f"reference.image: no file {image}")
    colour, space = ref.get("colour", "srgb"), ref.get("space", "field")
    if colour not in ("srgb", "linear"):
        raise SceneError(f"reference.colour: must be \"srgb\" or \"linear\", got {colour!r}")
    check_image(image, "reference.image", exr=colour == "linear")
    if space not in REFERENCE_SPACES:
        raise SceneError(f"reference.space: must be one of {list(REFERENCE_SPACES)}, got {space!r}")
    return Reference(image, colour, space)
