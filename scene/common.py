"""What every part of a scene description shares: the one error type, the file names a scene folder
holds, the image size limit, and the checks of a number, of a list of objects and of an image file that
several fields use.

The lowest of the scene modules: the others import it, it imports none of them but ``image_io``."""
from __future__ import annotations

import math
from pathlib import Path

SCENE_FILE = "scene.json"
BUNDLE_FILE = "bundle.json"
MAX_SIZE = 16384


class SceneError(ValueError):
    """A scene description that cannot be used; the message names the file and the field."""


def finite(v) -> bool:
    """A JSON number (not a bool) that is finite."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def is_bundle(path: Path) -> bool:
    """A bundle folder, or a bundle.json itself."""
    return (path / BUNDLE_FILE).is_file() or (path.name == BUNDLE_FILE and path.is_file())


def object_items(items: list, what: str, known, error=SceneError):
    """(where, item) for each item of a JSON list of objects, ``where`` naming it ``what[i]``. An
    item that is no object, or has a field outside ``known`` (listed in the message in the order
    given), raises ``error`` naming the item or the field."""
    for i, item in enumerate(items):
        where = f"{what}[{i}]"
        if not isinstance(item, dict):
            raise error(f"{where}: must be an object")
        extra = sorted(set(item) - set(known))
        if extra:
            raise error(f"{where}.{extra[0]}: unknown field (known: {', '.join(known)})")
        yield where, item


def check_image(path: Path, field: str, exr: bool) -> None:
    """An image file the renderer will read: a readable header of a sane size (image_io), else one
    SceneError naming the field and the file."""
    from .image_io import check_image_file

    try:
        check_image_file(path, exr=exr)
    except ValueError as exc:
        raise SceneError(f"{field}: {exc}") from None
