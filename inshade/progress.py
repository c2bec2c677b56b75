"""Progress of long work (training loops, data generation), on a TTY or off it.

On a TTY: a tqdm bar (transient, ``leave=False``). Off a TTY (logs, CI, ``nohup``): a plain line on
stderr every ``interval`` seconds (default 10, or ``INSHADE_PROGRESS_INTERVAL``) with step/total,
the latest postfix the caller set (a loss, a PSNR), the elapsed time and an ETA, and one closing
line if any was written. Short work off a TTY stays silent. ``enabled=False`` silences both.

    bar = progress(range(steps), desc="neural_image", enabled=progress_flag)
    for step in bar:
        ...
        bar.set_postfix(psnr=f"{value:.2f}")

Only what is printed depends on this module: it never touches the caller's numbers.
"""
from __future__ import annotations

import math
import os
import sys
import time

DEFAULT_INTERVAL = 10.0
INTERVAL_ENV = "INSHADE_PROGRESS_INTERVAL"


def default_interval() -> float:
    """Seconds between off-TTY lines: ``INSHADE_PROGRESS_INTERVAL`` if set (and valid), else 10."""
    try:
        value = float(os.environ.get(INTERVAL_ENV, DEFAULT_INTERVAL))
    except ValueError:
        return DEFAULT_INTERVAL
    return value if value > 0 else DEFAULT_INTERVAL


def format_seconds(seconds: float) -> str:
    """12.3 s, 4:05, 1:02:03."""
    if not math.isfinite(seconds):
        return "?"
    if seconds < 60:
        return f"{seconds:.1f} s"
    s = int(round(seconds))
    h, rest = divmod(s, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class Progress:
    """An iterable / context manager with tqdm's small API (``update``, ``set_postfix``,
    ``close``); see the module docstring. ``stream`` and ``clock`` are for tests."""

    def __init__(self, iterable=None, *, total: int | None = None, desc: str = "", initial: int = 0,
                 unit: str = "it", unit_scale: bool = False, enabled: bool | None = None,
                 interval: float | None = None, stream=None, clock=time.monotonic, tty: bool | None = None):
        if total is None and iterable is not None:
            try:
                total = len(iterable)
            except TypeError:
                total = None
        self.iterable, self.total, self.desc, self.unit = iterable, total, desc, unit
        self.unit_scale = unit_scale
        self.n = self.initial = int(initial)
        self.stream = sys.stderr if stream is None else stream
        self.clock = clock
        self.interval = default_interval() if interval is None else float(interval)
        self.postfix = ""
        self.lines = 0
        self.closed = False
        if tty is None:
            isatty = getattr(self.stream, "isatty", None)
            tty = bool(isatty and isatty())
        self.mode = "off" if enabled is False else ("tty" if tty else "lines")
        self._bar = None
        if self.mode == "tty":
            from tqdm import tqdm
            self._bar = tqdm(total=total, desc=desc, initial=initial, unit=unit, unit_scale=unit_scale,
                             leave=False, file=self.stream)
        self.start = self.clock()
        self.last = self.start

    # tqdm's API -------------------------------------------------------------------------------
    def __iter__(self):
        try:
            for item in self.iterable:
                yield item
                self.update(1)
        finally:
            self.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def update(self, n: int = 1) -> None:
        self.n += n
        if self._bar is not None:
            self._bar.update(n)
        elif self.mode == "lines":
            now = self.clock()
            if now - self.last >= self.interval:
                self.last = now
                self._write(now)

    def set_postfix(self, ordered_dict=None, refresh: bool = True, **kwargs) -> None:
        items = {**(ordered_dict or {}), **kwargs}
        self.postfix = ", ".join(f"{k}={v}" for k, v in items.items())
        if self._bar is not None:
            self._bar.set_postfix(items, refresh=refresh)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        if self._bar is not None:
            self._bar.close()
        elif self.mode == "lines" and self.lines:
            self._write(self.clock(), done=True)

    # off-TTY lines ----------------------------------------------------------------------------
    def _count(self, n) -> str:
        if not self.unit_scale:
            return str(n)
        for div, suffix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
            if abs(n) >= div:
                return f"{n / div:.1f}{suffix}"
        return str(n)

    def line(self, now: float, done: bool = False) -> str:
        """The text of one off-TTY line at clock time ``now``."""
        elapsed = now - self.start
        head = f"{self.desc}: " if self.desc else ""
        if self.total:
            pct = 100.0 * self.n / self.total
            count = f"{self._count(self.n)}/{self._count(self.total)} {self.unit} ({pct:.0f}%)"
        else:
            count = f"{self._count(self.n)} {self.unit}"
        parts = [head + count]
        if self.postfix:
            parts.append(self.postfix)
        if done:
            parts.append(f"done in {format_seconds(elapsed)}")
        else:
            parts.append(f"{format_seconds(elapsed)} elapsed")
            done_here = self.n - self.initial
            if self.total and done_here > 0:
                eta = elapsed / done_here * max(self.total - self.n, 0)
                parts.append(f"ETA {format_seconds(eta)}")
        return ", ".join(parts)

    def _write(self, now: float, done: bool = False) -> None:
        self.lines += 1
        print(self.line(now, done), file=self.stream, flush=True)


def progress(iterable=None, **kwargs) -> Progress:
    """``Progress(iterable, **kwargs)``: tqdm on a TTY, a line every ~10 s off it."""
    return Progress(iterable, **kwargs)


# ---------------------------------------------------------------------------------------------
# waiting on one long call (a driver's shader JIT): a watcher process, since the call holds the GIL

WAIT_QUIET_S = 2.0      # say nothing for a wait shorter than this
WAIT_LINE_S = 10.0      # off a TTY: a line this often

_WATCHER = r"""
import os, sys, time
what, quiet, every, tty = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), sys.argv[4] == "1"
parent = int(sys.argv[5])
start = time.monotonic()
frames = "|/-\\"
shown, k = 0.0, 0
time.sleep(quiet)
while os.getppid() == parent:   # a parent gone without stopping us (killed, os._exit): stop too
    now = time.monotonic() - start
    if tty:
        os.write(2, f"\r{frames[k % 4]} {what}: {now:.0f} s".encode())
        k += 1
        time.sleep(0.25)
    else:
        if now - shown >= every or shown == 0.0:
            os.write(2, f"inshade: still {what} ({now:.0f} s)\n".encode())
            shown = now
        time.sleep(0.5)
"""


_WATCHERS: set = set()   # the watcher processes running now


def stop_watchers() -> None:
    """Stop every watcher now: for an exit that skips ``waiting.__exit__`` (Ctrl+C's os._exit),
    so no watcher outlives its process holding its stderr open."""
    for proc in list(_WATCHERS):
        proc.kill()
        proc.wait()
    _WATCHERS.clear()


class waiting:
    """``with waiting("compiling 64x4 inline network"): draw()``: while the body runs, a spinner
    with the elapsed seconds on a TTY, or a line every 10 s off it (nothing for the first 2 s).
    Python threads cannot run while a GL call holds the GIL, so a small watcher process prints;
    it is stopped when the body returns. ``seconds`` holds the body's wall time afterwards."""

    def __init__(self, what: str, *, stream=None, enabled: bool = True, quiet: float = WAIT_QUIET_S,
                 every: float = WAIT_LINE_S):
        self.what, self.enabled, self.quiet, self.every = what, enabled, quiet, every
        self.stream = sys.stderr if stream is None else stream
        self.seconds = 0.0
        self._proc = None

    def __enter__(self):
        import subprocess

        self.start = time.perf_counter()
        if self.enabled:
            isatty = getattr(self.stream, "isatty", None)
            tty = bool(isatty and isatty())
            try:
                self.stream.flush()
                self._tty = tty
                self._proc = subprocess.Popen([sys.executable, "-c", _WATCHER, self.what, str(self.quiet),
                                               str(self.every), "1" if tty else "0", str(os.getpid())],
                                              stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL)
                _WATCHERS.add(self._proc)
            except OSError:   # no watcher (e.g. a process limit): the wait is just silent
                self._proc = None
        return self

    def __exit__(self, *exc):
        self.seconds = time.perf_counter() - self.start
        if self._proc is not None:
            self._proc.kill()
            self._proc.wait()
            _WATCHERS.discard(self._proc)
            if self._tty and self.seconds >= self.quiet:
                self.stream.write("\r\x1b[K")   # clear the spinner's line
                self.stream.flush()
        return False
