"""The one registry of component types: every concern of a type -- its spec, torch twin, GLSL
emitter, envelope rule and lowerings -- is filed here under the type's name, once.

A component folder (``components/<name>/``, or a plug-in folder given to ``register_folder`` or
named in ``INSHADE_COMPONENTS``) holds one module per concern, each registering what it defines
with its layer's decorator:

    spec.py        the bundle-level description (``inshade.components.spec.register``)
    torch_twin.py  the torch reference (``inshade.models.registry.register``)
    emit.py        the GLSL emitter (``inshade.codegen.registry.emitter``) and its chunks, *.glsl
    envelope.py    the parity envelope's rule (``inshade.envelope_base.rule``)
    lowering.py    what torch ops, ONNX ops and tiny-cuda-nn otypes become this component

A concern too long for one module is split into ``<module>_<part>.py`` modules beside it (the dense
layer's emit.py over emit_plan.py, emit_products.py and emit_layer_loop.py), which its module imports
and which sit in the same layer.

A folder's module for a concern is imported the first time that concern is asked for, so code
that never trains (the GL runtime) never imports a torch twin. A name registered twice for one
concern is an error naming both places.
"""
from __future__ import annotations

import importlib
import os
import sys
from pathlib import Path

PLUGINS_ENV = "INSHADE_COMPONENTS"
BUILTIN_ROOT = Path(__file__).resolve().parent
# concern -> the module that holds it in a component folder
CONCERNS = {"spec": "spec", "torch": "torch_twin", "glsl": "emit", "envelope": "envelope", "lowering": "lowering"}


class RegistryError(ValueError):
    """A component folder or registration that cannot be taken."""


_TABLES: dict[str, dict[str, object]] = {c: {} for c in CONCERNS}
_WHERE: dict[tuple[str, str], str] = {}
_FOLDERS: dict[str, Path] = {}          # package name -> folder, in registration order
_LOADED: set[tuple[str, str]] = set()   # (concern, package) imported
_plugins_read = False


def add(concern: str, name: str, obj, where: str | None = None) -> None:
    """File ``obj`` as ``name``'s ``concern``. The same definition again (a module reloaded) is
    taken; another one is refused. ``where``: what defined it (default: a function's or class's
    qualified name)."""
    table = _TABLES[concern]
    where = where or f"{obj.__module__}.{obj.__qualname__}"
    if name in table and _WHERE[concern, name] != where:
        raise RegistryError(f"component {name!r}: {concern} registered twice ({_WHERE[concern, name]} and {where})")
    table[name] = obj
    _WHERE[concern, name] = where


def add_folder(package: str, folder: Path) -> None:
    """A component folder importable as ``package``; its concerns load when asked for."""
    folder = Path(folder).resolve()
    if package in _FOLDERS and _FOLDERS[package] != folder:
        raise RegistryError(f"component folder {package!r} registered twice ({_FOLDERS[package]} and {folder})")
    _FOLDERS[package] = folder
    for concern, loaded_package in list(_LOADED):
        if loaded_package == "*":
            _import(concern, package, folder)


def register_folder(folder) -> str:
    """A plug-in component folder (a package: ``__init__.py`` and its concern modules), importable
    by its name from its parent folder. Returns the package name."""
    folder = Path(folder).resolve()
    if not (folder / "__init__.py").is_file():
        raise RegistryError(f"{PLUGINS_ENV}: {folder}: not a component folder (no __init__.py)")
    if str(folder.parent) not in sys.path:
        sys.path.insert(0, str(folder.parent))
    add_folder(folder.name, folder)
    return folder.name


def _read_plugins() -> None:
    global _plugins_read
    if not _plugins_read:
        _plugins_read = True
        for folder in filter(None, os.environ.get(PLUGINS_ENV, "").split(os.pathsep)):
            register_folder(folder)


def _import(concern: str, package: str, folder: Path) -> None:
    if (concern, package) in _LOADED:
        return
    _LOADED.add((concern, package))
    if (folder / f"{CONCERNS[concern]}.py").is_file():
        importlib.import_module(f"{package}.{CONCERNS[concern]}")


def load(concern: str) -> None:
    """Import every registered folder's module for ``concern`` (each once)."""
    _read_plugins()
    _LOADED.add((concern, "*"))
    for package, folder in list(_FOLDERS.items()):
        _import(concern, package, folder)


def table(concern: str) -> dict[str, object]:
    """name -> what is registered for ``concern``, every folder's module for it loaded."""
    load(concern)
    return _TABLES[concern]


def folders() -> dict[str, Path]:
    """package name -> folder of every registered component folder."""
    _read_plugins()
    return dict(_FOLDERS)


def chunk_roots() -> list[Path]:
    """The folders whose component subfolders hold GLSL chunks: a folder's chunk ``x.glsl`` is
    ``#include``d as ``<folder name>/x``."""
    return list(dict.fromkeys(folder.parent for folder in folders().values()))


def entries(concern: str) -> dict[str, object]:
    """The live table of ``concern`` as filled so far (no folder loaded): for the layer that owns it."""
    return _TABLES[concern]


def defined_where(concern: str, name: str) -> str:
    """The module (and name) that registered ``name``'s ``concern``."""
    return _WHERE[concern, name]
