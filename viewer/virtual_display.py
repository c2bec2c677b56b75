"""A virtual X display (Xvfb) for the window app on a machine without a screen: the docs' window
pictures and the viewer's tests start their own on a free display number."""
from __future__ import annotations

import shutil
import subprocess
import time
from pathlib import Path

DISPLAY_NUMBERS = range(90, 190)     # above the numbers desktops and xvfb-run take
SCREEN = "1280x1024x24"


class VirtualDisplayError(RuntimeError):
    """Xvfb is missing or did not start."""


def _free(number: int) -> bool:
    return not Path(f"/tmp/.X{number}-lock").exists() and not Path(f"/tmp/.X11-unix/X{number}").exists()


def start_xvfb(timeout: float = 20.0) -> tuple[subprocess.Popen, str]:
    """(the Xvfb process, its display ":N"), once its socket is there; the caller stops the process."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        raise VirtualDisplayError("Xvfb not found on PATH: install xvfb (apt-get install xvfb)")
    number = next((n for n in DISPLAY_NUMBERS if _free(n)), None)
    if number is None:
        raise VirtualDisplayError(f"no free X display number in :{DISPLAY_NUMBERS[0]}..:{DISPLAY_NUMBERS[-1]}")
    proc = subprocess.Popen([xvfb, f":{number}", "-screen", "0", SCREEN, "-nolisten", "tcp"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + timeout
    while not Path(f"/tmp/.X11-unix/X{number}").exists():
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise VirtualDisplayError(f"Xvfb :{number} did not start within {timeout:g} s (exit code {proc.poll()})")
        time.sleep(0.05)
    return proc, f":{number}"
