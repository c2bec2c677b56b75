"""What this machine took to draw a program before: the first draw (where a software driver JIT-
compiles the shader) and a frame, by renderer and program key, kept in
``$INSHADE_CACHE_DIR/draws.json`` (default ``~/.cache/inshade``). It lets a message say what to
expect ("85 s last time") instead of guessing, and warn before a view known to take minutes.

A history that cannot be read or written is ignored (it is a hint, never a reason to fail)."""
from __future__ import annotations

import json
import logging
import os
from pathlib import Path

log = logging.getLogger("inshade")
MAX_ENTRIES = 2000


def cache_dir() -> Path:
    return Path(os.environ.get("INSHADE_CACHE_DIR") or Path.home() / ".cache" / "inshade")


def _path() -> Path:
    return cache_dir() / "draws.json"


_DROP = object()   # record(key=_DROP) removes the field
_MEMO: dict = {}   # the file as last read, by (path, mtime, size): a frame asks without re-reading


def _read() -> dict:
    path = _path()
    try:
        st = path.stat()
        stamp = (str(path), st.st_mtime_ns, st.st_size)
        if _MEMO.get("stamp") != stamp:
            data = json.loads(path.read_text())
            _MEMO.update(stamp=stamp, data=data if isinstance(data, dict) else {})
        return _MEMO["data"]
    except (OSError, ValueError):
        return {}


def lookup(renderer: str, key: str) -> dict:
    """What was recorded for ``key`` on ``renderer`` (``first_draw_s``, ``frame_s``, ``pixels``), or {}."""
    entry = _read().get(f"{renderer}|{key}")
    return entry if isinstance(entry, dict) else {}


def entries(renderer: str) -> list[dict]:
    """Every record of ``renderer``."""
    prefix = f"{renderer}|"
    return [v for k, v in _read().items() if k.startswith(prefix) and isinstance(v, dict)]


def record(renderer: str, key: str, **values) -> None:
    from inshade.files import atomic_write

    data = dict(_read())   # the memo stays as read; the file is the record
    name = f"{renderer}|{key}"
    entry = {**(data.get(name) if isinstance(data.get(name), dict) else {}), **values}
    entry = {k: v for k, v in entry.items() if v is not _DROP}
    data.pop(name, None)
    if entry:
        data[name] = entry   # last written goes last: the oldest entries go first below
    if len(data) > MAX_ENTRIES:   # the oldest entries go first (dicts keep insertion order)
        data = dict(list(data.items())[-MAX_ENTRIES:])
    try:
        _path().parent.mkdir(parents=True, exist_ok=True)   # a cache of ours: made without a word
        atomic_write(_path(), json.dumps(data, indent=0, sort_keys=False) + "\n")
    except OSError as exc:
        log.debug("draw history not written (%s)", exc)


def shader_cache_on() -> bool:
    """Mesa keeps compiled shaders between runs unless MESA_SHADER_CACHE_DISABLE says not to."""
    return os.environ.get("MESA_SHADER_CACHE_DISABLE", "").lower() not in ("1", "true", "yes")


def mesa_cache_dir() -> Path:
    """Where Mesa keeps compiled shaders between runs (MESA_SHADER_CACHE_DIR, else the XDG cache)."""
    if os.environ.get("MESA_SHADER_CACHE_DIR"):
        return Path(os.environ["MESA_SHADER_CACHE_DIR"])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "mesa_shader_cache"


def compile_started(renderer: str, key: str, what: str) -> str | None:
    """Marks ``key`` as being compiled by this process, and returns a warning if the last process
    that compiled it ended during the compile (killed, or crashed in the driver): a compile cut off
    while the driver wrote its shader cache can leave an entry that crashes every later run."""
    last = lookup(renderer, key).get("compiling")
    record(renderer, key, compiling={"pid": os.getpid(), "what": what})
    if not isinstance(last, dict) or last.get("pid") == os.getpid() or _alive(last.get("pid")):
        return None
    said = f"the last compile of {last.get('what') or what} on this machine did not finish (its process ended during it)"
    if not shader_cache_on():
        return said
    return (f"{said}; if the driver crashes now, its shader cache holds a broken entry: run again with "
            f"MESA_SHADER_CACHE_DISABLE=true, or remove {mesa_cache_dir()}")


def compile_finished(renderer: str, key: str) -> None:
    record(renderer, key, compiling=_DROP)


def _alive(pid) -> bool:
    if not isinstance(pid, int) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:   # exists, owned by someone else
        return True
    return True
