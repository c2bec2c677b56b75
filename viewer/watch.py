"""Polling file watcher for hot reload (no extra dependency; a few stat() calls per poll)."""
from __future__ import annotations

import time
from pathlib import Path


class FileWatcher:
    """``poll()`` returns the watched paths whose (mtime_ns, size) changed since the last poll.

    Polls at most every ``interval`` seconds unless ``force``; a missing file counts as a state too
    (deleted -> changed; it is reported again when it reappears).
    """

    def __init__(self, paths, interval: float = 0.5):
        self.interval = interval
        self._last = 0.0
        self._state = {Path(p): self._stat(Path(p)) for p in paths}

    @staticmethod
    def _stat(path: Path):
        try:
            st = path.stat()
        except OSError:
            return None
        return (st.st_mtime_ns, st.st_size)

    @property
    def paths(self) -> list[Path]:
        return list(self._state)

    def poll(self, force: bool = False) -> list[Path]:
        now = time.monotonic()
        if not force and now - self._last < self.interval:
            return []
        self._last = now
        changed = []
        for path, old in self._state.items():
            new = self._stat(path)
            if new != old:
                self._state[path] = new
                changed.append(path)
        return changed
