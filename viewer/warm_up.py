"""The full-speed program compiled behind the window: on a software driver a program's first draw
JIT-compiles it (seconds to minutes), so the window first draws the scene with its weights in a
texture (loops, not unrolled literals: a quick compile); once that frame is on screen, another
process draws the scene as set, 8 x 8 pixels, with Mesa's shader cache on (after the window's own
compile, not beside it: on a few cores the two would slow each other); once it is done, the window
switches to the program as set, and its first draw finds the compiled shader in the cache (a second,
not the JIT's minutes).
"""
from __future__ import annotations

import json
import subprocess
import sys
import time

from inshade.runtime import draw_history
from inshade.runtime.quick_program import QUICK_STORAGE   # what the window draws with meanwhile
PROGRAM_BINDINGS = ("define", "codegen")   # settings that change the program (the others are uniforms)
SIZE = 8
# a program expected to take this long at its first draw compiles behind where its quick variant is
# expected quicker (inshade bench startup: texture storage draws the PRT and UV-free programs' first
# frame in 2-7 s where their literals take 6-19 s; the hash-grid field, ~6 s with literals and 15 s
# from a texture, stays below)
WARM_UP_MIN_S = 7.0


def program_settings(scene, values: dict) -> dict:
    """The settings of ``values`` that make the program what it is."""
    return {n: v for n, v in values.items() if scene.settings[n].binding in PROGRAM_BINDINGS}


def worth_it(renderer, source) -> bool:
    """Whether to draw a quick program first: a software driver whose first draw of this program is
    still to come and expected to take WARM_UP_MIN_S or more (runtime/compile_cost.py), more than its
    quick variant's (runtime/quick_program.py), Mesa's shader cache on (the other process's compile
    reaches the window through it) and not known to hold the program already, a scene with a storage
    setting not set to the quick one, and a scene the other process can open (a file, not one made in
    memory)."""
    from inshade.runtime.compile_cost import first_draw_estimate
    from inshade.runtime.first_draw import first_draw_note
    from inshade.runtime.quick_program import quick_first_draw

    if not (renderer.gl.get("software") and renderer.first_draw_pending and draw_history.shader_cache_on()):
        return False
    if "storage" not in renderer.scene.settings or renderer.values["storage"] == QUICK_STORAGE or source is None:
        return False
    if first_draw_note(renderer.gl, renderer.program_key, renderer.generated, True)[1]:
        return False
    as_set = first_draw_estimate(renderer.gl, renderer.program_key, renderer.generated,
                                 renderer.assembled()["fragment"])
    return as_set >= WARM_UP_MIN_S and quick_first_draw(renderer, renderer.values) < as_set


# the program exactly as set (not the quick choice `inshade render` makes for a short job at auto)
CHILD = ("import json, sys; from inshade.runtime.headless import render_scene; "
         f"render_scene(sys.argv[1], width={SIZE}, height={SIZE}, settings=json.loads(sys.argv[2]))")


class WarmUp:
    """The scene at ``settings`` (the program's: storage, defines, codegen options) drawn 8 x 8 in
    another process once ``start`` is called; ``done`` once it has exited."""

    def __init__(self, source, settings: dict):
        self.source, self.settings = source, dict(settings)
        self.process = None
        self.started = None
        self.seconds = None

    def start(self) -> None:
        self.started = time.perf_counter()
        self.process = subprocess.Popen([sys.executable, "-c", CHILD, str(self.source), json.dumps(self.settings)],
                                        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)

    def done(self) -> bool:
        if self.process is None or self.process.poll() is None:
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
        if self.process is not None and self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        if self.process is not None and self.process.stderr:
            self.process.stderr.close()
