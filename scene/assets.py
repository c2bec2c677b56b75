"""Where scenes are found: the scene folders under a root (``trained/``), and a bare asset name such
as ``prt_creature`` looked up in $INSHADE_ASSETS and the shipped ``trained/``."""
from __future__ import annotations

from pathlib import Path

from .common import BUNDLE_FILE, SCENE_FILE, SceneError

ASSETS_ENV = "INSHADE_ASSETS"   # extra folders of assets, os.pathsep-separated, searched before trained/


def list_scenes(root) -> list[Path]:
    """Sub-folders of ``root`` (e.g. ``trained/``) that hold a scene.json or a bundle, sorted."""
    root = Path(root)
    if not root.is_dir():
        return []
    return sorted(p for p in root.iterdir() if p.is_dir() and ((p / SCENE_FILE).is_file() or (p / BUNDLE_FILE).is_file()))


def asset_roots() -> list[Path]:
    """Folders a bare asset name is looked up in: each folder of $INSHADE_ASSETS, then the shipped
    ``trained/`` (beside the package, in this editable layout)."""
    import os

    import inshade

    roots = [Path(p).expanduser() for p in os.environ.get(ASSETS_ENV, "").split(os.pathsep) if p]
    roots.append(Path(inshade.__file__).resolve().parents[1] / "trained")
    return roots


def resolve_asset(name_or_path) -> Path:
    """The path of an asset given as a path (used as is when it exists) or as a bare name such as
    ``prt_creature`` (looked up in ``asset_roots()``). A path that does not exist is a SceneError
    saying so, with the closest asset names."""
    import difflib

    path = Path(name_or_path)
    if path.exists():
        return path
    text = str(name_or_path)
    bare = bool(text) and path.name == text and text not in (".", "..")
    if bare:
        for root in asset_roots():
            if (root / text).exists():
                return root / text
    names = sorted({p.name for root in asset_roots() for p in list_scenes(root)})
    close = difflib.get_close_matches(path.name, names, n=3, cutoff=0.6)
    hint = f" (did you mean {', '.join(close)}?)" if close else \
        (f" (no such path, nor an asset in {', '.join(str(r) for r in asset_roots())})" if bare else "")
    raise SceneError(f"{text}: does not exist{hint}")
