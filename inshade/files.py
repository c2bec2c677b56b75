"""Atomic output files: every file inshade writes appears whole or not at all.

Each output is written to a temporary file in its own folder (same suffix, so writers that go by
the suffix still work) and renamed into place with ``os.replace`` only once everything it belongs
with has been written. A write that fails halfway leaves no partial file, and files that were at
those paths before are untouched.

    with atomic_files(image, sidecar) as (image_tmp, sidecar_tmp):
        write_png(image_tmp, ...)
        sidecar_tmp.write_text(...)
"""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path


_LIVE: set[Path] = set()   # temporaries not yet renamed or removed (see remove_temporaries)


def remove_temporaries() -> None:
    """Remove every temporary an unfinished ``atomic_files`` block holds (for an exit that
    skips unwinding, e.g. the CLI's Ctrl+C handler)."""
    for tmp in list(_LIVE):
        tmp.unlink(missing_ok=True)
        _LIVE.discard(tmp)


@contextmanager
def atomic_files(*paths):
    """Yield one temporary path per target (the folders are created); on success each is moved
    onto its target, in order; on any exception every temporary file is removed."""
    targets = [Path(p) for p in paths]
    temps: list[Path] = []
    try:
        for target in targets:
            target.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=target.suffix, dir=target.parent)
            os.close(fd)
            temps.append(Path(tmp))
            _LIVE.add(Path(tmp))
        yield temps if len(temps) != 1 else temps[0]
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
