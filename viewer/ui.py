"""The viewer's panels (imgui-bundle + implot). Reads and changes the app only through its methods
(``set_mode``, ``set_setting``, ``go_to_bookmark`` ...), the same ones tests and scripts call."""
from __future__ import annotations

import math
import re

import numpy as np
from imgui_bundle import ImVec2, ImVec4, imgui, implot

from inshade.scene.display import UI_MODES, DisplayMode
from inshade.scene.labels import layout as label_layout

RED = ImVec4(1.0, 0.35, 0.3, 1.0)
YELLOW = ImVec4(1.0, 0.85, 0.3, 1.0)
GREY = ImVec4(0.65, 0.65, 0.65, 1.0)
WIDGET_MIN = 140.0   # window units: a widget narrower than this beside its label gets the label above it


def draw(app) -> None:
    """The side panel (fixed at the left, ``app.panel_width`` wide) and overlays."""
    width, height = app.window_size
    app.label_width = _label_width(app)
    # a label too long to leave a usable widget beside it goes on its own line above the widget
    app.labels_on_top = app.panel_width - app.label_width < WIDGET_MIN
    if app.labels_on_top:
        app.label_width = _label_width(app, settings=False)
    imgui.set_next_window_pos(ImVec2(0, 0))
    imgui.set_next_window_size(ImVec2(app.panel_width, height))
    flags = imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
    imgui.begin("inshade", None, flags)
    # widgets fill what the longest label leaves (labels are never cut while the panel can grow)
    imgui.push_item_width(-max(app.label_width, 1.0) - imgui.get_style().item_inner_spacing.x)
    _messages(app)
    _scene(app)
    if app.renderer is not None:
        _view(app)
        _settings(app)
        _compare(app)
        _performance(app)
        _plan(app)
    imgui.pop_item_width()
    imgui.end()
    if app.renderer is not None and not app.compiling:
        _labels(app)
    if app.compiling:
        note = app.renderer.first_draw_note if app.renderer is not None else None
        _overlay(app, "compiling the network program...\n" + (note or "(the driver compiles it at the first draw)"))
    elif app.flash_shown:
        _overlay(app, app.flash_shown, name="##flash", colour=YELLOW)


# settings whose label lists named values, e.g. "1 GGX, 2 Disney" or "sampler: 0 di, 1 trilinear"
_NAMED = re.compile(r"^(?:(?P<title>[^:,]+):\s*)?(?P<items>-?\d+\s+[^,]+(?:,\s*-?\d+\s+[^,]+)+)$")


def named_values(setting) -> tuple[str, dict] | None:
    """``(title, {value: name})`` when a setting's label lists names for its numbers, else None."""
    m = _NAMED.match((setting.label or "").strip())
    if not m:
        return None
    names = {}
    for item in m.group("items").split(","):
        number, name = item.strip().split(None, 1)
        names[int(number)] = name.strip()
    return (m.group("title") or setting.name).strip(), names


def setting_widget(setting) -> tuple[str, str, list]:
    """How the panel shows a setting: ``(kind, label, values)``. kind: ``combo`` (values: (value,
    shown name) pairs), ``slider``, ``checkbox`` or ``fixed`` (one possible value: plain text).
    An int or choice setting whose label names its values (``"1 GGX, 2 Disney"``) is a combo of
    those names; an int setting without names keeps its slider (a true range)."""
    label = setting.label or setting.name
    named = named_values(setting) if setting.type in ("int", "choice") else None
    if setting.type == "int":
        values = list(range(int(setting.min), int(setting.max) + 1))
    elif setting.type == "choice":
        values = list(setting.choices)
    else:
        values = []
    if setting.type == "bool":
        return "checkbox", label, []
    if setting.type == "float":
        return ("fixed" if setting.min == setting.max else "slider"), label, []
    if named is not None and all(isinstance(v, int) and v in named[1] for v in values):
        title, names = named
        pairs = [(v, names[v]) for v in values]
        return ("fixed" if len(pairs) == 1 else "combo"), title, pairs
    if setting.type == "choice":
        pairs = [(v, str(v)) for v in values]
        return ("fixed" if len(pairs) == 1 else "combo"), label, pairs
    if len(values) == 1:
        return "fixed", label, [(values[0], str(values[0]))]
    return "slider", label, []


def _label_width(app, settings: bool = True) -> float:
    """Width of the longest label of the side panel's widgets (window units); ``settings``: the
    scene settings' labels too."""
    labels = ["display", "scene", "split", "labels"]
    if settings and app.scene is not None:
        labels += [setting_widget(s)[1] for s in app.scene.settings.values() if s.exposed]
    return max(imgui.calc_text_size(t).x for t in labels)


def _widget_label(app, label: str, key: str) -> tuple[str, bool]:
    """The label to give a setting's widget: itself, or (labels on top) the label drawn on its own
    line and a hidden one, the widget then spanning the panel (True: pop the item width after)."""
    if not app.labels_on_top:
        return label, False
    imgui.text(label)
    imgui.push_item_width(-1)
    return f"##{key}", True


def _labels(app) -> None:
    """The scene's labels (scene/labels.py) over the viewport: the window's copy of what the PNG
    writer draws; never part of the rendered image."""
    labels = app.active_labels()
    if not labels:
        return
    x0, y0, w, h = app.scene_rect_window()
    if w <= 0 or h <= 0:
        return
    draw = imgui.get_background_draw_list()
    white, dark = imgui.IM_COL32(255, 255, 255, 255), imgui.IM_COL32(0, 0, 0, 230)
    for item in label_layout(labels, app.camera, w, h):
        if item[0] == "line":
            _, ax, ay, bx, by = item
            draw.add_line(ImVec2(x0 + ax, y0 + ay), ImVec2(x0 + bx, y0 + by), white, 1.0)
            continue
        _, x, y, text, align = item
        size = imgui.calc_text_size(text)
        tx = x - {"left": 0.0, "center": size.x / 2, "right": size.x}[align]
        ty = y - size.y / 2
        tx = min(max(tx, 2.0), w - size.x - 2.0)
        ty = min(max(ty, 2.0), h - size.y - 2.0)
        for dx, dy in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            draw.add_text(ImVec2(x0 + tx + dx, y0 + ty + dy), dark, text)
        draw.add_text(ImVec2(x0 + tx, y0 + ty), white, text)


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
    if imgui.begin_combo("display", app.mode.label):
        for key, mode in enumerate(UI_MODES, start=1):
            why = app.mode_unavailable(mode)
            if why is not None:
                imgui.begin_disabled()
            if imgui.selectable(f"{key}  {mode.label}", mode is app.mode)[0]:
                app.set_mode(mode)
            if why is not None:
                imgui.end_disabled()
                if imgui.is_item_hovered(imgui.HoveredFlags_.allow_when_disabled):
                    imgui.set_tooltip(why)
        imgui.end_combo()
    if app.mode is DisplayMode.SPLIT:
        changed, value = imgui.slider_float("split", app.split, 0.0, 1.0, "%.2f")
        if changed:
            app.split = value
    if app.scene.labels:
        changed, on = imgui.checkbox("labels", bool(app.renderer.values.get("labels", True)))
        if changed:
            app.set_setting("labels", on)
    no_reference = app.scene.reference is None
    if no_reference:
        imgui.begin_disabled()
    if imgui.button("neural <-> reference (T)"):
        app.toggle_reference()
    if no_reference:
        imgui.end_disabled()
        if imgui.is_item_hovered(imgui.HoveredFlags_.allow_when_disabled):
            imgui.set_tooltip("this scene has no reference image")
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
    if app.renderer.spec.accumulate:   # a stochastic program: samples averaged so far (reset on any change)
        imgui.text(f"{app.renderer.samples} spp (of {app.max_spp})")


def _camera_text(camera) -> str:
    d = camera.to_dict()
    if d["type"] == "plane2d":
        return f"centre ({d['center'][0]:.3f}, {d['center'][1]:.3f})  zoom {d['zoom']:.2f}"
    return ", ".join(f"{k} {v:.3g}" for k, v in d.items() if k in ("yaw", "pitch", "distance"))


def _settings(app) -> None:
    shown = [s for s in app.scene.settings.values() if s.exposed]
    if not shown or not imgui.collapsing_header("Settings", imgui.TreeNodeFlags_.default_open):
        return
    for s in shown:
        value = app.renderer.values[s.name]
        kind, label, pairs = setting_widget(s)
        changed, new = False, value
        if kind == "fixed":
            shown_value = pairs[0][1] if pairs else f"{value:.3g}" if isinstance(value, float) else str(value)
            imgui.text_disabled(shown_value)
            imgui.same_line(0.0, -1.0)
            imgui.text(label)
        elif kind == "checkbox":
            changed, new = imgui.checkbox(label, bool(value))
        else:
            shown_label, pop = _widget_label(app, label, s.name)
            if kind == "slider" and s.type == "float":
                changed, new = imgui.slider_float(shown_label, float(value), float(s.min), float(s.max), "%.3g")
            elif kind == "slider":
                changed, new = imgui.slider_int(shown_label, int(value), int(s.min), int(s.max))
            else:
                values = [v for v, _ in pairs]
                index = values.index(value) if value in values else 0
                changed, index = imgui.combo(shown_label, index, [name for _, name in pairs])
                new = values[index]
            if pop:
                imgui.pop_item_width()
        if imgui.is_item_hovered(imgui.HoveredFlags_.allow_when_disabled) and (s.label or s.name) != label:
            imgui.set_tooltip(s.label or s.name)
        if changed:
            app.set_setting(s.name, new)


def _compare(app) -> None:
    if app.scene.reference is None or not imgui.collapsing_header("Compare", imgui.TreeNodeFlags_.default_open):
        return
    psnr = app.psnr
    text = "-" if psnr is None else ("inf" if math.isinf(psnr) else f"{psnr:.2f} dB")
    imgui.text(f"PSNR of this view: {text}")
    imgui.text_colored(GREY, "  the window's pixels vs the reference,\n  linear, as framed and sized now")
    trained = app.renderer.bundles[0].meta.get("metrics", {}).get("psnr_linear")
    if trained is not None:
        imgui.text_colored(GREY, f"PSNR at training: {trained:.2f} dB\n  the whole image at its own size\n"
                                 "  (a different measurement: zoom, framing\n  and resampling change this view's)")


def _performance(app) -> None:
    if not imgui.collapsing_header("Performance", imgui.TreeNodeFlags_.default_open):
        return
    imgui.text_wrapped(app.renderer.gl["renderer"])
    frame = np.asarray(app.frame_ms, np.float32)
    gpu = np.asarray(app.gpu_ms, np.float32)
    if frame.size:
        imgui.text(f"frame {frame[-1]:.1f} ms   GPU {gpu[-1] if gpu.size else float('nan'):.2f} ms")
    _, _, w, h = app.scene_rect()
    dw, dh = app.draw_size(w, h)
    if (dw, dh) != (w, h):
        imgui.text_wrapped(f"drawn at {dw}x{dh}, shown at {w}x{h}: a software renderer, and the networks' "
                           f"{app.renderer.pixel_flops / 1e6:.1f} MFLOPs/px")
    if app.renderer.first_draw_seconds is not None:
        imgui.push_style_color(imgui.Col_.text, GREY)
        imgui.text_wrapped(f"first network draw (JIT on llvmpipe): {app.renderer.first_draw_seconds:.1f} s")
        imgui.pop_style_color()
    stamps = np.asarray(app.frame_t, np.float64)
    if frame.size > 1 and stamps.size == frame.size and implot.begin_plot("##times", ImVec2(-1, 110)):
        seconds = stamps - stamps[-1]      # x: seconds before now
        implot.setup_axes("time (s)", "ms")
        implot.setup_axis_limits(implot.ImAxis_.x1, float(seconds[0]), 0.0, imgui.Cond_.always)
        implot.setup_axis_limits(implot.ImAxis_.y1, 0.0, float(max(frame.max(), 1.0)) * 1.1, imgui.Cond_.always)
        implot.plot_line("frame", seconds, frame.astype(np.float64))
        n = min(gpu.size, seconds.size)
        if n > 1:   # one GPU time per drawn frame: the latest frames
            implot.plot_line("GPU", seconds[-n:], gpu[-n:].astype(np.float64))
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


def _overlay(app, text: str, name: str = "##overlay", colour=None) -> None:
    x, _, w, _ = app.scene_rect_window()
    imgui.set_next_window_pos(ImVec2(x + 8, 8))
    flags = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize |
             imgui.WindowFlags_.no_inputs | imgui.WindowFlags_.no_saved_settings)
    imgui.begin(name, None, flags)
    if colour is not None:
        imgui.text_colored(colour, text)
    else:
        imgui.text(text)
    imgui.end()
