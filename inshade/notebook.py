"""Bundles and assets in Jupyter: a picture from a headless render, and the WebGL2 page to turn it.

- A bundle or a loaded scene as the last line of a cell is a small PNG of what ``inshade render``
  draws for it (``bundle_png``, ``scene_png``); a bundle that cannot be drawn on its own (no
  ``render`` field and no scene beside it) gives None, so Jupyter shows its text instead. ``import
  inshade`` registers both with the running IPython's PNG formatter, by type name: the bundle and
  the scene model stay below the renderer (no method of theirs imports it).
- ``picture(x, settings=..., mode=...)``: the same for an asset (a folder with a scene.json, a
  shipped asset's name, a bundle), at any of its settings; a ``Picture`` shows itself as PNG.
- ``show(x)``: the page ``inshade export-web`` writes, inlined into one HTML document shown in an
  iframe (``srcdoc``): nothing to serve, nothing left on disk, and the page keeps its own window (its
  styles, keys and globals stay out of the notebook's). Its files are embedded as base64 and handed
  to the page's ``fetch``, so the cell's output is a third larger than the exported folder: a large
  asset makes a large notebook once saved with outputs.

Pictures are deterministic: the same asset, size and settings give the same bytes. Nothing here
imports torch (the runtime's rule), nor IPython unless a notebook already runs it; ``import inshade``
imports this module, so what it needs beyond the light standard library waits until called.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

SIZE = 256          # a picture's longer side at most, in pixels: small enough to render in a moment
PAGE_SIZE = 512     # the interactive view's longer side at most
PANEL_PX = 420      # the page's settings panel beside the canvas, with margins
TEXT_PX = 120       # the page's status line and help text below it
CONTROL_PX = 27     # one control of the panel
MISSING_IPYTHON = "inshade.show needs IPython (not installed): pip install -e '.[notebook]'"


class Picture:
    """A PNG (8-bit sRGB, as ``inshade render`` writes it) and the render's record (``info``: the GL
    driver, the bundle digests, the settings); shows itself in Jupyter."""

    def __init__(self, data: bytes, info: dict):
        self.data, self.info = data, info

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return _png_size(self.data)

    def save(self, path) -> Path:
        path = Path(path)
        path.write_bytes(self.data)
        return path

    def _repr_png_(self) -> bytes:
        return self.data

    def __repr__(self) -> str:
        return "<inshade picture {}x{}>".format(*self.size)


def fit(size, longest: int) -> tuple[int, int]:
    """``size`` (w, h) scaled down, aspect kept, so its longer side is at most ``longest``."""
    w, h = int(size[0]), int(size[1])
    scale = min(1.0, longest / max(w, h))
    return max(1, round(w * scale)), max(1, round(h * scale))


def picture(x, *, size: int = SIZE, settings: dict | None = None, mode=None, camera=None) -> Picture:
    """A headless render of ``x`` as a ``Picture``: what ``inshade render`` draws (the scene of an
    asset folder, or a bundle's ``render`` field), its longer side at most ``size`` pixels.
    ``x``: an asset folder or name, a scene.json, a bundle folder, a ``Bundle`` or a loaded scene;
    ``settings``: the scene's settings (``inshade render --set``); ``mode``: a display mode
    ("final", "network", "reference", "error", "split"); ``camera``: a camera or its dict."""
    from inshade.bundle import Bundle
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import Scene, load_scene, scene_from_bundle

    source = _source(x)
    if isinstance(source, Bundle):   # a bundle alone, drawn as its render field says (as render_bundle)
        scene, bundles = scene_from_bundle(source), [source]
    else:
        scene, bundles = (source if isinstance(source, Scene) else load_scene(source)), None
    w, h = fit(scene.size, size)
    image, info = render_scene(scene, width=w, height=h, settings=settings, mode=mode, camera=camera, bundles=bundles)
    return Picture(_png(image, info), info)


def bundle_png(bundle, size: int = SIZE) -> bytes | None:
    """A bundle in Jupyter: PNG bytes of the bundle as ``inshade render`` draws it (its asset's scene
    when it was loaded from a folder holding a scene.json, else its ``render`` field), or None when
    it cannot be drawn on its own, so Jupyter falls back to its text."""
    from inshade.scene.description import RenderSpecError, render_spec

    if _scene_folder(bundle) is None:
        try:
            render_spec(bundle)
        except RenderSpecError:   # no render field, or one only a scene can use
            return None
    return picture(bundle, size=size).data


def scene_png(scene, size: int = SIZE) -> bytes:
    """A loaded scene (``load_scene``) in Jupyter: PNG bytes of it at its default settings."""
    return picture(scene, size=size).data


def register(shell) -> None:
    """Bundles and scenes draw themselves in ``shell`` (an IPython shell): its PNG formatter calls
    ``bundle_png`` / ``scene_png`` for them. Named by module and class, so nothing is imported here."""
    png = shell.display_formatter.formatters["image/png"]
    png.for_type_by_name("inshade.bundle", "Bundle", bundle_png)
    png.for_type_by_name("inshade.scene.description", "Scene", scene_png)


def _register_in_running_notebook() -> None:
    """``register`` the IPython this process runs in, if any (a kernel imports IPython before any
    cell); a plain interpreter is left alone, and IPython is never imported from here."""
    ipython = sys.modules.get("IPython")
    shell = getattr(ipython, "get_ipython", lambda: None)() if ipython is not None else None
    if shell is not None and hasattr(shell, "display_formatter"):
        register(shell)


def show(x, *, width: int | None = None, height: int | None = None, settings: dict | None = None):
    """The interactive view of ``x`` in a notebook: the page ``inshade export-web`` writes (orbit,
    zoom, the settings as controls), inlined into an iframe. ``x``: an asset folder or name, a bundle
    folder or a ``Bundle``; ``width``/``height``: the canvas in pixels (default: the asset's size,
    its longer side at most 512); ``settings``: values fixed at export (``--set``). Returns an
    ``IPython.display.HTML``; ImportError (one line) without IPython."""
    try:
        from IPython.display import HTML
    except ImportError:
        raise ImportError(MISSING_IPYTHON, name="IPython") from None
    return HTML(page_html(x, width=width, height=height, settings=settings))


def page_html(x, *, width: int | None = None, height: int | None = None, settings: dict | None = None) -> str:
    """``show``'s HTML without IPython: an ``<iframe srcdoc=...>`` holding the whole exported page."""
    import html
    import json
    import tempfile

    from inshade.scene.description import load_scene
    from inshade.web.export import MANIFEST, PAGE_FILES, export_web

    with tempfile.TemporaryDirectory(prefix="inshade-show-") as tmp:
        source = _source(x, Path(tmp) / "bundle")
        if width is None or height is None:   # the asset's shape, from whichever side was given
            sw, sh = load_scene(source).size
            if width is None and height is None:
                width, height = fit((sw, sh), PAGE_SIZE)
            elif width is None:
                width = max(1, round(height * sw / sh))
            else:
                height = max(1, round(width * sh / sw))
        folder = Path(tmp) / "page"
        export_web(source, folder, settings=settings, width=width, height=height)
        files = {p.relative_to(folder).as_posix(): p.read_bytes()
                 for p in sorted(folder.rglob("*")) if p.is_file()}
    manifest = json.loads(files[MANIFEST])
    page = {name: files.pop(name).decode() for name in PAGE_FILES}
    doc = inline_page(page["index.html"], page["inshade.js"], files)
    # the panel: a control per setting, the view and split controls where there is a reference, a reset
    controls = len(manifest.get("settings", [])) + 1 + (2 if manifest.get("display", {}).get("reference") else 0)
    panel_h = CONTROL_PX * controls
    # in a <div>: IPython's HTML takes a bare <iframe> for one it should load by URL (IFrame) and warns
    title = html.escape(manifest.get("title", "inshade"))
    return (f'<div><iframe srcdoc="{html.escape(doc, quote=True)}" title="{title}" '
            f'width="{width + PANEL_PX}" height="{max(height, panel_h) + TEXT_PX}" '
            f'style="border: 0; max-width: 100%;"></iframe></div>')


def inline_page(index_html: str, script: str, files: dict[str, bytes]) -> str:
    """index.html with inshade.js inlined and the other files served to its ``fetch`` from memory."""
    import base64
    import json

    # the page loads inshade.js as a module and fetches the rest relative to itself: both need a
    # folder, which an iframe's srcdoc has not
    loader = re.compile(r'<script type="module">.*?</script>', re.S)
    found = loader.search(index_html)
    start = re.search(r"main\(\{.*?\}\);", found.group(0), re.S) if found else None
    if start is None:
        raise ValueError("index.html: its module script does not call main({...})")
    embedded = json.dumps({name: base64.b64encode(data).decode() for name, data in files.items()})
    shim = ("<script>\n// the exported folder's files, served to the page's fetch from memory\n"
            f"(() => {{ const files = {embedded};\n"
            "  window.fetch = async (url, init) => {\n"
            "    const name = String(url).replace(/^\\.\\//, \"\");\n"
            "    if (!(name in files)) return new Response(null, {status: 404, statusText: \"not in this page\"});\n"
            "    const text = atob(files[name]), bytes = new Uint8Array(text.length);\n"
            "    for (let i = 0; i < text.length; ++i) bytes[i] = text.charCodeAt(i);\n"
            "    return new Response(bytes, {status: 200});\n"
            "  };\n"
            "})();\n</script>\n")
    code = f"{script}\n{start.group(0)}".replace("</script", "<\\/script")   # else it would end the element
    module = f'<script type="module">\n{code}\n</script>'
    body = loader.sub(lambda _m: shim + module, index_html)
    # the evaluation page is a second document: not part of the inlined view
    return re.sub(r'\s*<a href="evaluate\.html">[^<]*</a>\s*·', "", body)


def _source(x, spill: Path | None = None):
    """What a render or an export reads: a path (an asset name resolved), a loaded scene, or a
    ``Bundle``; with ``spill``, a bundle without a folder is saved there (a copy: the caller's
    ``Bundle`` keeps its own path) and its folder is returned."""
    from inshade.bundle import Bundle
    from inshade.scene.description import Scene, resolve_asset

    if isinstance(x, Bundle):
        folder = _scene_folder(x)
        if folder is not None or spill is None:
            return folder or x
        if x.path is not None:
            return x.path
        Bundle(x.meta, x.tensors).save(spill)
        return spill
    if isinstance(x, Scene):
        if spill is None:
            return x
        if x.path is None and x.root is None:
            raise ValueError(f"scene '{x.name}' was made in memory: the page is exported from a folder; "
                             "pass the asset's folder")
        return x.path or x.root
    return resolve_asset(x)


def _scene_folder(bundle) -> Path | None:
    """The asset folder a bundle was loaded from, when it holds a scene.json: ``inshade render`` of
    that folder draws the scene, not the bare bundle."""
    from inshade.scene.description import SCENE_FILE

    if bundle.path is None:
        return None
    folder = Path(bundle.path)
    folder = folder.parent if folder.is_file() else folder
    return folder if (folder / SCENE_FILE).is_file() else None


def _png(image, info) -> bytes:
    """The PNG ``inshade render -o x.png`` writes (tone mapping, sRGB, the scene's labels), as bytes."""
    import tempfile

    from inshade.runtime.headless import save_render

    with tempfile.TemporaryDirectory(prefix="inshade-picture-") as tmp:
        path, _ = save_render(image, info, Path(tmp) / "picture.png")
        return path.read_bytes()


def _png_size(data: bytes) -> tuple[int, int]:
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


_register_in_running_notebook()
