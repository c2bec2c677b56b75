"""Layers you can see: every import in the project's code -- at module level, inside functions,
and ``importlib.import_module("...")`` with a literal name -- goes down the stack, never up or
sideways:

- no technique imports another technique (what two share lives in a shared layer: ``models/``
  for torch, ``shaders/lib`` for GLSL, the runtime for GL);
- the shared layers import only what is below them (``LAYER_RULES``), the core (``CORE``: modules
  of inshade/ itself) none of them, the technique registry only the shader library; the few stated
  exceptions are data with their reason (``ALLOWED``).
"""
from __future__ import annotations

import ast
from pathlib import Path

from test_architecture import ROOT, _module_files

TECHNIQUES = "inshade.techniques"
# Layer -> the layers it must not import. The CLI (inshade.cli), the conversion front end
# (inshade.convert), the engines' drop-ins (inshade.engines), the benches (inshade.bench) and the
# techniques sit on top and may import any shared layer.
ABOVE_SHARED = ("inshade.techniques", "inshade.viewer", "inshade.bench", "inshade.convert", "inshade.cli",
                "inshade.commands", "inshade.engines")
LAYER_RULES = {
    "inshade.shaders": ("inshade.codegen", "inshade.models", "inshade.runtime", "inshade.scene", "inshade.geometry",
                        "inshade.technique", *ABOVE_SHARED),
    "inshade.geometry": ("inshade.codegen", "inshade.models", "inshade.runtime", "inshade.scene", *ABOVE_SHARED),
    "inshade.codegen": ("inshade.models", "inshade.runtime", "inshade.scene", *ABOVE_SHARED),
    "inshade.scene": ("inshade.models", "inshade.runtime", *ABOVE_SHARED),      # the GL-free scene model
    "inshade.models": ("inshade.runtime", "inshade.scene", *ABOVE_SHARED),
    "inshade.runtime": ("inshade.models", *ABOVE_SHARED),
    "inshade.viewer": ("inshade.models", "inshade.techniques", "inshade.bench", "inshade.convert", "inshade.cli",
                       "inshade.commands"),
}
# The core (inshade/*.py: the bundle, the component specs, SH math, files, the trainer's command shell)
# sits below every folder; the registry of techniques sits on the shader library; the apps on top.
SHARED = ("inshade.shaders", "inshade.geometry", "inshade.codegen", "inshade.scene", "inshade.models",
          "inshade.runtime", "inshade.web")
REGISTRY = ("inshade.technique", "inshade.papers", "inshade.trainer")
APPS = ("inshade.cli", "inshade.commands", "inshade.notebook")
CORE = ("inshade.asset_folder", "inshade.bundle", "inshade.command", "inshade.components", "inshade.devices",
        "inshade.envelope", "inshade.envelope_base",
        "inshade.extras", "inshade.files", "inshade.grid_layout", "inshade.json_header", "inshade.lit_settings",
        "inshade.metrics", "inshade.pixels", "inshade.port_layout", "inshade.progress", "inshade.provenance",
        "inshade.quantize",
        "inshade.random", "inshade.sh")
LAYER_RULES.update({m: (*SHARED, *REGISTRY, *APPS, *ABOVE_SHARED) for m in CORE})
LAYER_RULES.update({m: (*[s for s in SHARED if s != "inshade.shaders"], *APPS, *ABOVE_SHARED) for m in REGISTRY})
# (importing file, imported module) -> why this edge is allowed.
ALLOWED: dict[tuple[str, str], str] = {
    ("inshade/technique.py", "inshade.techniques"):
        "the registry imports the built-in technique records by name, as it loads plug-in folders",
}


def imports(module: str, path: Path):
    """(imported module, line) for every import in the file, wherever it sits."""
    is_package = path.name == "__init__.py"
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            yield from ((a.name, node.lineno) for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")[:None if is_package else -1]
                base = base[:len(base) - (node.level - 1)]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = node.module
            yield name, node.lineno
            yield from ((f"{name}.{a.name}", node.lineno) for a in node.names)
        elif (isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant)
              and isinstance(node.args[0].value, str)
              and getattr(node.func, "attr", getattr(node.func, "id", None)) in ("import_module", "__import__")):
            yield node.args[0].value, node.lineno


def _within(name: str, package: str) -> bool:
    return name == package or name.startswith(package + ".")


def technique_of(module: str) -> str | None:
    parts = module.split(".")
    return ".".join(parts[:3]) if _within(module, TECHNIQUES) and len(parts) > 2 else None


def cross_technique_imports(files: dict[str, Path]) -> list[str]:
    found = []
    for module, path in files.items():
        own = technique_of(module)
        if own is None:
            continue
        for name, line in imports(module, path):
            other = technique_of(name)
            if other is not None and other != own:
                found.append(f"{path.relative_to(ROOT)}:{line}: {own.split('.')[-1]} imports {name}")
    return sorted(set(found))


# A component folder (components/<name>/) holds one module per concern; each sits in its concern's layer
# (the rest of the folder -- spec, envelope rule -- in the core). A concern too long for one module is split
# into <concern module>_<part>.py modules beside it (dense's emit_plan.py), checked in the same layer.
CONCERN_LAYERS = {"torch_twin": "inshade.models", "emit": "inshade.codegen", "lowering": "inshade.convert"}


def layer_of(module: str) -> str:
    parts = module.split(".")
    if _within(module, "inshade.components") and len(parts) == 4:
        for concern, layer in CONCERN_LAYERS.items():
            if parts[3] == concern or parts[3].startswith(concern + "_"):
                return layer
    return module


def layer_violations(files: dict[str, Path]) -> list[str]:
    found = []
    for module, path in files.items():
        for layer, forbidden in LAYER_RULES.items():
            if not _within(layer_of(module), layer):
                continue
            for name, line in imports(module, path):
                rel = str(path.relative_to(ROOT))
                if any(_within(name, f) for f in forbidden) and not any(
                        f == rel and _within(name, m) for f, m in ALLOWED):
                    found.append(f"{rel}:{line}: {layer} imports {name}")
    return sorted(set(found))


def test_no_technique_imports_another():
    files = _module_files()
    assert sum(technique_of(m) is not None for m in files) > 50     # the walk found the techniques
    found = cross_technique_imports(files)
    assert not found, "a technique imports another (share it through models/, shaders/lib or the runtime):\n" \
        + "\n".join(found)


def test_shared_layers_import_only_below_them():
    found = layer_violations(_module_files())
    assert not found, "an import goes up or across the layers:\n" + "\n".join(found)


def test_allowed_edges_still_exist():
    """An exception nobody needs any more is removed, not kept as a loophole."""
    files = {str(p.relative_to(ROOT)): (m, p) for m, p in _module_files().items()}
    for rel, name in ALLOWED:
        module, path = files[rel]
        assert any(_within(n, name) for n, _ in imports(module, path)), f"{rel} no longer imports {name}"


def test_checks_see_imports_inside_functions(tmp_path):
    """The walk catches what a module-level scan would miss: imports in function bodies, relative
    imports and import_module with a literal name."""
    tech = tmp_path / "techniques" / "alpha"
    tech.mkdir(parents=True)
    (tech / "train.py").write_text(
        "def f():\n    from inshade.techniques.beta import train\n"
        "def g():\n    from ..gamma import bench\n"
        "def h():\n    import importlib\n    importlib.import_module('inshade.techniques.delta.model')\n")
    models = tmp_path / "models"
    models.mkdir()
    (models / "thing.py").write_text("def f():\n    from inshade.runtime.context import shared_context\n")
    files = {"inshade.techniques.alpha.train": tech / "train.py", "inshade.models.thing": models / "thing.py"}
    global ROOT
    saved, ROOT = ROOT, tmp_path
    try:
        cross = cross_technique_imports(files)
        layers = layer_violations(files)
    finally:
        ROOT = saved
    assert {c.split(": ", 1)[1] for c in cross} == {
        "alpha imports inshade.techniques.beta", "alpha imports inshade.techniques.beta.train",
        "alpha imports inshade.techniques.delta.model", "alpha imports inshade.techniques.gamma",
        "alpha imports inshade.techniques.gamma.bench"}
    assert layers == ["models/thing.py:2: inshade.models imports inshade.runtime.context",
                      "models/thing.py:2: inshade.models imports inshade.runtime.context.shared_context"]


def test_every_core_module_has_a_layer():
    """A new module of inshade/ itself is placed in the core, the registry or the apps, so its imports
    are checked."""
    top = {m for m in _module_files() if m.count(".") == 1 and m.startswith("inshade.")}
    folders = {"inshade." + f for f in ("bench", "codegen", "convert", "engines", "geometry", "models", "runtime",
                                        "scene", "shaders", "techniques", "viewer", "web")}
    assert top - folders == set(CORE) | set(REGISTRY) | set(APPS)
