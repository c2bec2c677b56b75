"""The full-speed program compiled behind the window: on a software driver a program's first draw
JIT-compiles it (seconds to minutes), so the window first draws the scene with its weights in a
texture (loops, not unrolled literals: a quick compile) while another process draws the scene as
set, 8 x 8 pixels, with Mesa's shader cache on; once it is done, the window switches to the program
as set, and its first draw finds the compiled shader in the cache (a second, not the JIT's minutes).
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from inshade.runtime import draw_history

QUICK_STORAGE = "texture"   # the storage the window draws with while the program as set compiles behind
PROGRAM_BINDINGS = ("define", "codegen")   # settings that change the program (the others are uniforms)
SIZE = 8
# a program expected to take this long at its first draw, one network's literals alone that long,
# compiles behind (inshade bench startup: texture storage draws the PRT and UV-free programs' first
# frame in 2-3 s where their one big network's literals take 6-19 s; the hash-grid field, ~6 s with
# literals and 15 s from a texture, and the neural appearance programs, 5 s with their literals spread
# over five networks and 7 s from textures (15 s in the window beside the compile behind), stay below)
WARM_UP_MIN_S = 7.0


def program_settings(scene, values: dict) -> dict:
    """The settings of ``values`` that make the program what it is."""
    return {n: v for n, v in values.items() if scene.settings[n].binding in PROGRAM_BINDINGS}


def worth_it(renderer, source) -> bool:
    """Whether to draw a quick program first: a software driver whose first draw of this program is
    still to come and expected to take WARM_UP_MIN_S or more, most of it one network's literals
    (runtime/compile_cost.py), Mesa's shader cache on (the other process's compile reaches the window
    through it) and not known to hold the program already, a scene with a storage setting not set to
    the quick one, and a scene the other process can open (a file, not one made in memory)."""
    from inshade.runtime.compile_cost import first_draw_estimate, inline_flops, seconds_per_flop
    from inshade.runtime.first_draw import first_draw_note

    if not (renderer.gl.get("software") and renderer.first_draw_pending and draw_history.shader_cache_on()):
        return False
    if "storage" not in renderer.scene.settings or renderer.values["storage"] == QUICK_STORAGE or source is None:
        return False
    if first_draw_note(renderer.gl, renderer.program_key, renderer.generated, True)[1]:
        return False
    largest = max((inline_flops([g]) for g in renderer.generated), default=0)
    return (first_draw_estimate(renderer.gl, renderer.program_key, renderer.generated) >= WARM_UP_MIN_S
            and largest * seconds_per_flop(renderer.gl.get("renderer", "")) >= WARM_UP_MIN_S)


class WarmUp:
    """``inshade render`` of ``source`` at ``settings`` (the program's: storage, defines, codegen
    options), 8 x 8, in another process; ``done`` once it has exited."""

    def __init__(self, source, settings: dict):
        self.source, self.settings = source, dict(settings)
        self._folder = tempfile.TemporaryDirectory(prefix="inshade-warm-up-")
        sets = [a for n, v in sorted(self.settings.items()) for a in ("--set", f"{n}={json.dumps(v)}")]
        cmd = [sys.executable, "-c", "from inshade.cli import entry; entry()", "-q", "render", str(source),
               "--width", str(SIZE), "--height", str(SIZE), *sets, "-o", str(Path(self._folder.name) / "w.png")]
        self.started = time.perf_counter()
        self.process = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        self.seconds = None

    def done(self) -> bool:
        if self.process.poll() is None:
            return False
        if self.seconds is None:
            self.seconds = time.perf_counter() - self.started
        return True

    @property
    def ok(self) -> bool:
        return self.done() and self.process.returncode == 0

    def error(self) -> str:
        """The other process's last line on failure."""
        lines = (self.process.stderr.read() if self.process.stderr else "").strip().splitlines()
        return lines[-1] if lines else f"exit code {self.process.returncode}"

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        if self.process.stderr:
            self.process.stderr.close()
        self._folder.cleanup()
