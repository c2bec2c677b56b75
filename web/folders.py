"""An output folder written whole (the web page, the three.js material): refused before any work when
it is a file or holds files (unless ``force``), then filled beside it and renamed into place, so it
appears complete or not at all."""
from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

__all__ = ["PageExistsError", "claim_folder", "write_folder"]


class PageExistsError(ValueError):
    """The output folder already holds files (and --force was not given)."""


def claim_folder(out, force: bool) -> None:
    """Refuse an output folder that is a file, or that holds files unless ``force``: before any work."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise PageExistsError(f"{out}: -o: is a file, expected a folder")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise PageExistsError(f"{out}: -o: already holds files; choose another folder, or pass --force to "
                              "replace them")


def write_folder(out, fill) -> None:
    """``fill(folder)`` writes a new folder (which it creates) that then replaces ``out``: it appears
    complete or not at all."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        fill(staging / "new")
        if out.exists():
            out.rename(staging / "old")
        (staging / "new").rename(out)
    finally:
        shutil.rmtree(staging, ignore_errors=True)

