"""What the viewer saves and reads back: screenshots (the scene as drawn, PNG + EXR + JSON sidecar,
and the whole window with its panels), the window's own pixels, and live GL objects for leak checks."""
from __future__ import annotations

import datetime
import logging
from pathlib import Path

import numpy as np

from inshade.files import atomic_files
from inshade.runtime.headless import save_render

log = logging.getLogger("inshade")

GL_IS = ("glIsTexture", "glIsBuffer", "glIsFramebuffer", "glIsRenderbuffer", "glIsVertexArray",
         "glIsProgram", "glIsShader", "glIsQuery", "glIsSampler")


def read_back_buffer(width: int, height: int) -> np.ndarray:
    """The current window's back buffer (``width`` x ``height`` framebuffer pixels): uint8 RGB
    [H, W, 3], row 0 = top."""
    from OpenGL import GL
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, 0)
    GL.glReadBuffer(GL.GL_BACK)
    GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
    data = GL.glReadPixels(0, 0, width, height, GL.GL_RGB, GL.GL_UNSIGNED_BYTE)
    return np.frombuffer(data, np.uint8).reshape(height, width, 3)[::-1].copy()


def save_screenshot(app, path=None) -> dict:
    """Write the app's scene view (PNG + EXR + JSON sidecar, reproducible with ``inshade render
    --from``) and the whole window with panels (``.window.png``). Returns the paths."""
    if path is None:
        stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S-%f")
        path = app.screenshot_dir / f"{app.scene.name if app.scene else 'empty'}-{stamp}.png"
    path = Path(path).with_suffix(".png")
    path.parent.mkdir(parents=True, exist_ok=True)
    app.make_current()
    out = {}
    window = app.read_window()
    out["window"] = path.with_name(path.stem + ".window.png")
    from PIL import Image
    with atomic_files(out["window"]) as tmp:
        Image.fromarray(window).save(tmp, format="PNG")
    if app.renderer is not None:   # the scene view as drawn (draw_size), not the window's scaled copy
        w, h = app.draw_size(*app.scene_rect()[2:])
        app.renderer.render(app.camera, w, h, mode=app.mode, split=app.split)
        image = app.renderer.read()
        info = app.renderer.info(app.camera, w, h, mode=app.mode, split=app.split)
        info["viewer"] = {"window": list(app.window_size), "framebuffer": list(app.framebuffer_size),
                          "scene_rect": list(app.scene_rect()), "psnr_db": app.psnr,
                          "window_png": out["window"].name}
        out["png"], out["sidecar"] = save_render(image, info, path)
        out["exr"], out["exr_sidecar"] = save_render(image, info, path.with_suffix(".exr"))
    app.messages.append(f"screenshot: {path}")
    return out


def count_gl_objects(upto: int = 4096) -> dict:
    """Count live GL object names of each type in 1..upto in the current context (libGL glIs*)."""
    from OpenGL import GL
    pending = []
    while (err := GL.glGetError()) != GL.GL_NO_ERROR and len(pending) < 16:  # PyOpenGL would blame glIs*
        pending.append(int(err))
    if pending:
        log.debug("GL errors pending before counting objects: %s", pending)
    counts = {}
    for name in GL_IS:
        fn = getattr(GL, name)
        counts[name[4:].lower()] = sum(1 for i in range(1, upto + 1) if fn(i))
    return counts
