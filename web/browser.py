"""Headless Chromium for exported pages: serve a folder on localhost, open a page, wait for it,
read its console, its canvas and its results (the browser tests and ``inshade bench web``).

Chromium is Debian's ``chromium`` driven through ``chromium-driver`` (selenium). Without a GPU,
WebGL2 runs on SwiftShader (``--use-angle=swiftshader``: Vulkan on the CPU), which Chromium asks to
be enabled explicitly (``--enable-unsafe-swiftshader``: the pages are ours).
"""
from __future__ import annotations

import base64
import functools
import http.server
import shutil
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

CHROMIUM = ("chromium", "chromium-browser", "google-chrome")
DRIVER = ("chromedriver",)
FLAGS = ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--use-angle=swiftshader",
         "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--disable-gpu-watchdog",
         "--disable-gpu-process-crash-limit",
         # WebGPU on SwiftShader's Vulkan (no GPU needed): the pages' WebGPU evaluation
         "--enable-unsafe-webgpu", "--use-webgpu-adapter=swiftshader",
         "--window-size=1400,1200")


class BrowserError(RuntimeError):
    """No browser, or a page that failed: the message says which and why."""


def _which(names) -> str | None:
    return next((p for p in map(shutil.which, names) if p), None)


def find_browser() -> tuple[str, str]:
    """(chromium, chromedriver) paths, or BrowserError saying what to install."""
    chromium, driver = _which(CHROMIUM), _which(DRIVER)
    if chromium is None or driver is None:
        raise BrowserError("headless Chromium not found: install Debian's chromium and chromium-driver "
                           "(apt-get install chromium chromium-driver)")
    return chromium, driver


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


@contextmanager
def serve(folder, port: int = 0, host: str = "127.0.0.1"):
    """An HTTP server of ``folder`` on a thread; yields its base URL (``http://host:port/``)."""
    handler = functools.partial(_Quiet, directory=str(folder))
    server = http.server.ThreadingHTTPServer((host, port), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://{host}:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


class Browser:
    """One headless Chromium session; ``open`` a page and wait for ``window.inshade.ready``."""

    def __init__(self):
        from selenium import webdriver
        from selenium.webdriver.chrome.options import Options
        from selenium.webdriver.chrome.service import Service

        chromium, driver = find_browser()
        options = Options()
        options.binary_location = chromium
        for flag in FLAGS:
            options.add_argument(flag)
        options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
        self.driver = webdriver.Chrome(options=options, service=Service(driver))
        self.driver.set_script_timeout(600)

    def renderer(self) -> str:
        """The browser's WebGL renderer string (unmasked), e.g. ANGLE (... SwiftShader ...)."""
        return self.driver.execute_script(
            "const gl = document.createElement('canvas').getContext('webgl2');"
            "if (!gl) return 'no WebGL2';"
            "const e = gl.getExtension('WEBGL_debug_renderer_info');"
            "return e ? gl.getParameter(e.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);")

    def open(self, url: str, timeout: float = 600.0) -> dict:
        """Load ``url`` and wait until the page says it is ready or failed; returns
        {"ready", "error", "first_frame_ms", "full_frame_ms", "console": [SEVERE/WARNING messages], "seconds"}."""
        start = time.perf_counter()
        self.driver.get(url)
        state = {}
        while time.perf_counter() - start < timeout:
            state = self.driver.execute_script(
                "const p = window.inshade; return p ? {ready: p.ready, error: p.error, "
                "first_frame_ms: p.firstFrameMs ?? null, full_frame_ms: p.fullFrameMs ?? null} : null;") or {}
            if state.get("ready") or state.get("error"):
                break
            time.sleep(0.1)
        else:
            raise BrowserError(f"{url}: not ready after {timeout:.0f} s")
        console = [f"{e['level']}: {e['message']}" for e in self.driver.get_log("browser")
                   if e["level"] in ("SEVERE", "WARNING")]
        return {**state, "console": console, "seconds": time.perf_counter() - start}

    def canvas(self) -> np.ndarray:
        """The viewer's canvas as 8-bit sRGB RGB [H, W, 3], row 0 = top."""
        w, h = self.driver.execute_script("const v = window.inshade.viewer; return [v.width, v.height];")
        data = base64.b64decode(self.driver.execute_script("return window.inshade.viewer.pixels();"))
        return np.frombuffer(data, np.uint8).reshape(h, w, 4)[..., :3].copy()

    def frame_ms(self, frames: int = 5) -> list[float]:
        """Milliseconds of ``frames`` full redraws of the current view (the network pass forced), one call
        each (a slow page's frames together would outlast the driver connection's read timeout)."""
        return [self.driver.execute_script("const v = window.inshade.viewer; v.key = null; return v.render();")
                for _ in range(int(frames))]

    def evaluation(self) -> np.ndarray:
        """evaluate.html's outputs [N, out_dim] float32."""
        r = self.driver.execute_script("const r = window.inshade.result; return [r.base64, r.count, r.outDim];")
        return np.frombuffer(base64.b64decode(r[0]), np.float32).reshape(r[1], r[2]).copy()

    def close(self) -> None:
        self.driver.quit()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def srgb8(linear: np.ndarray, tonemap: str = "none") -> np.ndarray:
    """Linear RGB -> 8-bit sRGB as ``inshade render`` writes a PNG (scene/image_io.py display_pixels)."""
    from inshade.scene.image_io import display_pixels

    return display_pixels(np.asarray(linear)[..., :3], tonemap=tonemap)


def psnr8(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR (dB, peak 255) of two 8-bit images; inf when equal."""
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)


def page_bytes(folder) -> int:
    return sum(p.stat().st_size for p in Path(folder).rglob("*") if p.is_file())
