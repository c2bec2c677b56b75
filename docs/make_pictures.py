"""The pictures of the README and the docs, made from the shipped assets in trained/ by the project's
own renderers, so that none of them can show an asset as it no longer is.

    python docs/make_pictures.py                 # every picture, into docs/pictures/
    python docs/make_pictures.py --stale         # only those whose inputs changed since they were made
    python docs/make_pictures.py prt_previews.png assets/prt_creature/preview.png
    python docs/make_pictures.py --list          # each picture, what it shows and what it is made from
    python docs/make_pictures.py --out DIR NAME  # into DIR, the record left as it is (to compare)

Every picture needs GL (headless EGL, as `inshade render`); first_example.png also torch,
web_page.png headless Chromium + chromium-driver (selenium), viewer_*.png Xvfb and the `view` extra.

docs/pictures.json records, for each picture, the sha256 of what it was made from (the asset folders it
draws, the README's first example for first_example.png, the geometry module for gltf_in.png, and its
recipe in docs/picture_recipes.py), the sha256 of the PNG and the renderer that drew it. tests/test_docs_pictures.py
fails when README.md or a docs page shows a picture this script does not make, or one made from inputs
that have changed since. A re-run on the same renderer writes the same bytes: nothing in a picture
depends on the clock (the viewer's timings are below the window's edge, the page's readout outside the
screenshot) or on the order the pictures are made in.
"""
from __future__ import annotations

import argparse
import functools
import hashlib
import inspect
import json
import sys
import time
from pathlib import Path

if str(Path(__file__).resolve().parent) not in sys.path:   # the recipes beside this script, however it is loaded
    sys.path.append(str(Path(__file__).resolve().parent))
from picture_recipes import (COMMON, DOCS, PICTURES, ROOT, TRAINED, Picture, PictureError,  # noqa: E402
                             pictures, png_bytes, readme_example)

RECORD = DOCS / "pictures.json"


# --- what a picture is made from -------------------------------------------------------------------

def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def asset_files(asset: str) -> list[Path]:
    """The files of a shipped asset that a render reads. Its trainer's own preview*.png are its
    output, not its input: they are left out."""
    folder = TRAINED / asset
    if not (folder / "scene.json").is_file() and not (folder / "bundle.json").is_file():
        raise PictureError(f"trained/{asset}: no such shipped asset")
    return sorted(p for p in folder.rglob("*")
                  if p.is_file() and "__pycache__" not in p.parts
                  and not (p.parent == folder and p.name.startswith("preview") and ".png" in p.name))


@functools.lru_cache(maxsize=None)   # several pictures draw one asset
def folder_digest(asset: str) -> str:
    h = hashlib.sha256()
    for p in asset_files(asset):
        h.update(p.relative_to(TRAINED).as_posix().encode() + b"\0" + _sha256(p.read_bytes()).encode() + b"\n")
    return h.hexdigest()


def recipe_source(picture: Picture) -> str:
    """What of the recipes makes the picture: its maker, the helpers every picture goes through, and
    its data."""
    parts = [inspect.getsource(picture.make), *(inspect.getsource(f) for f in COMMON),
             json.dumps(picture.args, sort_keys=True), repr(picture.assets), repr(picture.files)]
    return "\n".join(parts)


def inputs(picture: Picture) -> dict[str, str]:
    """Input name -> sha256, as pictures.json records them."""
    out = {f"trained/{a}": folder_digest(a) for a in picture.assets}
    for rel in picture.files:
        out[rel] = _sha256((ROOT / rel).read_bytes())
    if picture.readme_example:
        out["README.md: the first example"] = _sha256("\n".join(readme_example()).encode())
    # the record names a recipe by this script, which makes the pictures from docs/picture_recipes.py
    out[f"docs/make_pictures.py: {picture.name}"] = _sha256(recipe_source(picture).encode())
    return out


# --- the record ------------------------------------------------------------------------------------

def load_record() -> dict:
    return json.loads(RECORD.read_text()) if RECORD.is_file() else {}


def write_record(record: dict) -> None:
    text = json.dumps(dict(sorted(record.items())), indent=1) + "\n"
    tmp = RECORD.with_name(RECORD.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(RECORD)


def stale(picture: Picture, record: dict) -> list[str]:
    """Why the picture is not current: inputs that changed, a picture file that is not what was made."""
    entry = record.get(picture.name)
    if entry is None:
        return ["never made"]
    now = inputs(picture)
    why = [k for k in sorted(set(now) | set(entry["inputs"])) if now.get(k) != entry["inputs"].get(k)]
    path = PICTURES / picture.name
    if not path.is_file():
        why.append("the file is missing")
    elif _sha256(path.read_bytes()) != entry["sha256"]:
        why.append("the file is not the one made")
    return why


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*", help="pictures to make (paths under docs/pictures/; default: all)")
    ap.add_argument("--stale", action="store_true", help="only the pictures whose inputs changed since they were made")
    ap.add_argument("--list", action="store_true", help="list the pictures and what each is made from")
    ap.add_argument("--out", type=Path, help="write into this folder and leave docs/pictures.json as it is")
    args = ap.parse_args(argv)
    known = pictures()
    unknown = [n for n in args.names if n not in known]
    if unknown:
        print(f"make_pictures: no such picture: {', '.join(unknown)} (--list names them)", file=sys.stderr)
        return 2
    chosen = [known[n] for n in args.names] if args.names else list(known.values())
    record = load_record()
    if args.list:
        for p in chosen:
            why = stale(p, record)
            print(f"{p.name}: {p.shows}\n    from {', '.join(inputs(p))}; needs {p.needs}"
                  + (f"\n    stale: {'; '.join(why)}" if why else ""))
        return 0
    if args.stale:
        chosen = [p for p in chosen if stale(p, record)]
    out = args.out if args.out is not None else PICTURES
    start = time.perf_counter()
    failed = []
    for p in chosen:
        t = time.perf_counter()
        made_from = inputs(p)   # before drawing: an input changed meanwhile shows as stale
        try:
            image, renderer = p.make(p)
        except Exception as exc:   # noqa: BLE001 - one picture that cannot be made here (no Chromium, no Xvfb) stops no other
            failed.append(p.name)
            print(f"{p.name}: not made: {type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
            continue
        data = png_bytes(image)
        path = out / p.name
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_bytes(data)
        tmp.replace(path)
        if args.out is None:   # kept after each picture: a run cut short keeps what it made
            record[p.name] = {"shows": p.shows, "inputs": made_from, "sha256": _sha256(data),
                              "size": list(image.size), "renderer": renderer}
            write_record(record)
        print(f"{p.name}: {image.width}x{image.height}, {len(data) / 1024:.0f} KB, "
              f"{time.perf_counter() - t:.1f} s", flush=True)
    if args.out is None and not args.names and not args.stale and not failed:
        # a full run: pictures the script no longer makes go, with their records
        for name in [n for n in record if n not in known]:
            del record[name]
        write_record(record)
        for path in sorted(PICTURES.rglob("*.png")):
            if path.relative_to(PICTURES).as_posix() not in known:
                path.unlink()
    print(f"{len(chosen) - len(failed)} picture(s) in {time.perf_counter() - start:.0f} s"
          + (f"; not made: {', '.join(failed)}" if failed else ""), flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
