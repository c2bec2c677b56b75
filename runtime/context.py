"""Headless OpenGL contexts, and what the driver reports about itself.

Every render path must run without a window, so contexts are standalone: EGL first (works with
no display server, on Mesa llvmpipe and on NVIDIA), then GLX if a display is set (Xvfb). The
installed ``glcontext`` backends are only ``egl`` and ``x11``; there is no OSMesa path.
Every context creation logs GL_VENDOR / GL_RENDERER / GL_VERSION, because results (speed, and the
rare precision difference) depend on the driver and must never be assumed to come from llvmpipe.
"""

from __future__ import annotations

import ctypes
import functools
import logging
import os

import moderngl

log = logging.getLogger("inshade")

GL_SHADING_LANGUAGE_VERSION = 0x8B8C
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "lavapipe")
LIMITS = (
    "GL_MAX_UNIFORM_BLOCK_SIZE",
    "GL_MAX_FRAGMENT_UNIFORM_BLOCKS",
    "GL_MAX_FRAGMENT_UNIFORM_COMPONENTS",
    "GL_MAX_TEXTURE_SIZE",
    "GL_MAX_3D_TEXTURE_SIZE",
    "GL_MAX_DRAW_BUFFERS",
    "GL_MAX_TEXTURE_IMAGE_UNITS",
    "GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS",
    "GL_MAX_ARRAY_TEXTURE_LAYERS",
)

_REMEDY = ("install Mesa's EGL and GL drivers (Debian/Ubuntu: apt-get install libegl1 libgl1-mesa-dri), "
           "or run under a display server (e.g. xvfb-run) so GLX can be used")


class GLContextError(RuntimeError):
    """No OpenGL context of the required version could be created headless."""


def create_context(require: int = 330) -> moderngl.Context:
    """Create a standalone (windowless) context of at least GL ``require`` (e.g. 330 = 3.3 core)."""
    backends = ["egl"] + (["x11"] if os.environ.get("DISPLAY") else [])
    failures = []
    for backend in backends:
        try:
            ctx = moderngl.create_standalone_context(backend=backend, require=require)
        except Exception as exc:  # glcontext raises bare Exception subclasses per backend
            failures.append(f"{backend}: {exc}")
            continue
        info = ctx.info
        log.info("OpenGL context (%s): GL_VENDOR=%s GL_RENDERER=%s GL_VERSION=%s", backend,
                 info["GL_VENDOR"], info["GL_RENDERER"], info["GL_VERSION"])
        return ctx
    raise GLContextError(f"no headless OpenGL {require // 100}.{require % 100 // 10} context "
                         f"({'; '.join(failures)}); {_REMEDY}")


def shared_context() -> moderngl.Context:
    """One process-wide context (GL 3.3+), so tests and tools do not pay for many contexts.

    It is made current again on every call, since another context may have been created or
    released in between (see ``make_current``).
    """
    return make_current(_shared())


@functools.cache
def _shared() -> moderngl.Context:
    return create_context(330)


def release_shared() -> None:
    """Leave the shared headless context not current on this thread.

    Mesa's GLX refuses to make a new window context current (X error BadAccess, which kills the
    process) on a thread where an EGL context is current: call this before creating a window.
    """
    if _shared.cache_info().currsize:
        _shared().__exit__(None, None, None)


def make_current(ctx: moderngl.Context) -> moderngl.Context:
    """Make ``ctx`` current on this thread and leave it current.

    moderngl sends GL calls to whichever context is current, not to the Context object used, so
    with several contexts this must be called before using one. Do not use ``with ctx:`` for
    this: on EGL its exit releases the context (nothing is current afterwards) rather than
    restoring the previous one, and later calls fail ("cannot create renderbuffer").
    """
    ctx.__enter__()
    return ctx


def gl_info(ctx: moderngl.Context) -> dict:
    """Driver identity and the limits codegen chooses weight placement from (leaves ctx current)."""
    info = ctx.info
    renderer = info["GL_RENDERER"]
    result = {
        "vendor": info["GL_VENDOR"],
        "renderer": renderer,
        "version": info["GL_VERSION"],
        "glsl_version": _glsl_version(ctx),
        "software": any(name in renderer.lower() for name in SOFTWARE_RENDERERS),
    }
    result.update({name: int(info[name]) for name in LIMITS})
    return result


def _glsl_version(ctx: moderngl.Context) -> str:
    """GL_SHADING_LANGUAGE_VERSION via the current context (moderngl does not expose it).

    Falls back to the GL version, which equals the GLSL version for every GL 3.3+ context.
    """
    for name in ("libOpenGL.so.0", "libGL.so.1"):
        try:
            get_string = ctypes.CDLL(name).glGetString
        except (OSError, AttributeError):
            continue
        get_string.restype = ctypes.c_char_p
        get_string.argtypes = [ctypes.c_uint]
        make_current(ctx)  # the raw call reads whichever context is current on this thread
        value = get_string(GL_SHADING_LANGUAGE_VERSION)
        if value:
            return value.decode()
    return f"{ctx.version_code // 100}.{ctx.version_code % 100}"


def egl_devices() -> list[str]:
    """Describe the EGL devices (``/dev/dri/...`` node, or the device's extensions); [] on any failure.

    Best effort, for logs: tells "no GPU visible" apart from "GPU visible but not used".
    """
    try:
        return _query_egl_devices()
    except Exception:  # diagnostics must never break a run
        log.debug("EGL device query failed", exc_info=True)
        return []


def _query_egl_devices() -> list[str]:
    egl = ctypes.CDLL("libEGL.so.1")
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]

    def proc(name, restype, *argtypes):
        address = egl.eglGetProcAddress(name.encode())
        if not address:
            raise OSError(f"{name} not available")
        return ctypes.CFUNCTYPE(restype, *argtypes)(address)

    query_devices = proc("eglQueryDevicesEXT", ctypes.c_uint, ctypes.c_int,
                         ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_int))
    query_string = proc("eglQueryDeviceStringEXT", ctypes.c_char_p, ctypes.c_void_p, ctypes.c_int)
    egl_extensions, egl_drm_device_file = 0x3055, 0x3233
    count = ctypes.c_int(0)
    if not query_devices(0, None, ctypes.byref(count)) or count.value <= 0:
        return []
    devices = (ctypes.c_void_p * count.value)()
    if not query_devices(count.value, devices, ctypes.byref(count)):
        return []
    described = []
    for device in devices[:count.value]:
        extensions = (query_string(device, egl_extensions) or b"").decode()
        drm_file = query_string(device, egl_drm_device_file) if "EGL_EXT_device_drm" in extensions else None
        described.append(drm_file.decode() if drm_file else f"(no DRM node) {extensions}".strip())
    return described
