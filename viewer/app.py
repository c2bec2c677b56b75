"""`inshade view`: the interactive window, a thin shell over ``renderer.SceneRenderer``.

It adds a glfw window (OpenGL 3.3 core, ``window``), input -> camera (``controls``, ``navigation``),
panels (``ui``), the present blit (linear float -> sRGB window pixels), timing, screenshots
(``capture``) and hot reload. Rendering itself is ``SceneRenderer.render``, the function
``inshade render`` calls headless.

Scripting / test hook: everything the UI does is a method (``open``, ``set_mode``, ``set_setting``,
``drag``, ``scroll``, ``go_to_bookmark``, ``screenshot``, ``check_reload``) and ``step(n)`` runs n
frames, so a script drives the app exactly as a user would, without synthetic OS events.

A stochastic program (``ProgramSpec.accumulate``) adds one sample per frame to its running mean
while the view is still, up to ``max_spp``; any change of the view or a setting restarts it.

Keys: 1..5 display modes (final, network, reference, error, split; a mode the scene lacks says why in
the viewport), T neural/reference toggle, F frame, Home reset, F12 or P screenshot,
W A S D Q E move (fly) / pan, Esc quit. Mouse: see ``navigation``.
"""
from __future__ import annotations

import collections
import logging
import math
import time
from pathlib import Path

import glfw
import moderngl
import numpy as np

from inshade.shaders import search_path

from . import navigation
from .capture import count_gl_objects, read_back_buffer, save_screenshot
from .controls import Controls
from .window import NoDisplayError, open_window   # noqa: F401 - NoDisplayError: callers catch it from here
from inshade.scene.display import DisplayMode, parse_mode
from inshade.scene.labels import active as active_labels
from inshade.scene.tonemap import TONEMAPS, presented_tonemap
from inshade.scene.tonemap import glsl_chunk as tonemap_chunk
from inshade.runtime.programs import ProgramCache
from inshade.runtime.render import FullscreenPass
from inshade.runtime.renderer import SceneRenderer
from inshade.scene.description import list_scenes, load_scene
from .warm_up import QUICK_STORAGE, WarmUp, program_settings, worth_it
from .watch import FileWatcher

log = logging.getLogger("inshade")

PANEL_MIN = 300           # side panel width (window units): at least this, wider for long labels,
PANEL_MAX = 520           # at most this and at most 45% of the window
WIDGET_WIDTH = 170        # the widget column of the side panel (window units)
FLASH_SECONDS = 3.0       # how long a viewport message (e.g. "no reference") stays
HISTORY = 240             # frames in the timing plots
PSNR_INTERVAL = 0.25      # seconds between live PSNR updates (only when the view changed)
MAX_SPP = 256             # stochastic programs: samples a still view accumulates, one per frame
SOFTWARE_FRAME_FLOPS = 1e12   # a software renderer draws a frame costing more (the plans' bound) smaller


def default_trained_root() -> Path:
    here = Path(__file__).resolve().parents[1] / "trained"
    return here if here.is_dir() else Path.cwd() / "trained"


class ViewerApp:
    def __init__(self, source=None, *, size=(1280, 800), visible: bool = True, trained_root=None,
                 settings: dict | None = None, vsync: bool = True, screenshot_dir=None,
                 title: str = "inshade view", max_spp: int = MAX_SPP):
        self.window = open_window(size, title, visible=visible, vsync=vsync)
        self.ctx = moderngl.create_context(require=330)
        log.info("window OpenGL: GL_RENDERER=%s GL_VERSION=%s", self.ctx.info["GL_RENDERER"],
                 self.ctx.info["GL_VERSION"])

        from imgui_bundle import imgui, implot
        from imgui_bundle.python_backends.glfw_backend import GlfwRenderer

        self._imgui, self._implot = imgui, implot
        self.imgui_context = imgui.create_context()
        self.implot_context = implot.create_context()
        imgui.get_io().set_ini_filename("")
        self.impl = GlfwRenderer(self.window, attach_callbacks=False)
        self.controls = Controls(self, self.impl, imgui)
        self.controls.attach(self.window)

        self.cache = ProgramCache(self.ctx)
        self.present_program = self.cache.get("common/fullscreen.vert", "passes/present.frag",
                                              chunks={"tonemaps": tonemap_chunk()})
        self.present = FullscreenPass(self.ctx, self.present_program)
        self.timer = self.ctx.query(time=True)
        self.frame_ms: collections.deque = collections.deque(maxlen=HISTORY)
        self.frame_t: collections.deque = collections.deque(maxlen=HISTORY)   # perf_counter per frame
        self.gpu_ms: collections.deque = collections.deque(maxlen=HISTORY)
        self.messages: list[str] = []
        self.trained_root = Path(trained_root) if trained_root is not None else default_trained_root()
        self.scene_paths = list_scenes(self.trained_root)
        self.screenshot_dir = Path(screenshot_dir) if screenshot_dir is not None else Path.cwd() / "screenshots"
        self.overrides = dict(settings or {})
        self.scene = self.renderer = self.camera = self.watcher = None
        self.warm_up = None   # the program as set, compiling in another process (viewer/warm_up.py)
        self.mode, self.split, self.psnr = DisplayMode.FINAL, 0.5, None
        self.compiling = False
        self.frames = 0
        self.max_spp = int(max_spp)
        self.label_width = 0.0            # widest label of the side panel (measured by ui.draw)
        self.labels_on_top = False        # long setting labels drawn above their widgets (ui.draw decides)
        self.flash_text, self._flash_until = None, 0.0
        self._psnr_key = None
        self._psnr_time = 0.0
        self._last_frame = time.perf_counter()
        self._closed = False
        self.last_window = None
        if source is not None:
            self.open(source)
        elif self.scene_paths:   # no scene chosen: the picker, not the first (maybe slowest) scene
            self.messages.append("choose a scene in the list (its first draw may take a while on a software "
                                 "renderer: the driver compiles it)")

    # scenes -------------------------------------------------------------------------------------
    def make_current(self) -> None:
        """Make the window's context current and clear stale GL errors. Other code in this process
        (e.g. a headless render on the shared EGL context) may have switched contexts, and PyOpenGL
        (used by the imgui backend) would blame a later call for an error left pending."""
        glfw.make_context_current(self.window)
        from OpenGL import GL
        for _ in range(16):
            err = GL.glGetError()
            if err == GL.GL_NO_ERROR:
                break
            log.debug("stale GL error 0x%x cleared", err)

    def open(self, source) -> bool:
        """Load a scene (folder, scene.json, bundle); on failure keep the window and show why."""
        self.make_current()
        try:
            scene = load_scene(source)
            settings = {k: v for k, v in self.overrides.items() if k in scene.settings}
            renderer = SceneRenderer(scene, self.ctx, cache=self.cache, settings=settings, owns_programs=True)
        except Exception as exc:  # a bad scene or a missing capability is a message, not a crash
            self.messages.append(f"cannot open {source}: {exc}")
            log.warning("cannot open %s: %s", source, exc)
            return False
        self._release_scene(keep=(renderer.program, renderer.display_program))
        self.scene, self.renderer = scene, renderer
        self._start_warm_up(scene.source or source)
        renderer.sample_cap = self.max_spp   # accumulating programs: a still view stops adding samples here
        self.camera = scene.make_camera()
        self.mode, self.split, self.psnr, self._psnr_key = scene.display_mode, scene.split, None, None
        self.compiling = False
        paths = [Path(n.bundle) / f for n in scene.networks for f in ("weights.safetensors", "bundle.json")]
        paths += [p for root in search_path() for p in sorted(root.rglob("*.glsl"))]   # shared + technique chunks
        self.watcher = FileWatcher(paths)
        return True

    def scene_index(self) -> int | None:
        if self.scene is None:
            return None
        root = self.scene.root.resolve() if self.scene.root else None
        for i, p in enumerate(self.scene_paths):
            if p.resolve() == root:
                return i
        return None

    def _start_warm_up(self, source) -> None:
        """Draw with a program that compiles quickly while the program as set compiles behind (where that
        pays: viewer/warm_up.py)."""
        r = self.renderer
        if not worth_it(r, source):
            return
        wanted = program_settings(self.scene, r.values)
        try:
            r.set_setting("storage", QUICK_STORAGE)
        except Exception as exc:  # e.g. past a texture limit: the program as set, compiled here
            log.info("no quick program first (%s)", exc)
            return
        self.warm_up = WarmUp(source, wanted)
        self.flash(f"drawing with storage {QUICK_STORAGE} while storage {wanted['storage']} compiles behind")

    def _check_warm_up(self) -> None:
        """Once the quick program's first frame is drawn: compile the program as set behind. Once that
        is done: switch to it (its first draw finds the shader in Mesa's cache)."""
        w = self.warm_up
        if w is not None and w.process is None and not self.renderer.first_draw_pending:
            w.start()
        if w is None or not w.done():
            return
        self.warm_up = None
        if not w.ok:
            self.messages.append(f"compiling storage {w.settings['storage']} behind the window failed "
                                 f"({w.error()}); compiling it here")
        w.stop()
        self.set_setting("storage", w.settings["storage"])
        self.flash(f"storage {w.settings['storage']} ready (compiled behind in {w.seconds:.0f} s)")

    def _stop_warm_up(self) -> None:
        if self.warm_up is not None:
            self.warm_up.stop()
            self.warm_up = None

    def _release_scene(self, keep=()) -> None:
        self._stop_warm_up()
        if self.renderer is not None:
            self.renderer.release(keep=keep)   # programs the next scene shares stay in the cache
        self.renderer = None

    # state changes (UI and scripts) -------------------------------------------------------------
    def mode_unavailable(self, mode) -> str | None:
        """Why this scene cannot show display ``mode`` (None: it can)."""
        mode = parse_mode(mode)
        if self.scene is None:
            return "no scene is open"
        if mode in (DisplayMode.REFERENCE, DisplayMode.ERROR, DisplayMode.SPLIT) and self.scene.reference is None:
            return f"{mode.label}: this scene has no reference image"
        if mode not in self.scene.display_modes:
            shown = ", ".join(m.label for m in self.scene.display_modes)
            return f"{mode.label}: not a display mode of this scene (it shows: {shown})"
        return None

    def set_mode(self, mode) -> bool:
        """Switch the display mode; a mode the scene lacks is refused with a viewport message."""
        mode = parse_mode(mode)
        why = self.mode_unavailable(mode)
        if why is not None:
            self.flash(why)
            return False
        self.mode = mode
        return True

    def toggle_reference(self) -> bool:
        if self.scene is not None and self.scene.reference is None:
            self.flash("T: this scene has no reference image to compare with")
            return False
        target = DisplayMode.REFERENCE if self.mode is not DisplayMode.REFERENCE else DisplayMode.FINAL
        return self.set_mode(target)

    def flash(self, text: str, seconds: float = FLASH_SECONDS) -> None:
        """A short message over the viewport for a few seconds."""
        self.flash_text, self._flash_until = text, time.perf_counter() + seconds

    @property
    def flash_shown(self) -> str | None:
        """The viewport message now on screen (None once it has timed out)."""
        return self.flash_text if self.flash_text and time.perf_counter() < self._flash_until else None

    def active_labels(self) -> list:
        """The scene's labels (scene/labels.py) to draw over the viewport now."""
        if self.scene is None or self.renderer is None:
            return []
        return active_labels(self.scene.labels, self.renderer.values, self.mode)

    def set_setting(self, name: str, value) -> str:
        self.make_current()
        if self.warm_up is not None and name == "storage":   # the user's own choice: nothing to switch to
            self._stop_warm_up()
        try:
            outcome = self.renderer.set_setting(name, value)
        except Exception as exc:
            self.messages.append(f"{name} = {value!r} failed: {exc}")
            return "failed"
        if self.warm_up is not None and name in program_settings(self.scene, {name: value}):
            # another program as set: compile that one behind instead
            source, wanted = self.warm_up.source, {**self.warm_up.settings, name: self.renderer.values[name]}
            self._stop_warm_up()
            self.warm_up = WarmUp(source, wanted)
        return outcome

    def reset_camera(self) -> None:
        self.camera = self.scene.make_camera()

    def go_to_bookmark(self, name: str) -> None:
        self.camera = self.scene.make_camera(name)

    def add_bookmark(self) -> str:
        name = f"view {len(self.scene.bookmarks) + 1}"
        self.scene.bookmarks[name] = self.camera.to_dict()
        return name

    def drag(self, dx: float, dy: float, button: int = 0) -> None:
        _, _, w, h = self.scene_rect_window()
        navigation.drag(self.camera, dx, dy, w, h, button)

    def scroll(self, notches: float, x: float | None = None, y: float | None = None) -> None:
        """Wheel at window point (x, y) (default: the scene centre)."""
        sx, sy, w, h = self.scene_rect_window()
        x = sx + w / 2 if x is None else x
        y = sy + h / 2 if y is None else y
        navigation.scroll(self.camera, notches, x - sx, y - sy, w, h)

    # geometry -----------------------------------------------------------------------------------
    @property
    def window_size(self) -> tuple[int, int]:
        return glfw.get_window_size(self.window)

    @property
    def framebuffer_size(self) -> tuple[int, int]:
        return glfw.get_framebuffer_size(self.window)

    @property
    def panel_width(self) -> int:
        """Wide enough for the longest label beside a WIDGET_WIDTH widget, within PANEL_MIN..PANEL_MAX
        and at most 45% of the window."""
        want = max(PANEL_MIN, self.label_width + WIDGET_WIDTH + 40)
        return int(min(PANEL_MAX, want, 0.45 * self.window_size[0]))

    def scene_rect_window(self) -> tuple[int, int, int, int]:
        """Scene viewport in window units: x, y (from the top), width, height."""
        w, h = self.window_size
        return self.panel_width, 0, max(w - self.panel_width, 0), h

    def scene_rect(self) -> tuple[int, int, int, int]:
        """Scene viewport in framebuffer pixels, GL convention: x, y (from the bottom), width, height
        (HiDPI: framebuffer pixels = window units x content scale)."""
        (w, h), (fw, fh) = self.window_size, self.framebuffer_size
        scale = fw / w if w else 1.0
        x0 = int(round(self.panel_width * scale))
        return x0, 0, max(fw - x0, 0), fh

    def draw_size(self, width: int, height: int) -> tuple[int, int]:
        """The size the scene pass draws at for a (width, height) viewport, presented scaled up to it.
        The viewport's own size, except on a software renderer where a frame would cost more than
        SOFTWARE_FRAME_FLOPS by the plans' upper bound (a big network marched per pixel takes minutes
        a frame on a CPU); then the cost allows, but never smaller than the scene's own size."""
        r = self.renderer
        cost = r.pixel_flops * width * height if r is not None else 0
        if not (r is not None and r.gl.get("software") and cost > SOFTWARE_FRAME_FLOPS):
            return width, height
        pixels = max(self.scene.size[0] * self.scene.size[1], SOFTWARE_FRAME_FLOPS / r.pixel_flops)
        scale = min(1.0, math.sqrt(pixels / (width * height)))
        return max(1, round(width * scale)), max(1, round(height * scale))

    # frames -------------------------------------------------------------------------------------
    def step(self, n: int = 1) -> None:
        for _ in range(n):
            self.frame()

    def run(self) -> None:
        while not glfw.window_should_close(self.window):
            self.frame()
        self.close()

    def frame(self, capture: bool = False) -> None:
        """One frame: input, hot-reload poll, scene render + present, panels, swap. ``capture``
        keeps the finished frame in ``last_window`` (see ``read_window``)."""
        imgui = self._imgui
        now = time.perf_counter()
        dt, self._last_frame = now - self._last_frame, now
        self.frame_ms.append(dt * 1000.0)
        self.frame_t.append(now)
        self.make_current()
        glfw.poll_events()
        self.impl.process_inputs()
        self.check_reload()
        self._check_warm_up()
        x, y, w, h = self.scene_rect()
        self.controls.move(dt)

        # scene: GL state reset (imgui leaves blend/scissor/programs around), then one render call
        self.ctx.scissor = None
        self.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        self.ctx.screen.use()
        self.ctx.viewport = (0, 0, *self.framebuffer_size)
        self.ctx.clear(0.08, 0.08, 0.09, 1.0)
        draw_scene = self.renderer is not None and w > 0 and h > 0
        if draw_scene and self.renderer.first_draw_pending:
            # llvmpipe JIT-compiles the network program at its first draw (seconds): show a
            # "compiling..." frame first, then block on the draw in the next frame.
            if not self.compiling:
                self.compiling, draw_scene = True, False
        if draw_scene:
            self.compiling = False
        if draw_scene:
            dw, dh = self.draw_size(w, h)
            with self.timer:
                out = self.renderer.render(self.camera, dw, dh, mode=self.mode, split=self.split)
            self.gpu_ms.append(self.timer.elapsed / 1e6)
            self._update_psnr(dw, dh)
            self.ctx.scissor = None
            self.ctx.disable(moderngl.BLEND)
            self.ctx.screen.use()
            self.ctx.viewport = (x, y, w, h)
            tonemap = presented_tonemap(self.renderer.values, self.mode.name.lower())
            self.present.render(self.ctx.screen, uniforms={"u_origin": (float(x), float(y)),
                                                           "u_scale": (dw / w, dh / h),
                                                           "u_tonemap": TONEMAPS.index(tonemap)},
                                textures={"u_source": out.color_attachments[0]})
            self.ctx.viewport = (0, 0, *self.framebuffer_size)

        from . import ui
        self.make_current()   # clear errors before PyOpenGL's checked calls in the imgui backend
        imgui.new_frame()
        ui.draw(self)
        imgui.render()
        self.impl.render(imgui.get_draw_data())
        if capture:
            self.last_window = read_back_buffer(*self.framebuffer_size)
        glfw.swap_buffers(self.window)
        self.frames += 1

    def _update_psnr(self, w: int, h: int) -> None:
        key = (repr(self.camera.to_dict()), w, h, self.renderer.weights_version, id(self.renderer.program))
        now = time.perf_counter()
        if key != self._psnr_key and now - self._psnr_time >= PSNR_INTERVAL:
            self.psnr = self.renderer.psnr(self.camera, w, h)
            self._psnr_key, self._psnr_time = key, now

    # hot reload ---------------------------------------------------------------------------------
    def check_reload(self, force: bool = False) -> str | None:
        """Poll watched files; weights -> re-upload (recompile only if the code changed), .glsl ->
        recompile, keeping the last good program on failure. Returns what happened, or None."""
        if self.watcher is None or self.renderer is None:
            return None
        self.make_current()
        changed = self.watcher.poll(force=force)
        if not changed:
            return None
        try:
            if any(p.suffix == ".glsl" for p in changed):
                outcome = f"shaders {self.renderer.reload_shaders()}"
            else:
                outcome = f"weights {self.renderer.reload_weights()}"
        except Exception as exc:
            log.warning("reload failed: %s", exc)
            return f"failed: {exc}"
        self.messages.append(f"hot reload: {outcome}")
        return outcome

    # screenshots and pixels ---------------------------------------------------------------------
    def read_window(self) -> np.ndarray:
        """Draw one frame and return it as the window shows it (read before the swap, since the back
        buffer is undefined after one): uint8 RGB [H, W, 3], row 0 = top."""
        self.frame(capture=True)
        return self.last_window

    def screenshot(self, path=None) -> dict:
        """Write the scene view (PNG + EXR + JSON sidecar, reproducible with ``inshade render --from``)
        and the whole window with panels (``.window.png``). Returns the paths."""
        return save_screenshot(self, path)

    def gl_object_counts(self, upto: int = 4096) -> dict:
        """Live GL names per object type (glIs* over 1..upto), for leak checks."""
        glfw.make_context_current(self.window)
        return count_gl_objects(upto)

    # input --------------------------------------------------------------------------------------
    def _on_key(self, window, key, scancode, action, mods) -> None:
        """A key event as glfw delivers it (``controls``): scripts press keys the user's way."""
        self.controls.on_key(window, key, scancode, action, mods)

    # teardown -----------------------------------------------------------------------------------
    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self.make_current()
        self._release_scene()
        self.present.vao.release()
        self.timer.release() if hasattr(self.timer, "release") else None
        self.cache.release()
        self.impl.shutdown()
        self._implot.destroy_context(self.implot_context)
        self._imgui.destroy_context(self.imgui_context)
        self.ctx.release()
        glfw.destroy_window(self.window)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

