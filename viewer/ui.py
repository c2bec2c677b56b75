"""The viewer's panels (imgui-bundle + implot). Reads and changes the app only through its methods
(``set_mode``, ``set_setting``, ``go_to_bookmark`` ...), the same ones tests and scripts call."""
from __future__ import annotations

import math

import numpy as np
from imgui_bundle import ImVec2, ImVec4, imgui, implot

from inshade.runtime.display import DisplayMode

RED = ImVec4(1.0, 0.35, 0.3, 1.0)
YELLOW = ImVec4(1.0, 0.85, 0.3, 1.0)
GREY = ImVec4(0.65, 0.65, 0.65, 1.0)


def draw(app) -> None:
    """The side panel (fixed at the left, ``app.panel_width`` wide) and overlays."""
    width, height = app.window_size
    imgui.set_next_window_pos(ImVec2(0, 0))
    imgui.set_next_window_size(ImVec2(app.panel_width, height))
    flags = imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
    imgui.begin("inshade", None, flags)
    _messages(app)
    _scene(app)
    if app.renderer is not None:
        _view(app)
        _settings(app)
        _compare(app)
        _performance(app)
        _plan(app)
    imgui.end()
    if app.compiling:
        _overlay(app, "compiling the network program...\n(llvmpipe JIT-compiles at the first draw)")


def _messages(app) -> None:
    error = app.renderer.error if app.renderer is not None else None
    if error is not None:
        imgui.text_colored(RED, "shader error (showing the last good program):")
        where = getattr(error, "location", None) or getattr(error, "chunk", None)
        line = getattr(error, "line", None)
        if where:
            imgui.text_colored(RED, f"{where}:{line}" if line else str(where))
        imgui.text_wrapped(str(error))
        imgui.separator()
    for text in app.messages[-4:]:
        imgui.text_wrapped(text)
    if app.messages:
        if imgui.small_button("clear messages"):
            app.messages.clear()
        imgui.separator()


def _scene(app) -> None:
    if not imgui.collapsing_header("Scene", imgui.TreeNodeFlags_.default_open):
        return
    names = [p.name for p in app.scene_paths]
    current = app.scene_index()
    if names:
        changed, index = imgui.combo("scene", current if current is not None else -1, names)
        if changed and index != current:
            app.open(app.scene_paths[index])
    if app.scene is not None:
        imgui.text_wrapped(app.scene.title)
    if imgui.button("screenshot (F12)"):
        app.screenshot()


def _view(app) -> None:
    if not imgui.collapsing_header("View", imgui.TreeNodeFlags_.default_open):
        return
    modes = list(app.scene.display_modes)
    labels = [m.label for m in modes]
    index = modes.index(app.mode) if app.mode in modes else 0
    changed, index = imgui.combo("display", index, labels)
    if changed:
        app.set_mode(modes[index])
    if app.mode is DisplayMode.SPLIT:
        changed, value = imgui.slider_float("split", app.split, 0.0, 1.0)
        if changed:
            app.split = value
    if imgui.button("neural <-> reference (T)"):
        app.toggle_reference()
    imgui.same_line()
    if imgui.button("reset (Home)"):
        app.reset_camera()
    for name in app.scene.bookmarks:
        if imgui.small_button(name):
            app.go_to_bookmark(name)
        imgui.same_line()
    if imgui.small_button("+ bookmark"):
        app.add_bookmark()
    imgui.text_colored(GREY, _camera_text(app.camera))


def _camera_text(camera) -> str:
    d = camera.to_dict()
    if d["type"] == "plane2d":
        return f"centre ({d['center'][0]:.3f}, {d['center'][1]:.3f})  zoom {d['zoom']:.2f}"
    return ", ".join(f"{k} {v}" for k, v in d.items() if k in ("yaw", "pitch", "distance"))


def _settings(app) -> None:
    shown = [s for s in app.scene.settings.values() if s.exposed]
    if not shown or not imgui.collapsing_header("Settings", imgui.TreeNodeFlags_.default_open):
        return
    for s in shown:
        value = app.renderer.values[s.name]
        label = s.label or s.name
        if s.type == "float":
            changed, new = imgui.slider_float(label, float(value), float(s.min), float(s.max))
        elif s.type == "int":
            changed, new = imgui.slider_int(label, int(value), int(s.min), int(s.max))
        elif s.type == "bool":
            changed, new = imgui.checkbox(label, bool(value))
        else:
            choices = list(s.choices)
            changed, index = imgui.combo(label, choices.index(value), [str(c) for c in choices])
            new = choices[index]
        if changed:
            app.set_setting(s.name, new)


def _compare(app) -> None:
    if app.scene.reference is None or not imgui.collapsing_header("Compare", imgui.TreeNodeFlags_.default_open):
        return
    psnr = app.psnr
    text = "-" if psnr is None else ("inf" if math.isinf(psnr) else f"{psnr:.2f} dB")
    imgui.text(f"PSNR (this view, linear): {text}")
    trained = app.renderer.bundles[0].meta.get("metrics", {}).get("psnr_linear")
    if trained is not None:
        imgui.text_colored(GREY, f"training metric: {trained:.2f} dB")


def _performance(app) -> None:
    if not imgui.collapsing_header("Performance", imgui.TreeNodeFlags_.default_open):
        return
    imgui.text_wrapped(app.renderer.gl["renderer"])
    frame = np.asarray(app.frame_ms, np.float32)
    gpu = np.asarray(app.gpu_ms, np.float32)
    if frame.size:
        imgui.text(f"frame {frame[-1]:.1f} ms   GPU {gpu[-1] if gpu.size else float('nan'):.2f} ms")
    if app.renderer.first_draw_seconds is not None:
        imgui.text_colored(GREY, f"first network draw (JIT on llvmpipe): {app.renderer.first_draw_seconds:.1f} s")
    if frame.size > 1 and implot.begin_plot("##times", ImVec2(-1, 110)):
        implot.setup_axes("frame", "ms")
        implot.setup_axis_limits(implot.ImAxis_.y1, 0.0, float(max(frame.max(), 1.0)) * 1.1, imgui.Cond_.always)
        implot.plot_line("frame", frame)
        if gpu.size > 1:
            implot.plot_line("GPU", gpu)
        implot.end_plot()


def _plan(app) -> None:
    if not imgui.collapsing_header("Plan"):
        return
    for g in app.renderer.generated:
        t = g.plan.totals()
        imgui.text(f"{g.plan.network}: {t['params']} params, {t['flops']} FLOPs/px")
        imgui.text_colored(GREY, f"UBO {t['uniform_bytes']} B, textures {t['texture_bytes']} B")
        if imgui.begin_table(f"plan_{g.prefix}", 4, imgui.TableFlags_.borders | imgui.TableFlags_.sizing_fixed_fit):
            for head in ("node", "storage", "params", "FLOPs"):
                imgui.table_setup_column(head)
            imgui.table_headers_row()
            for r in g.plan.rows:
                imgui.table_next_row()
                for v in (r.node, r.storage, r.params, r.flops):
                    imgui.table_next_column()
                    imgui.text(str(v))
            imgui.end_table()


def _overlay(app, text: str) -> None:
    x, _, w, _ = app.scene_rect_window()
    imgui.set_next_window_pos(ImVec2(x + 8, 8))
    flags = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize |
             imgui.WindowFlags_.no_inputs | imgui.WindowFlags_.no_saved_settings)
    imgui.begin("##overlay", None, flags)
    imgui.text(text)
    imgui.end()
