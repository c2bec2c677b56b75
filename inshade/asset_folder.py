"""Where a trainer writes its asset: ``--out DIR``, else ``./inshade-out/<technique>_<name>``.

A trainer never writes into a folder that already holds files (a shipped asset under ``trained/``,
an earlier run, anything of the user's) unless ``--force`` says to: the check runs before any
work, so a refused run costs nothing and leaves everything as it was. A trainer that resumes from
its own checkpoint names that file in ``resume``: a folder holding only it is an unfinished run,
not an asset.

    asset_folder.add_arguments(parser, "neural_image_<image>")
    out = asset_folder.claim(args.out, f"neural_image_{args.image}", force=args.force)
"""
from __future__ import annotations

import argparse
from pathlib import Path

ROOT = Path("inshade-out")   # relative: the folder a trainer run from here writes into


class OutputExistsError(ValueError):
    """The asset folder already holds files and ``--force`` was not given."""


def default(name: str) -> Path:
    """The folder a trainer writes ``name`` into when no ``--out`` is given."""
    return ROOT / name


def add_arguments(parser: argparse.ArgumentParser, name: str) -> None:
    """``-o/--out DIR`` (default ``./inshade-out/<name>``) and ``--force``."""
    # %(default).0s prints nothing: it only keeps ArgumentDefaultsHelpFormatter from adding "(default: None)"
    parser.add_argument("-o", "--out", metavar="DIR",
                        help=f"asset folder to write (default: {default(name)}); a folder that already "
                             "holds files is refused unless --force%(default).0s")
    parser.add_argument("--force", action="store_true",
                        help="write into --out even if it already holds an asset (its files are replaced)%(default).0s")


def claim(out, name: str, *, force: bool = False, resume: tuple[str, ...] = (), option: str = "--out",
          force_option: str = "--force") -> Path:
    """The folder to write: ``out``, or ``default(name)`` when ``out`` is empty. Raises
    ``OutputExistsError`` when it holds files (other than ``resume``) and ``force`` is false;
    ``option`` / ``force_option`` name the caller's spelling of the two in the message."""
    folder = Path(out) if out else default(name)
    if folder.exists() and not folder.is_dir():
        raise OutputExistsError(f"{folder}: {option}: is a file, expected an asset folder")
    held = sorted(p.name for p in folder.iterdir() if p.name not in resume) if folder.is_dir() else []
    if held and not force:
        shown = ", ".join(held[:3]) + (f" and {len(held) - 3} more" if len(held) > 3 else "")
        raise OutputExistsError(f"{folder}: {option}: already holds an asset ({shown}); choose another {option}, "
                                f"or pass {force_option} to write over it")
    return folder
