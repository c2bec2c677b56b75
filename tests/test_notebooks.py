"""Jupyter: a bundle's or a scene's picture (what ``inshade render`` draws, small, through IPython's
PNG formatter), an asset's page inlined (``inshade.show``: the exported WebGL2 page in an iframe's srcdoc, drawn in
headless Chromium here), and the docs' notebooks (docs/notebooks/*.ipynb) run cell by cell in a
kernel of this interpreter, committed without outputs so every picture they show is made by them."""
from __future__ import annotations

import html
import io
import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from inshade.bundle import Bundle, load
from inshade.notebook import MISSING_IPYTHON, Picture, bundle_png, page_html, picture, register, show

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "docs" / "notebooks").glob("*.ipynb"))
TRAINED = ROOT / "trained"
CELL_TIMEOUT_S = 300


def pixels(png: bytes) -> np.ndarray:
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


# pictures -------------------------------------------------------------------------------------------

def formatter():
    """A notebook's display formatter, as ``import inshade`` sets it up in a running kernel."""
    from types import SimpleNamespace

    from IPython.core.formatters import DisplayFormatter

    shell = SimpleNamespace(display_formatter=DisplayFormatter())
    register(shell)
    return shell.display_formatter


def test_a_bundle_with_a_render_field_shows_what_inshade_render_writes(gl, tmp_path):
    from inshade.cli import main

    data, _ = formatter().format(load(TRAINED / "neural_image"))
    png = data["image/png"]
    assert pixels(png).shape == (256, 256, 3)
    assert png == bundle_png(load(TRAINED / "neural_image"))   # deterministic, byte for byte
    assert main(["render", str(TRAINED / "neural_image"), "-o", str(tmp_path / "shot.png")]) == 0
    assert np.array_equal(pixels(png), pixels((tmp_path / "shot.png").read_bytes()))


def test_a_bundle_in_memory_draws_its_render_field_at_most_256_pixels(gl):
    on_disk = load(TRAINED / "hash_grid_image")            # render field: 2048 x 2048
    bundle = Bundle(on_disk.meta, on_disk.tensors)           # no folder, no scene beside it
    assert pixels(bundle_png(bundle)).shape == (256, 256, 3)
    assert bundle.path is None


def test_a_bundle_that_cannot_be_drawn_alone_shows_as_text(gl):
    drawn = load(TRAINED / "neural_image")
    meta = {k: v for k, v in drawn.meta.items() if k != "render"}
    bare = Bundle(meta, drawn.tensors)
    assert bundle_png(bare) is None                                         # no render field
    assert bundle_png(load(TRAINED / "prt_creature" / "transfer")) is None   # drawn by its scene only
    data, _ = formatter().format(bare)
    assert "image/png" not in data and "text/plain" in data                 # Jupyter shows the text


def test_a_loaded_scene_shows_itself(gl):
    from inshade.scene.description import load_scene

    data, _ = formatter().format(load_scene(TRAINED / "prt_creature"))
    assert data["image/png"] == picture("prt_creature").data


def test_import_registers_only_with_a_running_ipython(monkeypatch):
    import types

    import inshade.notebook as nb

    calls = []
    monkeypatch.setattr(nb, "register", calls.append)
    monkeypatch.setitem(sys.modules, "IPython", types.SimpleNamespace(get_ipython=lambda: None))
    nb._register_in_running_notebook()                       # IPython imported, no shell: a script
    shell = types.SimpleNamespace(display_formatter=object())
    monkeypatch.setitem(sys.modules, "IPython", types.SimpleNamespace(get_ipython=lambda: shell))
    nb._register_in_running_notebook()
    assert calls == [shell]


def test_an_asset_renders_at_its_settings(gl):
    plain = picture("prt_creature")
    glossy = picture("prt_creature", settings={"shading": "glossy"})
    assert isinstance(plain, Picture) and plain.size == (256, 256)
    assert plain._repr_png_() == plain.data
    assert not np.array_equal(pixels(plain.data), pixels(glossy.data))
    with pytest.raises(Exception, match="unknown setting 'nope'"):
        picture("prt_creature", settings={"nope": 1})


# the page ------------------------------------------------------------------------------------------

def _srcdoc(page: str) -> str:
    m = re.fullmatch(r'<div><iframe srcdoc="([^"]*)" .*</iframe></div>', page, re.S)
    assert m, page[:200]
    return html.unescape(m.group(1))


def test_show_inlines_the_exported_page(gl):
    out = show("neural_image", width=64, height=64)
    page = out._repr_html_()
    assert page.startswith("<div><iframe srcdoc=")
    doc = _srcdoc(page)
    assert "export async function loadExport" in doc          # inshade.js, inlined
    assert '"manifest.json"' in doc and '"data.bin"' in doc   # the folder's files, for its fetch
    assert 'href="evaluate.html"' not in doc                  # a second document: not in the iframe


def test_show_takes_a_bundle_in_memory_without_moving_it(gl):
    drawn = load(TRAINED / "neural_image")
    bundle = Bundle({k: v for k, v in drawn.meta.items()}, drawn.tensors)
    assert "loadExport" in _srcdoc(page_html(bundle, width=32, height=32))
    assert bundle.path is None


def test_show_without_ipython_says_which_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "IPython", None)
    monkeypatch.setitem(sys.modules, "IPython.display", None)
    with pytest.raises(ImportError) as info:
        show("neural_image")
    assert str(info.value) == MISSING_IPYTHON
    assert "\n" not in MISSING_IPYTHON and "pip install -e '.[notebook]'" in MISSING_IPYTHON


def test_the_inlined_page_draws_what_the_picture_shows(gl, tmp_path):
    """The iframe's page in headless Chromium (no server: a file with the iframe in it) against the
    headless render, as the exported pages are held (tests/web/test_web.py: >= 40 dB, two rasterisers)."""
    from inshade.web.browser import Browser, psnr8

    host = tmp_path / "notebook.html"
    host.write_text(f"<!doctype html><html><body>{page_html('neural_image', width=128, height=128)}</body></html>")
    with Browser() as browser:
        driver = browser.driver
        driver.get(host.as_uri())
        driver.switch_to.frame(driver.find_element("tag name", "iframe"))
        state, start = {}, time.perf_counter()
        while time.perf_counter() - start < 300:
            state = driver.execute_script(
                "const p = window.inshade; return p ? {ready: p.ready, error: p.error} : null;") or {}
            if state.get("ready") or state.get("error"):
                break
            time.sleep(0.1)
        assert state.get("ready"), state
        canvas = browser.canvas()
    assert psnr8(canvas, pixels(picture("neural_image", size=128).data)) >= 40.0


def test_the_notebook_module_is_torch_free():
    probe = ("import sys, inshade, inshade.notebook as nb\n"
             "from inshade.bundle import load\n"
             f"assert nb.bundle_png(load({str(TRAINED / 'neural_image')!r}))\n"
             "nb.page_html('neural_image', width=16, height=16)\n"
             "print(sorted(m for m in ('torch', 'IPython') if m in sys.modules))\n")
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "[]"   # nor IPython, outside a notebook


# the docs' notebooks ------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def kernel_specs(tmp_path_factory):
    """A kernel spec that runs this interpreter (the venv's, with ipykernel): the machine's own
    "python3" spec may name another Python."""
    from jupyter_client.kernelspec import KernelSpecManager

    folder = tmp_path_factory.mktemp("kernels")
    spec = folder / "inshade-test"
    spec.mkdir()
    (spec / "kernel.json").write_text(json.dumps({
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "inshade tests", "language": "python"}))
    return KernelSpecManager(kernel_dirs=[str(folder)], ensure_native_kernel=False)


def test_the_docs_have_notebooks():
    assert {p.name for p in NOTEBOOKS} >= {"first_network.ipynb", "shipped_asset.ipynb"}


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_a_notebook_is_committed_without_outputs(path):
    import nbformat

    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    stale = [i for i, c in enumerate(nb.cells) if c.cell_type == "code" and (c.outputs or c.execution_count)]
    assert not stale, f"{path.name}: cells {stale} hold outputs: clear them (the pictures come from running it)"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_a_notebook_runs(path, kernel_specs, tmp_path):
    import nbformat
    from jupyter_client.manager import KernelManager
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    km = KernelManager(kernel_name="inshade-test", kernel_spec_manager=kernel_specs)
    # run where it may write (the first notebook exports my_net/ into its working folder)
    NotebookClient(nb, km=km, timeout=CELL_TIMEOUT_S, resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]    # execute() raises first; kept as a guard
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    pages = [o for o in outputs if "<iframe srcdoc=" in o.get("data", {}).get("text/html", "")]
    if path.name == "first_network.ipynb":
        import base64

        assert len(images) == 1 and len(pages) == 1
        assert pixels(base64.b64decode(images[0]["data"]["image/png"])).shape == (256, 256, 3)
    else:
        assert images, f"{path.name}: shows no picture"
