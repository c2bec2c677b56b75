"""Scene labels: short texts and divider lines that say which side of a comparison is which.

They are scene data (scene.json ``"labels"``), drawn over the *displayed* picture only: by the window
(imgui draw list, viewer/ui.py) and by the 8-bit PNG writer (``headless.save_render``, Pillow). The
float image a render returns and the EXR stay untouched, so labels never move a recorded pixel.

    "labels": [
      {"text": "analytic", "at": [0.25, 0.9], "when": {"view": 2}},
      {"text": "learned", "at": [0.75, 0.9], "when": {"view": [1, 2]}, "align": "center"},
      {"line": [[0.5, 0.0], [0.5, 1.0]], "when": {"view": "split"}}
    ]

``at`` / ``line`` points are ``[u, v]`` with (0, 0) bottom-left, (1, 1) top-right: of the camera's
field for a ``plane2d`` camera (the labels follow pan and zoom), else of the image. ``at`` is where
the text is anchored (``align``: ``left``, ``center`` or ``right``, vertically centred); texts stay
inside the image. ``when`` maps setting names to a value or a list of values: the label shows when
every named setting has one of them. ``modes`` lists the display modes it shows in (default
``final`` and ``network``: the views of the scene pass itself). The built-in bool setting
``labels`` (scene/settings.py BUILTIN_SETTINGS) turns every label off: ``--set labels=false``.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass

from .common import object_items

log = logging.getLogger("inshade")

LABEL_KEYS = ("text", "line", "at", "align", "when", "modes")
ALIGNS = ("left", "center", "right")
DEFAULT_MODES = ("final", "network")
SETTING = "labels"       # the built-in setting that turns labels on and off


@dataclass(frozen=True)
class Label:
    text: str | None = None
    at: tuple | None = None           # (u, v) of a text
    line: tuple | None = None         # ((u0, v0), (u1, v1)) of a divider
    align: str = "center"
    when: tuple = ()                  # ((setting, (allowed values...)), ...)
    modes: tuple = DEFAULT_MODES

    def shown(self, values: dict, mode: str) -> bool:
        if mode not in self.modes:
            return False
        return all(name in values and values[name] in allowed for name, allowed in self.when)


def _point(value, where: str) -> tuple:
    if not (isinstance(value, list) and len(value) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
        raise ValueError(f"{where}: must be [u, v], two finite numbers, got {value!r}")
    return float(value[0]), float(value[1])


def parse_labels(data, settings: dict | None = None, modes=None) -> tuple:
    """Check a scene's ``"labels"`` list; ``settings`` (name -> Setting) checks the names ``when``
    uses. ValueError naming ``labels[i].field``."""
    if data is None:
        return ()
    if not isinstance(data, list):
        raise ValueError("labels: must be a list of {\"text\": ..., \"at\": [u, v], \"when\": {...}}")
    out = []
    for w, item in object_items(data, "labels", LABEL_KEYS, error=ValueError):
        text, at, line = item.get("text"), None, None
        if ("text" in item) == ("line" in item):
            raise ValueError(f"{w}: needs exactly one of \"text\" (with \"at\") or \"line\"")
        if text is not None:
            if not isinstance(text, str) or not text.strip():
                raise ValueError(f"{w}.text: must be a non-empty string")
            at = _point(item.get("at"), f"{w}.at")
        else:
            line = item["line"]
            if not (isinstance(line, list) and len(line) == 2):
                raise ValueError(f"{w}.line: must be [[u0, v0], [u1, v1]]")
            line = (_point(line[0], f"{w}.line[0]"), _point(line[1], f"{w}.line[1]"))
        align = item.get("align", "center")
        if align not in ALIGNS:
            raise ValueError(f"{w}.align: must be one of {list(ALIGNS)}, got {align!r}")
        when = item.get("when", {})
        if not isinstance(when, dict):
            raise ValueError(f"{w}.when: must be an object {{setting: value or [values]}}")
        conditions = []
        for name, allowed in when.items():
            if settings is not None and name not in settings:
                raise ValueError(f"{w}.when.{name}: no such setting (this scene has: {', '.join(settings)})")
            allowed = tuple(allowed) if isinstance(allowed, list) else (allowed,)
            conditions.append((name, allowed))
        shown_in = item.get("modes", list(DEFAULT_MODES))
        if not isinstance(shown_in, list) or not all(isinstance(m, str) for m in shown_in):
            raise ValueError(f"{w}.modes: must be a list of display mode names")
        if modes is not None:
            bad = [m for m in shown_in if m not in modes]
            if bad:
                raise ValueError(f"{w}.modes: unknown display mode {bad[0]!r} (known: {', '.join(modes)})")
        out.append(Label(text, at, line, align, tuple(conditions), tuple(shown_in)))
    return tuple(out)


def active(labels, values: dict, mode) -> list:
    """The labels to draw for these setting values and display mode (none if ``labels`` is off)."""
    if not labels or not values.get(SETTING, True):
        return []
    mode = getattr(mode, "label", mode)
    return [lab for lab in labels if lab.shown(values, str(mode))]


def layout(labels, camera, width: float, height: float) -> list:
    """Pixel positions (x right, y down, in a ``width`` x ``height`` view) of the labels:
    ``("text", x, y, text, align)`` and ``("line", x0, y0, x1, y1)``."""
    view = None
    if camera is not None:
        try:
            view = camera.uniforms(max(int(width), 1), max(int(height), 1)).get("u_view")
        except Exception:   # a camera without a field view: image space
            view = None

    def pixel(p):
        u, v = p
        if view is not None:
            u, v = (u - view[0]) / view[2], (v - view[1]) / view[3]
        return u * width, (1.0 - v) * height

    out = []
    for lab in labels:
        if lab.text is not None:
            out.append(("text", *pixel(lab.at), lab.text, lab.align))
        else:
            out.append(("line", *pixel(lab.line[0]), *pixel(lab.line[1])))
    return out


def font_size(width: int, height: int) -> int:
    """Text height of PNG labels: about 6% of the short side, 11..24 px."""
    return int(min(24, max(11, round(min(width, height) * 0.06))))


MIN_FONT = 8   # px: labels shrink to fit the picture and each other, down to this


def split_labels(left: str, right: str, setting: str = "view", value: str = "split", at: float = 0.5,
                 divider: bool = True) -> list[dict]:
    """scene.json ``"labels"`` of a side-by-side view drawn by the scene pass at ``at`` of the width:
    what each side shows, and (``divider``) the line between them."""
    when = {setting: value}
    out = [{"text": left, "at": [at / 2, 0.95], "when": when}, {"text": right, "at": [(1 + at) / 2, 0.95], "when": when}]
    if divider:
        out.insert(0, {"line": [[at, 0.0], [at, 1.0]], "when": when})
    return out


def fit_texts(items, width: int, height: int, size: int):
    """(font, [(x, y, text, anchor, box)]) of the laid-out text items: the largest font size from
    ``size`` down to MIN_FONT at which every text fits inside the picture (moved in from its edges)
    and no two texts overlap (at MIN_FONT they are drawn however they fall)."""
    from PIL import Image, ImageDraw, ImageFont

    draw = ImageDraw.Draw(Image.new("L", (1, 1)))
    texts = [item for item in items if item[0] == "text"]
    for k in range(size, MIN_FONT - 1, -1):
        font = ImageFont.load_default(size=k)
        placed = []
        for _, x, y, text, align in texts:
            anchor = {"left": "lm", "center": "mm", "right": "rm"}[align]
            box = draw.textbbox((x, y), text, font=font, anchor=anchor, stroke_width=1)
            dx = max(0.0, 1.0 - box[0]) - max(0.0, box[2] - (width - 1))   # keep the text inside the image
            dy = max(0.0, 1.0 - box[1]) - max(0.0, box[3] - (height - 1))
            moved = (box[0] + dx, box[1] + dy, box[2] + dx, box[3] + dy)
            placed.append((x + dx, y + dy, text, anchor, moved))
        fits = all(b[4][0] >= 0 and b[4][2] <= width and b[4][1] >= 0 and b[4][3] <= height for b in placed)
        apart = all(not _overlap(a[4], b[4]) for i, a in enumerate(placed) for b in placed[i + 1:])
        if fits and apart:
            break
    return font, placed


def _overlap(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def draw_on_png(path, labels, camera) -> None:
    """Draw ``labels`` onto the 8-bit PNG at ``path`` (white text with a dark outline, white lines),
    the text size shrunk until the texts fit the picture and each other (``fit_texts``)."""
    from PIL import Image, ImageDraw

    with Image.open(path) as im:
        im.load()
        image = im.copy()
    w, h = image.size
    draw = ImageDraw.Draw(image)
    white = (255, 255, 255, 255) if image.mode == "RGBA" else (255, 255, 255)
    dark = (0, 0, 0, 255) if image.mode == "RGBA" else (0, 0, 0)
    items = layout(labels, camera, w, h)
    for item in items:
        if item[0] == "line":
            x0, y0, x1, y1 = item[1:]
            draw.line([(x0, y0), (x1, y1)], fill=white, width=1)
    font, placed = fit_texts(items, w, h, font_size(w, h))
    for x, y, text, anchor, _ in placed:
        draw.text((x, y), text, font=font, anchor=anchor, fill=white, stroke_width=1, stroke_fill=dark)
    image.save(path, format="PNG")


def labels_for_info(info: dict) -> list:
    """The active labels of the render a sidecar record describes: the scene file's ``"labels"``
    evaluated against ``view.settings`` and ``view.mode``. Empty when there are none (or the scene
    file cannot be read back: labels are decoration, never a reason to fail a render)."""
    view = info.get("view") if isinstance(info, dict) else None
    path = (info.get("scene") or {}).get("path") if isinstance(info, dict) else None
    if not isinstance(view, dict) or not isinstance(path, str) or not path.endswith(".json"):
        return []
    settings = view.get("settings") or {}
    if not settings.get(SETTING, True):
        return []
    try:
        from inshade.bundle import read_json

        labels = parse_labels(read_json(path).get("labels"))
    except Exception as exc:   # noqa: BLE001
        log.warning("labels of %s not drawn: %s", path, exc)
        return []
    return active(labels, settings, view.get("mode", "final"))
