"""The recipes of the docs' pictures: each picture, what it shows, what it draws and how, as
docs/make_pictures.py makes them (that script keeps the record, docs/pictures.json, and its command
line). A recipe's source (its maker and the helpers in ``COMMON``) is part of what a picture is
recorded as made from, so a change here shows the picture as stale.
"""
from __future__ import annotations

import contextlib
import io
import json
import os
import re
import shlex
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
TRAINED = ROOT / "trained"
PICTURES = DOCS / "pictures"
README = ROOT / "README.md"

CAPTION_HEIGHT = 18
CAPTION_BACKGROUND = (20, 20, 22)
THUMBNAIL_WIDTH = 256        # the assets page shows them 256 wide, the README 64
PALETTE_COLOURS = 256        # an adaptive palette keeps a render at tens of KB (~39 dB from its own pixels)


class PictureError(RuntimeError):
    """A picture could not be made: the message says which and why."""


# --- what a picture is made from -------------------------------------------------------------------

@dataclass(frozen=True)
class Picture:
    name: str                                   # its path under docs/pictures/
    shows: str
    make: Callable                              # make(picture) -> (PIL image, renderer record)
    assets: tuple = ()                          # shipped asset folders it draws (trained/NAME)
    files: tuple = ()                           # other inputs, relative to the repository
    args: dict = field(default_factory=dict)    # the recipe's data: sizes, settings, views
    readme_example: bool = False                # made from the README's first example as written
    needs: str = "gl"                           # gl | torch | browser | window


def readme_example() -> tuple[str, str]:
    """The README's first example as written: its python block and its `inshade render my_net` line."""
    text = README.read_text()
    python = re.search(r"```python\n(.*?)```", text, re.S)
    render = re.search(r"^(inshade render my_net\b[^#\n]*)", text, re.M)
    if python is None or render is None:
        raise PictureError("README.md: the first example (a ```python block, then `inshade render my_net`) "
                           "is not there")
    return python.group(1), render.group(1).strip()


# --- drawing -----------------------------------------------------------------------------------------

def run_cli(argv: list[str]) -> tuple[int, str]:
    """``inshade ARGV`` in this process, its "wrote ..." lines kept out of the script's own;
    (exit status, the last line it said)."""
    from inshade.cli import main

    said = io.StringIO()
    with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
        code = main(argv)
    lines = said.getvalue().strip().splitlines()
    return code, lines[-1] if lines else ""


def render(asset, width: int, height: int, settings: dict | None = None, spp: int | None = None):
    """`inshade render ASSET -o x.png --width W --height H [--set ...]`, as a user types it: the PNG
    (exposure, tone map, the scene's labels) and the renderer its sidecar names."""
    from PIL import Image

    with tempfile.TemporaryDirectory(prefix="inshade-picture-") as tmp:
        out = Path(tmp) / "shot.png"
        argv = ["-q", "render", str(asset), "-o", str(out), "--width", str(width), "--height", str(height)]
        for key, value in (settings or {}).items():
            argv += ["--set", f"{key}={value}"]
        if spp:
            argv += ["--spp", str(spp)]
        code, said = run_cli(argv)
        if code != 0:
            raise PictureError(f"inshade {shlex.join(argv[1:])}: exit {code}: {said}")
        gl = json.loads(out.with_name(out.name + ".json").read_text())["gl"]
        image = Image.open(out).convert("RGB")
        image.load()
    return image, {"gl_renderer": gl["renderer"], "gl_version": gl["version"]}


def scene_size(asset: str) -> tuple[int, int]:
    from inshade.scene.description import load_scene

    return tuple(load_scene(TRAINED / asset).size)


def captioned(image, text: str):
    """The image under a dark strip naming it."""
    from PIL import Image, ImageDraw, ImageFont

    out = Image.new("RGB", (image.width, image.height + CAPTION_HEIGHT), CAPTION_BACKGROUND)
    out.paste(image, (0, CAPTION_HEIGHT))
    ImageDraw.Draw(out).text((5, CAPTION_HEIGHT // 2), text, fill=(225, 225, 225),
                             font=ImageFont.load_default(size=12), anchor="lm")
    return out


def grid(images, columns: int):
    """Images of one size in rows of ``columns``."""
    from PIL import Image

    w, h = images[0].size
    rows = -(-len(images) // columns)
    out = Image.new("RGB", (w * columns, h * rows), CAPTION_BACKGROUND)
    for k, image in enumerate(images):
        out.paste(image, ((k % columns) * w, (k // columns) * h))
    return out


def one_renderer(records) -> dict:
    """The renderer of a picture drawn in several renders (they all ran on the one context)."""
    records = [r for r in records if r]
    if any(r != records[0] for r in records):
        raise PictureError(f"one picture drawn by several renderers: {records}")
    return records[0]


def png_bytes(image) -> bytes:
    """The picture as a small PNG: an adaptive palette where the image has more colours than that,
    zlib at its best; no time stamp, so the same pixels are the same bytes."""
    from PIL import Image

    image = image.convert("RGB")
    if image.getcolors(PALETTE_COLOURS) is None:
        image = image.quantize(PALETTE_COLOURS, method=Image.Quantize.MEDIANCUT)
    buf = io.BytesIO()
    image.save(buf, format="PNG", optimize=True)
    return buf.getvalue()


COMMON = (render, captioned, grid, png_bytes)   # every picture goes through these: part of each recipe


# --- the pictures --------------------------------------------------------------------------------------

def make_first_example(picture: Picture):
    """The README's first example as a newcomer runs it: its python block exports `my_net` in an
    empty folder, then its `inshade render my_net` line draws it."""
    from PIL import Image

    code, line = readme_example()
    argv = shlex.split(line)[1:]
    if "-o" in argv:
        del argv[argv.index("-o"):argv.index("-o") + 2]
    here = Path.cwd()
    with tempfile.TemporaryDirectory(prefix="inshade-first-example-") as tmp:
        os.chdir(tmp)
        try:
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
                exec(compile(code, "README.md", "exec"), {"__name__": "__readme__"})   # its parity line
            code, said = run_cli(["-q", *argv, "-o", "shot.png"])
            if code != 0:
                raise PictureError(f"README.md: `{line}`: exit {code}: {said}")
            gl = json.loads(Path("shot.png.json").read_text())["gl"]
            image = Image.open("shot.png").convert("RGB")
            image.load()
        finally:
            os.chdir(here)
    return image, {"gl_renderer": gl["renderer"], "gl_version": gl["version"]}


def make_thumbnail(picture: Picture):
    """A shipped asset as `inshade render NAME` draws it (its defaults, or the settings named), at
    the thumbnail width and its own aspect."""
    asset = picture.assets[0]
    w, h = scene_size(asset)
    width = min(w, picture.args["width"])
    height = max(1, round(h * width / w))
    return render(TRAINED / asset, width, height, picture.args.get("settings"))


def make_grid(picture: Picture):
    """Assets drawn at one tile size, with the settings of each row, in a grid; each named above it
    where ``captions`` asks."""
    a = picture.args
    tiles, renderers = [], []
    for settings in a["rows"]:
        for asset in picture.assets:
            image, renderer = render(TRAINED / asset, a["tile"][0], a["tile"][1], settings, a.get("spp"))
            if a.get("captions"):
                image = captioned(image, asset[len(a.get("strip", "")):])
            tiles.append(image)
            renderers.append(renderer)
    return grid(tiles, a.get("columns", len(picture.assets))), one_renderer(renderers)


def make_gltf(picture: Picture):
    """The tests' glTF files (python -m inshade.geometry.gltf_scenes) as `inshade render FILE.glb`
    draws them: the glTF spec's shading, and the material's channels on the torus."""
    from inshade.geometry import gltf_scenes

    a = picture.args
    tiles, renderers = [], []
    with tempfile.TemporaryDirectory(prefix="inshade-gltf-") as tmp:
        for scene, settings in a["views"]:
            path = Path(tmp) / f"{scene}.glb"
            if not path.exists():
                gltf_scenes.SCENES[scene]().write(path)
            image, renderer = render(path, *a["tile"], settings)
            view = settings.get("view", "shaded")
            tiles.append(captioned(image, f"{scene}.glb" + ("" if view == "shaded" else f": {view}")))
            renderers.append(renderer)
    return grid(tiles, len(tiles)), one_renderer(renderers)


# the page's own loop stops once it is ready, so the canvas holds its first frame (an accumulating
# program would otherwise add samples for as long as the browser runs)
_STOP_AFTER_READY = ("const raf = window.requestAnimationFrame.bind(window);"
                     "window.requestAnimationFrame = (f) => raf((t) => { if (!(window.inshade && window.inshade.ready)) f(t); });")


def make_web_page(picture: Picture):
    """`inshade export-web ASSET` opened in headless Chromium (SwiftShader): the canvas and its
    controls as the page first shows them (its frame-time readout, a clock, is left out)."""
    from PIL import Image
    from selenium.webdriver.common.by import By

    from inshade.runtime.context import shared_context
    from inshade.web.browser import Browser, serve
    from inshade.web.export import export_web

    info = shared_context().info
    with tempfile.TemporaryDirectory(prefix="inshade-page-") as tmp, Browser() as browser:
        export_web(TRAINED / picture.assets[0], Path(tmp) / "page")
        browser.driver.execute_cdp_cmd("Page.addScriptToEvaluateOnNewDocument", {"source": _STOP_AFTER_READY})
        browser.driver.set_window_size(*picture.args["window"])
        with serve(Path(tmp) / "page") as url:
            state = browser.open(url + "index.html")
            if state["error"] or not state["ready"]:
                raise PictureError(f"{picture.assets[0]}: the page says: {state['error']}")
            png = browser.driver.find_element(By.ID, "view").screenshot_as_png
        renderer = {"browser": browser.driver.capabilities.get("browserVersion"),
                    "webgl_renderer": browser.renderer(),
                    "gl_renderer": info["GL_RENDERER"], "gl_version": info["GL_VERSION"]}   # the export's draw
    image = Image.open(io.BytesIO(png)).convert("RGB")
    image.load()
    return image, renderer


_xvfb_display = None


def _xvfb() -> str:
    """An X display for the window pictures: our own Xvfb on a free display number (as the viewer's
    tests start it), stopped when the script ends."""
    global _xvfb_display
    if _xvfb_display is not None:
        return _xvfb_display
    import atexit

    from inshade.viewer.virtual_display import VirtualDisplayError, start_xvfb

    try:
        proc, display = start_xvfb()
    except VirtualDisplayError as exc:
        raise PictureError(f"the viewer pictures need a display: {exc}") from None
    atexit.register(lambda: (proc.terminate(), proc.wait(timeout=10)))
    _xvfb_display = os.environ["DISPLAY"] = display
    return _xvfb_display


def make_viewer(picture: Picture):
    """`inshade view ASSET` in a window on Xvfb: the panel and the scene, at a bookmark and display
    mode. The window stops above the panel's Performance section (frame times: a clock)."""
    _xvfb()
    from inshade.viewer.app import ViewerApp

    a = picture.args
    with tempfile.TemporaryDirectory(prefix="inshade-viewer-") as tmp:
        app = ViewerApp(TRAINED / picture.assets[0], size=tuple(a["window"]), vsync=False, screenshot_dir=tmp)
        try:
            # the view is set before the first draw, so the panel's PSNR is measured for it
            app.go_to_bookmark(a["bookmark"])
            app.set_mode(a["mode"])
            app.step(4)   # "compiling...", the JIT draw, then imgui's layout settles
            if app.compiling:
                raise PictureError(f"{picture.name}: the network program did not draw")
            image = app.read_window()
            renderer = {"gl_renderer": app.ctx.info["GL_RENDERER"], "gl_version": app.ctx.info["GL_VERSION"]}
        finally:
            app.close()
    from PIL import Image

    return Image.fromarray(image), renderer


def _pictures() -> list[Picture]:
    prt = ("prt_creature", "prt_mechanical", "prt_neural_bunny", "prt_mesh")
    uvfree = ("uvfree_material_stump_high_memory", "uvfree_material_stump_high_balanced",
              "uvfree_material_stump_high_quality", "uvfree_material_stump_low_balanced",
              "uvfree_material_rock_balanced", "uvfree_material_fruit_balanced")
    viewer = {"window": [800, 480]}
    out = [
        Picture("first_example.png", "the README's first network (my_net), as `inshade render my_net` draws it",
                make_first_example, readme_example=True, needs="torch"),
        Picture("prt_previews.png", "learnt-transfer PRT: creature, mechanical, neural bunny, mesh bunny; "
                "diffuse above, glossy below", make_grid, assets=prt,
                args={"tile": [192, 192], "rows": [{"shading": "diffuse"}, {"shading": "glossy"}]}),
        Picture("neural_appearance_previews.png", "neural materials on the teapot, ceramic and brushed metal, "
                "each split: left reference, right neural", make_grid,
                assets=("neural_appearance_ceramic", "neural_appearance_brushed_metal"),
                args={"tile": [384, 288], "rows": [{"view": "split"}]}),
        Picture("uvfree_material_previews.png", "UV-free neural materials, each split: left the uv-textured "
                "reference, right decoded", make_grid, assets=uvfree,
                args={"tile": [240, 240], "rows": [{"view": "split"}], "columns": 3, "captions": True,
                      "strip": "uvfree_material_"}),
        Picture("gltf_in.png", "the tests' glTF files as the glTF spec shades them, and the torus's material "
                "channels", make_gltf, files=("geometry/gltf_scenes.py",),
                args={"tile": [256, 256], "views": [["showcase", {}], ["tiles_torus", {}],
                                                    ["tiles_torus", {"view": "base_color"}],
                                                    ["tiles_torus", {"view": "normal"}]]}),
        Picture("web_page.png", "neural_appearance_ceramic exported as a WebGL2 page, in headless Chromium",
                make_web_page, assets=("neural_appearance_ceramic",), args={"window": [1000, 700]},
                needs="browser"),
        Picture("viewer_final.png", "the viewer on neural_image: the network's picture", make_viewer,
                assets=("neural_image",), args={**viewer, "bookmark": "whole picture", "mode": "final"},
                needs="window"),
        Picture("viewer_split.png", "the viewer on neural_image, the face bookmark split: network | reference",
                make_viewer, assets=("neural_image",), args={**viewer, "bookmark": "face", "mode": "split"},
                needs="window"),
        Picture("viewer_error.png", "the viewer on neural_image: the error heat map", make_viewer,
                assets=("neural_image",), args={**viewer, "bookmark": "whole picture", "mode": "error"},
                needs="window"),
    ]
    # each shipped asset at its defaults (the README's technique table, the docs' Shipped assets page);
    # PRT assets glossy too, as their trainer's previews were
    for folder in sorted(p for p in TRAINED.iterdir() if (p / "scene.json").is_file()):
        out.append(Picture(f"assets/{folder.name}/preview.png", f"{folder.name} as `inshade render` draws it",
                           make_thumbnail, assets=(folder.name,), args={"width": THUMBNAIL_WIDTH}))
        if folder.name.startswith("prt_"):
            out.append(Picture(f"assets/{folder.name}/preview_glossy.png", f"{folder.name}, glossy",
                               make_thumbnail, assets=(folder.name,),
                               args={"width": THUMBNAIL_WIDTH, "settings": {"shading": "glossy"}}))
    return out


def pictures() -> dict[str, Picture]:
    return {p.name: p for p in _pictures()}
