"""Headless OpenGL contexts, and what the driver reports about itself.

Every render path must run without a window, so contexts are standalone. Two backends:

- ``egl`` (default): EGL with no display server, on Mesa llvmpipe and on NVIDIA/AMD/Intel GPUs;
  ``INSHADE_EGL_DEVICE`` (CLI: ``--gl-device N``) picks one of the EGL devices. Without a device
  choice, GLX is tried next when a display is set (Xvfb).
- ``osmesa``: Mesa's off-screen library (libOSMesa, Debian ``libosmesa6``, CPU only), for machines
  and containers where EGL cannot initialise. The context is made through PyOpenGL's OSMesa
  platform and moderngl attaches to it. PyOpenGL picks its platform once, at its first import in
  a process: choose this backend (``INSHADE_GL_BACKEND=osmesa`` / ``--gl-backend osmesa``) before
  anything imports ``OpenGL`` (the viewer does, so the viewer cannot use it).

``INSHADE_GL_BACKEND`` / ``INSHADE_EGL_DEVICE`` are read when a context is made; the CLI's flags
write them (``select``) so worker processes render the same way.
Every context creation logs GL_VENDOR / GL_RENDERER / GL_VERSION, because results (speed, and the
rare precision difference) depend on the driver and must never be assumed to come from llvmpipe.
"""

from __future__ import annotations

import ctypes
import functools
import logging
import os
import sys
from dataclasses import dataclass
from pathlib import Path

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

BACKENDS = ("egl", "osmesa")
BACKEND_ENV = "INSHADE_GL_BACKEND"
DEVICE_ENV = "INSHADE_EGL_DEVICE"

_REMEDY = ("install Mesa's EGL and GL drivers (Debian/Ubuntu: apt-get install libegl1 libgl1-mesa-dri), "
           "or run under a display server (e.g. xvfb-run) so GLX can be used, or use Mesa's off-screen "
           "library: apt-get install libosmesa6, then --gl-backend osmesa (INSHADE_GL_BACKEND=osmesa); "
           "`inshade doctor` says more")


class GLContextError(RuntimeError):
    """No OpenGL context of the required version could be created headless."""


# backend and device choice ------------------------------------------------------------------
def select(backend: str | None = None, device: int | None = None) -> None:
    """Use ``backend`` / EGL ``device`` for contexts made from now on (the CLI's --gl-backend and
    --gl-device). Checked first (a bad index names the EGL device count), then written to the
    environment, so worker processes started later render the same way."""
    resolve(backend, device)
    if backend is not None:
        os.environ[BACKEND_ENV] = backend
    if device is not None:
        os.environ[DEVICE_ENV] = str(device)


def resolve(backend: str | None = None, device: int | str | None = None) -> tuple[str, int | None]:
    """(backend, EGL device index or None): the arguments (CLI flags), else INSHADE_GL_BACKEND /
    INSHADE_EGL_DEVICE, else ("egl", None). Raises GLContextError naming what to fix."""
    backend_from = "--gl-backend"
    if backend is None:
        backend, backend_from = os.environ.get(BACKEND_ENV) or "egl", BACKEND_ENV
    if backend not in BACKENDS:
        raise GLContextError(f"{backend_from}: unknown GL backend {backend!r}; use one of {', '.join(BACKENDS)}")
    device_from = "--gl-device"
    if device is None:
        device, device_from = os.environ.get(DEVICE_ENV) or None, DEVICE_ENV
        if device is None:
            return backend, None
        if backend == "osmesa":   # an environment-wide device choice does not concern OSMesa
            return backend, None
    elif backend == "osmesa":
        raise GLContextError("--gl-device picks an EGL device; the osmesa backend renders on the CPU "
                             "(drop one of the two)")
    try:
        index = int(device)
    except ValueError:
        index = -1
    if index < 0:
        raise GLContextError(f"{device_from}: expected an EGL device index (0, 1, ...), got {device!r}")
    count = len(egl_device_list())
    if index >= count:
        listed = f"{count} EGL device{'s' if count != 1 else ''}" + (f" (0..{count - 1})" if count else "")
        raise GLContextError(f"{device_from}: EGL device {index} requested, but this machine has {listed}; "
                             "`inshade doctor` lists them")
    return backend, index


# contexts -------------------------------------------------------------------------------------
def create_context(require: int = 330, backend: str | None = None, device: int | None = None) -> moderngl.Context:
    """Create a standalone (windowless) context of at least GL ``require`` (e.g. 330 = 3.3 core)
    on ``backend`` / EGL ``device`` (default: ``resolve()``: the environment, else EGL)."""
    backend, device = resolve(backend, device)
    if backend == "osmesa":
        return _log(_create_osmesa(require), "osmesa")
    # an explicit device is that device or an error; without one, GLX when EGL fails
    attempts = [("egl", {"device_index": device})] if device is not None else \
        [("egl", {})] + ([("x11", {})] if os.environ.get("DISPLAY") else [])
    failures = []
    for name, extra in attempts:
        try:
            ctx = moderngl.create_standalone_context(backend=name, require=require, **extra)
        except Exception as exc:  # glcontext raises bare Exception subclasses per backend
            failures.append(f"{name}: {exc}")
            continue
        ctx.extra = {"backend": name, "device": device}
        return _log(ctx, name if device is None else f"{name} device {device}")
    raise GLContextError(f"no headless OpenGL {require // 100}.{require % 100 // 10} context "
                         f"({'; '.join(failures)}); {_REMEDY}")


def _log(ctx: moderngl.Context, how: str) -> moderngl.Context:
    info = ctx.info
    log.info("OpenGL context (%s): GL_VENDOR=%s GL_RENDERER=%s GL_VERSION=%s", how,
             info["GL_VENDOR"], info["GL_RENDERER"], info["GL_VERSION"])
    return ctx


def shared_context() -> moderngl.Context:
    """One process-wide context (GL 3.3+) per backend/device choice, so tests and tools do not
    pay for many contexts.

    It is made current again on every call, since another context may have been created or
    released in between (see ``make_current``).
    """
    return make_current(_shared(os.environ.get(BACKEND_ENV, ""), os.environ.get(DEVICE_ENV, "")))


_contexts: dict[tuple[str, int | None], moderngl.Context] = {}


@functools.cache   # keyed by the raw settings: checks them once, not on every call
def _shared(backend_setting: str, device_setting: str) -> moderngl.Context:
    backend, device = resolve()
    key = (backend, 0 if backend == "egl" and device is None else device)   # EGL's default is device 0
    if key not in _contexts:
        _contexts[key] = create_context(330, backend, device)
    return _contexts[key]


def release_shared() -> None:
    """Leave the shared headless context(s) not current on this thread.

    Mesa's GLX refuses to make a new window context current (X error BadAccess, which kills the
    process) on a thread where an EGL context is current: call this before creating a window.
    """
    for ctx in _contexts.values():
        ctx.__exit__(None, None, None)


def pyopengl_bound_to_osmesa() -> bool:
    """Whether this process's PyOpenGL is on its OSMesa platform (the osmesa backend was used here):
    PyOpenGL picks its platform once per process, so a window's GL calls cannot reach its own
    context any more."""
    loaded = sys.modules.get("OpenGL.platform")
    return loaded is not None and type(getattr(loaded, "PLATFORM", None)).__name__ == "OSMesaPlatform"


# OSMesa through PyOpenGL ------------------------------------------------------------------------
def _osmesa_module():
    """PyOpenGL's OSMesa bindings, with PyOpenGL on its OSMesa platform (or GLContextError)."""
    chosen = os.environ.get("PYOPENGL_PLATFORM") or None
    loaded = sys.modules.get("OpenGL.platform")
    if loaded is not None and type(loaded.PLATFORM).__name__ != "OSMesaPlatform":
        raise GLContextError(
            f"the osmesa backend needs PyOpenGL's osmesa platform, but this process already loaded PyOpenGL "
            f"on {type(loaded.PLATFORM).__name__} (PYOPENGL_PLATFORM={chosen or 'unset'}), and PyOpenGL picks "
            "its platform once; choose the backend before anything imports OpenGL (INSHADE_GL_BACKEND=osmesa "
            "in the environment, or `inshade --gl-backend osmesa ...`)")
    if chosen not in (None, "osmesa"):
        raise GLContextError(f"the osmesa backend needs PyOpenGL's osmesa platform, but PYOPENGL_PLATFORM={chosen}; "
                             "unset it or set it to osmesa")
    os.environ["PYOPENGL_PLATFORM"] = "osmesa"
    try:
        from OpenGL import osmesa
        from OpenGL import platform

        platform.PLATFORM.GL   # loads libOSMesa now (ImportError when it is missing)
    except ImportError as exc:
        raise GLContextError(f"the osmesa backend needs PyOpenGL (pip install PyOpenGL) and Mesa's libOSMesa "
                             f"(Debian/Ubuntu: apt-get install libosmesa6): {exc}") from None
    return osmesa, platform.PLATFORM


class _OSMesaLoader:
    """What moderngl needs to attach to a context it did not create: GL entry points, and
    making the context current (on a small colour buffer; inshade draws into its own FBOs)."""

    SIZE = 16

    def __init__(self, osmesa, platform, handle):
        import numpy as np

        self.osmesa, self.handle = osmesa, handle
        self.proc = platform.getExtensionProcedure      # OSMesaGetProcAddress
        self.buffer = np.zeros((self.SIZE, self.SIZE, 4), np.uint8)

    def load_opengl_function(self, name: str) -> int:
        return self.proc(name.encode()) or 0

    def __enter__(self):
        if not self.osmesa.OSMesaMakeCurrent(self.handle, self.buffer, 0x1401, self.SIZE, self.SIZE):
            raise GLContextError("OSMesaMakeCurrent failed")   # 0x1401 = GL_UNSIGNED_BYTE

    def __exit__(self, *exc):
        pass   # stays current: release_shared's concern (a GLX window next) does not arise, the viewer cannot use osmesa

    def release(self):
        if self.handle is not None:
            self.osmesa.OSMesaDestroyContext(self.handle)
            self.handle = None


def _create_osmesa(require: int) -> moderngl.Context:
    osmesa, platform = _osmesa_module()
    handle = None
    # the newest core profile first (4.5 is what llvmpipe offers), then exactly what is required
    for major, minor in dict.fromkeys([(4, 5), (require // 100, require % 100 // 10)]):
        attributes = [osmesa.OSMESA_FORMAT, osmesa.OSMESA_RGBA, osmesa.OSMESA_DEPTH_BITS, 24,
                      osmesa.OSMESA_PROFILE, osmesa.OSMESA_CORE_PROFILE,
                      osmesa.OSMESA_CONTEXT_MAJOR_VERSION, major, osmesa.OSMESA_CONTEXT_MINOR_VERSION, minor, 0]
        handle = osmesa.OSMesaCreateContextAttribs(attributes, None)
        if handle:
            break
    if not handle:
        raise GLContextError(f"OSMesa could not create an OpenGL {require // 100}.{require % 100 // 10} core "
                             "context (a Mesa with OSMesaCreateContextAttribs, 11.2 or newer, is needed)")
    loader = _OSMesaLoader(osmesa, platform, handle)
    loader.__enter__()
    # moderngl.create_context() would look for a current EGL/GLX context and find none: attach
    # through a loader instead (moderngl's public hook for contexts made elsewhere)
    moderngl.init_context(loader=loader)
    ctx = moderngl.get_context()
    if ctx.version_code < require:
        raise GLContextError(f"OSMesa gave OpenGL {ctx.version_code}, {require} is required")
    ctx.extra = {"backend": "osmesa", "device": None, "loader": loader}
    return ctx


def make_current(ctx: moderngl.Context) -> moderngl.Context:
    """Make ``ctx`` current on this thread and leave it current.

    moderngl sends GL calls to whichever context is current, not to the Context object used, so
    with several contexts this must be called before using one. Do not use ``with ctx:`` for
    this: on EGL its exit releases the context (nothing is current afterwards) rather than
    restoring the previous one, and later calls fail ("cannot create renderbuffer").
    """
    ctx.__enter__()
    return ctx


def machine_limits() -> dict:
    """This machine's driver identity and limits (``gl_info`` of the shared headless context): what
    codegen plans against when the code runs here."""
    return gl_info(shared_context())


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
    for get_string in _get_string_functions(ctx):
        make_current(ctx)  # the raw call reads whichever context is current on this thread
        value = get_string(GL_SHADING_LANGUAGE_VERSION)
        if value:
            return value.decode()
    return f"{ctx.version_code // 100}.{ctx.version_code % 100}"


def _get_string_functions(ctx: moderngl.Context) -> list:
    prototype = ctypes.CFUNCTYPE(ctypes.c_char_p, ctypes.c_uint)
    loader = ctx.extra.get("loader") if isinstance(ctx.extra, dict) else None
    if loader is not None:   # OSMesa: its own entry point (glvnd's libOpenGL knows no OSMesa context)
        address = loader.load_opengl_function("glGetString")
        return [prototype(address)] if address else []
    found = []
    for name in ("libOpenGL.so.0", "libGL.so.1"):
        try:
            found.append(prototype(("glGetString", ctypes.CDLL(name))))
        except (OSError, AttributeError):
            continue
    return found


@dataclass(frozen=True)
class EGLDevice:
    """One EGL device, as ``eglQueryDevicesEXT`` lists it (the index --gl-device takes)."""

    index: int
    node: str | None      # its /dev/dri/... file when EGL names one
    extensions: str

    @property
    def software(self) -> bool:
        """Mesa's CPU device (llvmpipe), not a GPU."""
        return "EGL_MESA_device_software" in self.extensions.split()

    def describe(self) -> str:
        return self.node or f"(no DRM node) {self.extensions}".strip()


def egl_devices() -> list[str]:
    """Describe the EGL devices (``/dev/dri/...`` node, or the device's extensions); [] on any failure.

    Best effort, for logs: tells "no GPU visible" apart from "GPU visible but not used".
    """
    return [device.describe() for device in egl_device_list()]


def egl_device_list() -> list[EGLDevice]:
    """The EGL devices, in the order --gl-device / INSHADE_EGL_DEVICE index them; [] on any failure."""
    try:
        return _query_egl_devices()
    except Exception:  # diagnostics must never break a run
        log.debug("EGL device query failed", exc_info=True)
        return []


def _query_egl_devices() -> list[EGLDevice]:
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
    for index, device in enumerate(devices[:count.value]):
        extensions = (query_string(device, egl_extensions) or b"").decode()
        drm_file = query_string(device, egl_drm_device_file) if "EGL_EXT_device_drm" in extensions.split() else None
        described.append(EGLDevice(index, drm_file.decode() if drm_file else None, extensions))
    return described


def nvidia_hints() -> list[str]:
    """Why EGL may see no NVIDIA GPU here, as steps to take (for ``inshade doctor``).

    The usual causes (moderngl/pyrender reports: EGL error 0x3001, "found 0 devices"): the NVIDIA
    EGL driver library is not in the container (the NVIDIA container runtime mounts it only with
    the ``graphics`` capability), or glvnd has no vendor file pointing at it."""
    driver = Path("/proc/driver/nvidia/version").exists() or Path("/dev/nvidia0").exists()
    hints = []
    if not driver:
        hints.append("no NVIDIA driver is visible here (no /proc/driver/nvidia/version, no /dev/nvidia0); in a "
                     "container, start it with the GPU (docker run --gpus all ...)")
    try:
        ctypes.CDLL("libEGL_nvidia.so.0")
    except OSError:
        hints.append("libEGL_nvidia.so.0 (NVIDIA's EGL driver) is not loadable: in a container set "
                     "NVIDIA_DRIVER_CAPABILITIES=graphics,compute,utility (or all); on a host install "
                     "libnvidia-gl-<driver version>")
    vendor_dirs = [Path(d) for d in os.environ.get("__EGL_VENDOR_LIBRARY_DIRS", "").split(":") if d] or \
        [Path("/etc/glvnd/egl_vendor.d"), Path("/usr/share/glvnd/egl_vendor.d")]
    vendor_files = [f for d in vendor_dirs if d.is_dir() for f in d.glob("*.json")]
    named = os.environ.get("__EGL_VENDOR_LIBRARY_FILENAMES", "")
    if "nvidia" not in named.lower() and not any("nvidia" in f.name.lower() for f in vendor_files):
        hints.append("glvnd has no NVIDIA EGL vendor file: install libegl1 and libglvnd0, and write "
                     "/usr/share/glvnd/egl_vendor.d/10_nvidia.json containing "
                     '{"file_format_version": "1.0.0", "ICD": {"library_path": "libEGL_nvidia.so.0"}}')
    if not hints:
        hints.append("the NVIDIA driver, its EGL library and the glvnd vendor file are all here; run "
                     "`EGL_LOG_LEVEL=debug inshade doctor` to see why EGL skips the device")
    return hints
