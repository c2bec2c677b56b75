"""The pictures of the README and the docs are made by docs/make_pictures.py from the shipped assets,
and are current: every picture a page shows is one the script makes, and none was made from inputs
(an asset's files, the README's first example, the script's recipe for it) that have changed since.
These checks hash files and draw nothing; one test redraws the cheapest picture and compares it."""
from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
# Plots `inshade bench NAME --out docs/bench` writes beside its JSON record: measurements of a
# machine at a time, remade by running the benchmark, not drawn from the assets.
BENCH = DOCS / "bench"
REDO = "python docs/make_pictures.py --stale"


def _load(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module   # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def mp():
    return _load("make_pictures", DOCS / "make_pictures.py")


@pytest.fixture(scope="module")
def made(mp):
    return mp.pictures()


@pytest.fixture(scope="module")
def record(mp):
    return mp.load_record()


def _images_in(md: Path) -> list[str]:
    text = md.read_text()
    text = re.sub(r"```.*?```", "", text, flags=re.S)   # commands in code blocks name output files, not pictures
    targets = re.findall(r"!\[[^\]]*\]\(([^)\s]+)[^)]*\)", text) + re.findall(r'<img\s[^>]*src="([^"]+)"', text)
    return [t for t in targets if not re.match(r"^[a-z]+:", t)]


def shown_pictures() -> dict[Path, list[str]]:
    """Every image README.md and the docs' pages show (and the Shipped assets page that
    docs/gen_reference.py writes at build time) -> the pages that show it."""
    gen = _load("gen_reference", DOCS / "gen_reference.py")
    copies: dict[Path, Path] = {}   # what the generator copies into the site -> where from
    gen.assets_reference(lambda src, dest: copies.setdefault((DOCS / dest).resolve(), Path(src).resolve()))
    shown: dict[Path, list[str]] = {src: ["the Shipped assets page (docs/gen_reference.py)"] for src in copies.values()}
    for md in [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]:
        for target in _images_in(md):
            path = (md.parent / target).resolve()
            shown.setdefault(copies.get(path, path), []).append(md.relative_to(ROOT).as_posix())
    return shown


@pytest.fixture(scope="module")
def shown():
    return shown_pictures()


def _name(mp, path: Path) -> str | None:
    try:
        return path.relative_to(mp.PICTURES).as_posix()
    except ValueError:
        return None


def test_pages_show_pictures(shown):
    assert len(shown) > 20


def test_every_picture_shown_exists(shown):
    missing = [f"{p.relative_to(ROOT)} (shown by {', '.join(by)})" for p, by in shown.items() if not p.is_file()]
    assert not missing, "pictures that are not there: " + "; ".join(missing)


def test_every_picture_shown_is_made_by_the_script(mp, made, shown):
    """A picture outside docs/pictures/ (other than a benchmark's plot) is one nobody remakes."""
    loose = [f"{p.relative_to(ROOT)} (shown by {', '.join(by)})" for p, by in shown.items()
             if _name(mp, p) not in made and not p.is_relative_to(BENCH)]
    assert not loose, ("pictures not made by docs/make_pictures.py: add them to its list (and point the page at "
                       "docs/pictures/): " + "; ".join(loose))


def test_every_picture_the_script_makes_is_shown(mp, made, shown):
    names = {_name(mp, p) for p in shown}
    assert not [n for n in made if n not in names], "pictures no page shows: drop them from the script"


def test_the_record_holds_every_picture(made, record):
    assert set(record) == set(made), (f"docs/pictures.json and the script disagree: not recorded "
                                      f"{sorted(set(made) - set(record))}, recorded but not made "
                                      f"{sorted(set(record) - set(made))}: run {REDO}")


def test_no_stray_files_among_the_pictures(mp, made):
    stray = [p.relative_to(ROOT).as_posix() for p in mp.PICTURES.rglob("*") if p.is_file()
             and p.relative_to(mp.PICTURES).as_posix() not in made]
    assert not stray, f"files in docs/pictures/ the script does not make: {stray}"


def test_every_picture_is_current(mp, made, record):
    """An asset retrained, the README's first example edited or a recipe changed, and the picture
    not made again: each is named with what changed."""
    stale = {name: why for name, p in made.items() if name in record and (why := mp.stale(p, record))}
    assert not stale, (f"pictures made from inputs that changed since (run {REDO}):\n" +
                       "\n".join(f"  {n}: {'; '.join(why)}" for n, why in stale.items()))


def test_the_record_names_the_renderer(record):
    assert record and not [n for n, e in record.items() if not e.get("renderer", {}).get("gl_renderer")]


CHEAPEST = "assets/sdf_creature/preview.png"


def test_the_cheapest_picture_is_made_again_as_recorded(gl, mp, record, tmp_path):
    """On the renderer the record names: the same bytes; on another, the same picture within what a
    driver's arithmetic and the palette allow."""
    from PIL import Image

    assert mp.main(["--out", str(tmp_path), CHEAPEST]) == 0
    again = (tmp_path / CHEAPEST).read_bytes()
    entry = record[CHEAPEST]
    same = entry["renderer"] == {"gl_renderer": gl.info["GL_RENDERER"], "gl_version": gl.info["GL_VERSION"]}
    if same:
        assert mp._sha256(again) == entry["sha256"], f"{CHEAPEST}: made again on {gl.info['GL_RENDERER']}, other bytes"
    else:
        a = np.asarray(Image.open(tmp_path / CHEAPEST).convert("RGB"), np.float64)
        b = np.asarray(Image.open(mp.PICTURES / CHEAPEST).convert("RGB"), np.float64)
        db = 10 * np.log10(255.0 ** 2 / max(float(np.mean((a - b) ** 2)), 1e-12))
        assert db >= 30.0, f"{CHEAPEST}: made again on {gl.info['GL_RENDERER']}: {db:.1f} dB from the committed one"
