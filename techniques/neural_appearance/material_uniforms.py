"""The reference material's constants as the pass's uniforms, read from the asset's material.json
(numpy only: the per-frame hook of the technique record imports this)."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

MATERIAL_FILE = "material.json"


@lru_cache(maxsize=32)
def _uniforms(path: str, mtime_ns: int) -> dict:
    from .material import load_material, uniforms

    return dict(uniforms(load_material(path)))


def material_path(scene) -> Path:
    if scene.root is None:
        raise ValueError(f"scene '{scene.name}': a neural appearance scene lives in an asset folder "
                         f"holding {MATERIAL_FILE}")
    return Path(scene.root) / MATERIAL_FILE


def material_uniforms(scene) -> dict:
    """u_na_* values of the scene's material (cached per file version)."""
    path = material_path(scene)
    return _uniforms(str(path), path.stat().st_mtime_ns)
