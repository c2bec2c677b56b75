"""The viewer's window: glfw with an OpenGL 3.3 core context, or one clear error saying why no
window can open here and what to run instead."""
from __future__ import annotations

import os
import warnings

import glfw

from inshade.runtime.context import pyopengl_bound_to_osmesa, release_shared


class NoDisplayError(RuntimeError):
    """No window can be opened here (no display server / no GL 3.3 window context)."""


def open_window(size, title: str, *, visible: bool, vsync: bool):
    """A glfw window of ``size`` (window units) with its GL 3.3 core context current."""
    if pyopengl_bound_to_osmesa():
        raise NoDisplayError("the window draws through its own GL context, but this process already used the "
                             "osmesa backend and PyOpenGL stays on OSMesa for the process's life; open the "
                             "window from a process that has not (without INSHADE_GL_BACKEND=osmesa)")
    with warnings.catch_warnings():  # glfw warns, then returns False; the error below says it all
        warnings.simplefilter("ignore")
        ok = glfw.init()
    if not ok:
        raise NoDisplayError(no_display_text())
    glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
    glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
    glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
    glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
    glfw.window_hint(glfw.VISIBLE, bool(visible))
    glfw.window_hint(glfw.SCALE_TO_MONITOR, True)
    release_shared()  # an EGL context current on this thread makes GLX window creation fail
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        window = glfw.create_window(int(size[0]), int(size[1]), title, None, None)
    if not window:
        glfw.terminate()
        raise NoDisplayError(no_display_text())
    glfw.make_context_current(window)
    glfw.swap_interval(1 if vsync else 0)
    return window


def no_display_text() -> str:
    display = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    why = f"cannot open a window on display {display!r}" if display else "no display (DISPLAY is not set)"
    return (f"{why}; inshade view needs a desktop with OpenGL 3.3. On a headless machine run it under "
            "a virtual display: xvfb-run -s '-screen 0 1280x800x24' inshade view ... "
            "(or render without a window: inshade render ASSET -o shot.png)")
