"""The viewer's keys and mouse: glfw's callbacks -> the app's own methods (the ones scripts call) and
the camera moves of ``navigation``. Input over an imgui widget is the panel's, not the scene's.

Keys: 1..5 display modes, T neural/reference toggle, F frame, Home reset, F12 or P screenshot,
W A S D Q E move (fly) / pan while held, Esc quit."""
from __future__ import annotations

import glfw

from inshade.scene.display import UI_MODES

from . import navigation


class Controls:
    """Input state (held keys, pressed buttons, the last cursor) of one window; ``attach`` routes the
    window's callbacks here, each passed on to the imgui backend ``impl`` first."""

    def __init__(self, app, impl, imgui):
        self.app, self.impl, self.imgui = app, impl, imgui
        self.cursor = None
        self.buttons = set()
        self.held = set()

    def attach(self, window) -> None:
        glfw.set_key_callback(window, self.on_key)
        glfw.set_char_callback(window, self.impl.char_callback)
        glfw.set_cursor_pos_callback(window, self.on_cursor)
        glfw.set_mouse_button_callback(window, self.on_button)
        glfw.set_scroll_callback(window, self.on_scroll)
        glfw.set_window_size_callback(window, self.impl.resize_callback)

    def move(self, dt: float) -> None:
        """Held W A S D Q E move the camera for a frame of ``dt`` seconds."""
        app, held = self.app, self.held
        if app.camera is not None:
            fwd = (glfw.KEY_W in held) - (glfw.KEY_S in held)
            right = (glfw.KEY_D in held) - (glfw.KEY_A in held)
            up = (glfw.KEY_E in held) - (glfw.KEY_Q in held)
            navigation.keys(app.camera, fwd, right, up, dt, *app.scene_rect_window()[2:])

    def on_key(self, window, key, scancode, action, mods) -> None:
        app = self.app
        self.impl.keyboard_callback(window, key, scancode, action, mods)
        if action == glfw.RELEASE:
            self.held.discard(key)
            return
        if self.imgui.get_io().want_capture_keyboard or action != glfw.PRESS:
            return
        self.held.add(key)
        if glfw.KEY_1 <= key <= glfw.KEY_9 and app.scene is not None:
            if key - glfw.KEY_1 < len(UI_MODES):   # 1 final, 2 network, 3 reference, 4 error, 5 split
                app.set_mode(UI_MODES[key - glfw.KEY_1])
        elif key == glfw.KEY_T:
            app.toggle_reference()
        elif key == glfw.KEY_F and app.camera is not None:
            navigation.frame(app.camera)
        elif key == glfw.KEY_HOME and app.scene is not None:
            app.reset_camera()
        elif key in (glfw.KEY_F12, glfw.KEY_P) and app.renderer is not None:
            app.screenshot()
        elif key == glfw.KEY_ESCAPE:
            glfw.set_window_should_close(window, True)

    def on_cursor(self, window, x, y) -> None:
        self.impl.mouse_callback(window, x, y)
        if self.cursor is not None and self.buttons and self.app.camera is not None:
            self.app.drag(x - self.cursor[0], y - self.cursor[1], button=min(self.buttons))
        self.cursor = (x, y)

    def on_button(self, window, button, action, mods) -> None:
        self.impl.mouse_button_callback(window, button, action, mods)
        if action == glfw.PRESS:
            x, _ = glfw.get_cursor_pos(window)
            if not self.imgui.get_io().want_capture_mouse and x >= self.app.panel_width:
                self.buttons.add(button)
                self.cursor = glfw.get_cursor_pos(window)
        else:
            self.buttons.discard(button)

    def on_scroll(self, window, dx, dy) -> None:
        self.impl.scroll_callback(window, dx, dy)
        if self.imgui.get_io().want_capture_mouse or self.app.camera is None:
            return
        x, y = glfw.get_cursor_pos(window)
        if x >= self.app.panel_width:
            self.app.scroll(dy, x, y)
