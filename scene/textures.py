"""Plain images a scene's program samples: ``"textures"``, each bound to a sampler uniform."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from .common import SceneError, check_image, object_items

TEXTURE_KEYS = {"uniform", "image", "mipmaps", "anisotropy", "repeat"}


@dataclass
class SceneTexture:
    """An 8-bit image bound to a sampler uniform as stored (no colour decode: the program decides),
    image row 0 at v = 1 (uv (0,0) bottom-left), optionally with a GL-built mip chain."""
    uniform: str
    image: Path
    mipmaps: bool = True
    anisotropy: float = 1.0
    repeat: bool = True


def parse_textures(data, root: Path) -> list:
    if not isinstance(data, list):
        raise SceneError("textures: must be a list of {\"uniform\": ..., \"image\": ...}")
    out = []
    for w, t in object_items(data, "textures", sorted(TEXTURE_KEYS)):
        name = t.get("uniform")
        if not isinstance(name, str) or not name.isidentifier():
            raise SceneError(f"{w}.uniform: must be a GLSL identifier, got {name!r}")
        if not isinstance(t.get("image"), str) or not (root / t["image"]).is_file():
            raise SceneError(f"{w}.image: no image file {t.get('image')!r} (relative to the scene file)")
        aniso = t.get("anisotropy", 1.0)
        if isinstance(aniso, bool) or not isinstance(aniso, (int, float)) or not 1.0 <= aniso <= 16.0:
            raise SceneError(f"{w}.anisotropy: must be a number in [1, 16], got {aniso!r}")
        for key in ("mipmaps", "repeat"):
            if not isinstance(t.get(key, True), bool):
                raise SceneError(f"{w}.{key}: must be true or false")
        check_image((root / t["image"]).resolve(), f"{w}.image", exr=False)
        out.append(SceneTexture(name, (root / t["image"]).resolve(), t.get("mipmaps", True), float(aniso),
                                t.get("repeat", True)))
    return out
