"""scene.json data for the code that writes one (trainers, converters, a technique's file opener).

Each function takes keyword arguments and returns the JSON form description.py reads, so no writer
spells the format's header or a part's keys itself:

    scene_json("my_image", "my image", "passes/field2d.frag", (256, 256),
               networks=[network(".", "net", output="rgb")], camera=plane2d(),
               display=display_modes("final", "network"), settings={"exposure": exposure_setting()},
               requires=requires())

``scene_json`` writes the header, then the parts in the order they are given: the order of a
scene.json's keys is its writer's, and a rewritten asset keeps the bytes it shipped with. Plain data,
no import of the parser (a technique's record may build a scene while the registry is loading).
"""
from __future__ import annotations

import math

FORMAT = "inshade.scene"
VERSION = 1
# What a scene.json may hold after its header (format, version, name, title, program, size); the
# parser (description.py) reads each.
PARTS = ("networks", "sdf", "mesh", "reference", "textures", "camera", "bookmarks", "lights", "environment",
         "display", "labels", "settings", "requires", "notes")


def scene_json(name: str, title: str, program: str, size, **parts) -> dict:
    """A whole scene.json: the header, then ``parts`` (names of ``PARTS``) in the order given."""
    unknown = [k for k in parts if k not in PARTS]
    if unknown:
        raise ValueError(f"{unknown[0]}: not a part of a scene (parts: {', '.join(PARTS)})")
    return {"format": FORMAT, "version": VERSION, "name": name, "title": title, "program": program,
            "size": list(size), **parts}


# --- what is drawn ---------------------------------------------------------------------------------

def network(bundle: str, prefix: str, output: str | None = None) -> dict:
    """One of ``"networks"``: a bundle folder (relative to the scene) bound under a GLSL prefix,
    ``output`` naming which of its outputs a field pass shows."""
    return {"bundle": bundle, "prefix": prefix, **({} if output is None else {"output": output})}


def network_sdf(bundle: str = ".") -> dict:
    """``"sdf"`` traced from a network SDF bundle (codegen/network_sdf.py) instead of an analytic file."""
    return {"network": bundle}


def mesh_shape(shape: str, **params) -> dict:
    """``"mesh"`` as a built-in shape (geometry/shapes.py), e.g. ``mesh_shape("teapot", segments=12)``."""
    return {"shape": shape, **params}


def texture(uniform: str, image: str, *, mipmaps: bool, repeat: bool | None = None,
            anisotropy: float | None = None) -> dict:
    """One of ``"textures"``: a plain image the program samples through ``uniform``."""
    out = {"uniform": uniform, "image": image, "mipmaps": mipmaps}
    if repeat is not None:
        out["repeat"] = repeat
    if anisotropy is not None:
        out["anisotropy"] = anisotropy
    return out


def reference(image: str, colour: str, space: str) -> dict:
    """``"reference"``: the image the display modes compare with (colour "srgb" | "linear", space
    "field" | "screen")."""
    return {"image": image, "colour": colour, "space": space}


# --- how it is seen --------------------------------------------------------------------------------

def orbit(target, distance: float, yaw: float, pitch: float, fov_y: float = 40.0) -> dict:
    """An orbit camera (or bookmark) around ``target``, angles in degrees."""
    return {"type": "orbit", "fov_y": fov_y, "target": list(target), "distance": distance, "yaw": yaw,
            "pitch": pitch}


def orbit_around(center, radius: float, yaw: float, pitch: float, fov_y: float = 40.0) -> dict:
    """An orbit camera whose view cone holds the sphere (``center``, ``radius``) with 5% to spare."""
    distance = radius / math.sin(math.radians(fov_y / 2.0)) * 1.05
    return orbit([float(c) for c in center], round(distance, 6), yaw, pitch, fov_y)


def plane2d(center=(0.5, 0.5), zoom: float = 1.0, aspect: float = 1.0) -> dict:
    """A 2D field camera (or bookmark): the field's point at the picture's centre, and the zoom."""
    return {"type": "plane2d", "center": list(center), "zoom": zoom, "aspect": aspect}


def display_modes(*modes: str, mode: str | None = None, split: float = 0.5) -> dict:
    """``"display"``: the modes a UI offers (by default only "final"), starting in ``mode`` (the first)."""
    modes = modes or ("final",)
    return {"mode": modes[0] if mode is None else mode, "modes": list(modes), "split": split}


def text_label(text: str, at, when: dict, align: str | None = None) -> dict:
    """One of ``"labels"`` (scene/labels.py): a text at ``at`` (fractions of the picture) shown while the
    settings in ``when`` hold."""
    return {"text": text, "at": list(at), **({} if align is None else {"align": align}), "when": when}


def line_label(start, end, when: dict) -> dict:
    """One of ``"labels"``: a line from ``start`` to ``end`` (fractions of the picture)."""
    return {"line": [list(start), list(end)], "when": when}


def view_labels(left: str, right: str, split: dict, views=()) -> list[dict]:
    """``"labels"`` of a pass with a side-by-side view (shown while ``split`` holds): what each half
    shows and the line between them, then a centred text per single view, ``views`` as (text, when)."""
    return [text_label(left, (0.25, 0.95), split), text_label(right, (0.75, 0.95), split),
            line_label((0.5, 0.0), (0.5, 1.0), split), *(text_label(text, (0.5, 0.95), when) for text, when in views)]


# --- how it is lit ---------------------------------------------------------------------------------

def point_light(position, intensity: float) -> dict:
    """One of ``"lights"``: a point light (inverse-square falloff)."""
    return {"type": "point", "position": list(position), "intensity": intensity}


def directional_light(direction, intensity: float) -> dict:
    """One of ``"lights"``: a light from ``direction`` (towards the light), irradiance ``intensity``."""
    return {"type": "directional", "direction": list(direction), "intensity": intensity}


def sky(preset: str, rotation: float = 0.0, degree: int = 4) -> dict:
    """``"environment"``: a procedural sky (inshade.sh SKY_PRESETS) projected to SH of ``degree``."""
    return {"sky": preset, "rotation": rotation, "degree": degree}


def requires(gl: int = 330) -> dict:
    """``"requires"``: the GLSL version the program needs."""
    return {"gl": gl}


# --- the knobs a UI may turn (scene/settings.py) ---------------------------------------------------
# ``binding`` is exactly one of uniform=, define=, codegen=, environment=, frame=, present= (settings.py
# BINDINGS) naming what the value drives.

def _setting(kind: str, default, extent: dict, label: str, binding: dict) -> dict:
    if len(binding) != 1:
        raise ValueError(f"{label!r}: a setting is bound to exactly one target, got {sorted(binding) or 'none'}")
    return {"type": kind, "default": default, **extent, **binding, "label": label}


def float_setting(default: float, low: float, high: float, label: str, **binding) -> dict:
    return _setting("float", default, {"min": low, "max": high}, label, binding)


def int_setting(default: int, low: int, high: int, label: str, **binding) -> dict:
    return _setting("int", default, {"min": low, "max": high}, label, binding)


def choice_setting(default, choices, label: str, **binding) -> dict:
    return _setting("choice", default, {"choices": list(choices)}, label, binding)


def bool_setting(default: bool, label: str, **binding) -> dict:
    return _setting("bool", default, {}, label, binding)


def exposure_setting() -> dict:
    """The linear exposure every scene's pass multiplies by (u_exposure)."""
    return float_setting(1.0, 0.0, 8.0, "exposure", uniform="u_exposure")


def lut_filter_setting(default: str = "exact") -> dict:
    """Exact (texelFetch + fp32 mix) or fast (hardware filtering) lookups of the learnt arrays."""
    return choice_setting(default, ["exact", "fast"], "LUT filtering", codegen="lut_filter")
