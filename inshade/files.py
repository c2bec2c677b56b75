"""Atomic output files: every file inshade writes appears whole or not at all.

Each output is written to a temporary file in its own folder (same suffix, so writers that go by
the suffix still work) and renamed into place with ``os.replace`` only once everything it belongs
with has been written. A write that fails halfway leaves no partial file, and files that were at
those paths before are untouched. A group of outputs is checked before the first rename (a target
that is a folder fails there, naming it), so a group never lands half. Each file gets the mode a
plain ``open()`` would give it (0666 less the umask), not the temporary file's private 0600; a
folder the write had to create is said once on the ``inshade`` log.

    with atomic_files(image, sidecar) as (image_tmp, sidecar_tmp):
        write_png(image_tmp, ...)
        sidecar_tmp.write_text(...)
"""
from __future__ import annotations

import logging
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

log = logging.getLogger("inshade")

_LIVE: set[Path] = set()   # temporaries not yet renamed or removed (see remove_temporaries)


def remove_temporaries() -> None:
    """Remove every temporary an unfinished ``atomic_files`` block holds (for an exit that
    skips unwinding, e.g. the CLI's Ctrl+C handler)."""
    for tmp in list(_LIVE):
        tmp.unlink(missing_ok=True)
        _LIVE.discard(tmp)


def file_mode() -> int:
    """0666 less the process umask: the mode ``open(path, "w")`` creates a file with."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def make_folder(folder: Path) -> None:
    """Create ``folder`` (and its parents) if missing, and say so once."""
    if not folder.is_dir():
        folder.mkdir(parents=True, exist_ok=True)
        log.info("created folder %s", folder)


@contextmanager
def atomic_files(*paths):
    """Yield one temporary path per target (the folders are created); on success each is moved
    onto its target, in order; on any exception every temporary file is removed. An OSError
    names the target it is about (``exc.filename``)."""
    targets = [Path(p) for p in paths]
    temps: list[Path] = []
    try:
        for target in targets:
            if target.is_dir():
                raise IsADirectoryError(21, "is a folder", str(target))
            make_folder(target.parent)
            try:
                fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=target.suffix, dir=target.parent)
            except OSError as exc:
                raise type(exc)(exc.errno, exc.strerror, str(target)) from None
            os.close(fd)
            temps.append(Path(tmp))
            _LIVE.add(Path(tmp))
        yield temps if len(temps) != 1 else temps[0]
        mode = file_mode()
        for tmp, target in zip(temps, targets):   # checked again: the block may have made a folder there
            if target.is_dir():
                raise IsADirectoryError(21, "is a folder", str(target))
            os.chmod(tmp, mode)
        for tmp, target in zip(temps, targets):
            os.replace(tmp, target)
    except BaseException:
        for tmp in temps:
            tmp.unlink(missing_ok=True)
        raise
    finally:
        _LIVE.difference_update(temps)


def atomic_write(path, data: str | bytes) -> Path:
    """Write ``data`` (text as UTF-8) to ``path`` atomically."""
    with atomic_files(path) as tmp:
        tmp.write_bytes(data.encode() if isinstance(data, str) else data)
    return Path(path)
