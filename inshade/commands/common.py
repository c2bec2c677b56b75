"""What every command shares: the error a user can fix, the parser class that reports a bad
command line in one line, option types, output checks, and assets and settings as given."""
from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

STDOUT = "-"   # -o -: standard output, where the format allows


class UserError(Exception):
    """Input the user can fix; reported in one line with exit status 2."""


class ArgumentParser(argparse.ArgumentParser):
    """argparse, but a bad command line is one `inshade: error: ...` line (exit 2), not a usage dump."""

    def error(self, message):
        command = self.prog.split(" ", 1)[1] + ": " if " " in self.prog else ""
        self.exit(2, f"inshade: error: {command}{' '.join(message.split())}\n")


def int_at_least(minimum: int, not_int: str, too_small: str):
    """An argparse type: an int >= ``minimum``; the messages end with ``, got VALUE``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{not_int}, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{too_small}, got {value}")
        return value
    return parse


count = int_at_least(1, "must be an integer", "must be >= 1")   # --spp, --calls


def image_size(text: str) -> int:
    """--width/--height: an int in 1..MAX_SIZE."""
    from inshade.scene.description import MAX_SIZE

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    if not 1 <= value <= MAX_SIZE:
        raise argparse.ArgumentTypeError(f"must be in 1..{MAX_SIZE}, got {value}")
    return value


def check_output(path, option: str = "-o") -> Path:
    """Refuse an output path that cannot be written, before any work: its folder (or the first
    existing folder above it) must be a writable folder, and the path itself not a folder."""
    path = Path(path)
    if path.is_dir():
        raise UserError(f"{path}: {option}: is a folder, expected a file path")
    parent = path.parent
    while not parent.exists():
        if parent.is_symlink():
            raise UserError(f"{path}: {option}: {parent} is a dangling link")
        parent = parent.parent
    if not parent.is_dir():
        raise UserError(f"{path}: {option}: {parent} is a file, not a folder")
    if parent == path.parent:   # try exactly what the writer will do: a temporary file beside it
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".probe", dir=parent)
        except OSError as e:
            raise UserError(f"{path}: {option}: cannot write in {parent} ({e.strerror or e})") from None
        os.close(fd)
        os.unlink(tmp)
    elif not os.access(parent, os.W_OK | os.X_OK):
        raise UserError(f"{path}: {option}: cannot create folders in {parent} (not writable)")
    return path


def one_line(text: str) -> str:
    """A message as one line: its lines joined with '; ' (e.g. a shader compiler's log)."""
    return "; ".join(line.strip() for line in text.splitlines() if line.strip())


def write_error(path, e: OSError) -> UserError:
    """The error of a write that failed, naming the file that failed (one of a group, maybe)."""
    return UserError(f"{e.filename or path}: cannot write ({e.strerror or e})")


def user_errors():
    from inshade.bundle import BundleError
    from inshade.components import ComponentError
    from inshade.shaders import ShaderCompileError, ShaderIncludeError
    from inshade.runtime.context import GLContextError
    return (UserError, BundleError, ComponentError, ShaderCompileError, ShaderIncludeError,
            GLContextError, ValueError)


def resolve(name_or_path) -> Path:
    """An asset path, or a bare name looked up in trained/ and $INSHADE_ASSETS (scene/description.py)."""
    from inshade.scene.description import resolve_asset

    return resolve_asset(name_or_path)


def asset_networks(src: Path):
    """(scene, [(role, prefix, bundle path)]) of an asset with a scene.json (its networks, then a
    network SDF), or (None, []) for a bare bundle."""
    from inshade.scene.description import NetworkSdfRef, is_scene, load_scene

    if not is_scene(src):
        return None, []
    scene = load_scene(src)
    nets = [("network", n.prefix, n.bundle) for n in scene.networks]
    if isinstance(scene.sdf, NetworkSdfRef):
        nets.append(("network SDF", scene.sdf.prefix, scene.sdf.bundle))
    return scene, nets


def scene_settings(args) -> dict:
    """Scene settings the user gave: --storage, --lut-filter and --set NAME=VALUE (VALUE parsed
    as JSON when it is JSON, else kept as a string); the scene's defaults fill in the rest."""
    settings = {}
    if args.storage is not None:
        settings["storage"] = args.storage
    if args.lut_filter is not None:
        settings["lut_filter"] = args.lut_filter
    for item in args.set or []:
        name, sep, text = item.partition("=")
        if not sep or not name:
            raise UserError(f"{args.command}: --set expects NAME=VALUE, got {item!r}")
        if name in settings:
            raise UserError(f"{args.command}: --set {name}: given more than once (or also by its own option)")
        try:
            settings[name] = json.loads(text)
        except ValueError:
            settings[name] = text
    return settings
