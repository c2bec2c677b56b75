"""Package architecture: the torch-free side stays torch-free, and imports between the project's
modules form no cycle, neither at module load nor through function bodies.

- torch-free: the runtime, the scene model, geometry sources, codegen, the shader library, the viewer app, the technique registry
  (with every technique's record imported) and the CLI's parser are imported in a fresh
  interpreter, which must not have imported torch. On failure every entry point is imported
  alone in its own interpreter and the message names each one that pulls torch, with the
  project frames of the import chain that reached it.
- no import cycle: the graph of imports executed at module load (top level, class bodies,
  top-level if/try/with; not function bodies nor ``if TYPE_CHECKING:``) over every .py of the
  packages in pyproject.toml's ``package-dir``, with relative imports resolved; then the graph of
  every import, function bodies included.
"""
from __future__ import annotations

import ast
import json
import subprocess
import sys
import textwrap
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pytest depends on tomli below 3.11
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]


def _package_dirs() -> dict[str, Path]:
    """Top-level package name -> folder, from pyproject.toml (inshade.codegen = codegen, ...)."""
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    return {pkg: ROOT / folder for pkg, folder in meta["tool"]["setuptools"]["package-dir"].items()}


def _module_files() -> dict[str, Path]:
    """Every project module name -> its file. A folder mapped to a package (e.g. techniques/ ->
    inshade.techniques) is walked whole; folders mapped to subpackages of it are not walked twice."""
    dirs = _package_dirs()
    out: dict[str, Path] = {}
    for pkg, folder in dirs.items():
        nested = [d for p, d in dirs.items() if p != pkg and d != folder and folder in d.parents]
        for path in sorted(folder.rglob("*.py")):
            if "__pycache__" in path.parts or any(n in path.parents for n in nested):
                continue
            parts = list(path.relative_to(folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join([pkg, *parts])] = path
    return out


# --- torch-free -------------------------------------------------------------------------------

def _torch_free_steps() -> list[str]:
    """Python statements, each one entry point; run in order in one interpreter."""
    files = _module_files()
    steps = ["import inshade", "import inshade; inshade.export; inshade.check", "import inshade.runtime"]
    steps += [f"import {m}" for m in sorted(files) if m.startswith("inshade.runtime.")]
    steps += ["import inshade.scene"]
    steps += [f"import {m}" for m in sorted(files) if m.startswith("inshade.scene.")]
    steps += ["import inshade.geometry"]
    steps += [f"import {m}" for m in sorted(files) if m.startswith("inshade.geometry.")]
    steps += ["import inshade.codegen"]
    steps += [f"import {m}" for m in sorted(files) if m.startswith("inshade.codegen.")]
    steps += ["import inshade.shaders"]
    steps += [f"import {m}" for m in sorted(files) if m.startswith("inshade.shaders.")]
    steps += ["import inshade.viewer.app",
              "import inshade.technique",
              "import inshade.technique; assert inshade.technique.techniques()",
              "import inshade.cli",
              "import inshade.cli; inshade.cli.build_parser()"]
    return steps


# Runs `steps` (argv[1], JSON); prints JSON: the first step after which torch is loaded, and the
# project frames (file:line) on the stack when torch was first looked up.
_PROBE = textwrap.dedent('''
    import json, sys, traceback
    root = sys.argv[2]
    chain = []

    class Spy:
        def find_spec(self, name, path=None, target=None):
            if (name == "torch" or name.startswith("torch.")) and not chain:
                chain.extend(f"{f.filename[len(root) + 1:]}:{f.lineno} {f.line}"
                             for f in traceback.extract_stack()[:-1]
                             if f.filename.startswith(root + "/") and "<frozen" not in f.filename)
                chain.append(name)
            return None

    sys.meta_path.insert(0, Spy())
    culprit = "<interpreter startup>" if "torch" in sys.modules else None
    for step in json.loads(sys.argv[1]) if culprit is None else []:
        exec(step, {})
        if "torch" in sys.modules:
            culprit = step
            break
    print(json.dumps({"culprit": culprit, "chain": chain}))
''')


def _probe(steps: list[str]) -> dict:
    proc = subprocess.run([sys.executable, "-c", _PROBE, json.dumps(steps), str(ROOT)],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 0, f"importing {steps} failed:\n{proc.stdout}{proc.stderr}"
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_torch_free_imports():
    steps = _torch_free_steps()
    assert any(s.startswith("import inshade.runtime.") for s in steps)  # the glob found the runtime
    result = _probe(steps)
    if result["culprit"] is None:
        return
    # name every entry point that pulls torch on its own, with its import chain
    report = []
    for step in steps:
        alone = _probe([step])
        if alone["culprit"] is not None:
            report.append(f"{step!r} imports torch via:\n    " + "\n    ".join(alone["chain"]))
    raise AssertionError("torch was imported by the torch-free side:\n" + "\n".join(report or [
        f"(only in combination) first after {result['culprit']!r}, via:\n    " + "\n    ".join(result["chain"])]))


def test_runtime_never_imports_onnx():
    """ONNX import is an optional extra (inshade convert): the runtime, codegen and CLI parser do
    not load onnx or onnxruntime."""
    steps = [s for s in _torch_free_steps()]
    code = ("import json, sys\n" + "\n".join(f"exec({s!r}, {{}})" for s in steps) +
            "\nprint(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in ('onnx', 'onnxruntime'))))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == []


# --- import cycles ----------------------------------------------------------------------------

def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or \
        (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _load_time_imports(tree: ast.Module):
    """Import statements executed when the module is imported (not in function bodies, not
    under ``if TYPE_CHECKING:``)."""
    todo = list(tree.body)
    while todo:
        node = todo.pop(0)
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            continue
        elif isinstance(node, ast.If) and _is_type_checking(node.test):
            todo.extend(node.orelse)
        elif isinstance(node, ast.stmt):
            todo.extend(c for c in ast.iter_child_nodes(node) if isinstance(c, (ast.stmt, ast.ExceptHandler,
                                                                               ast.match_case)))
        elif isinstance(node, (ast.ExceptHandler, ast.match_case)):
            todo.extend(node.body)


def _ancestors(module: str) -> list[str]:
    parts = module.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


def _every_import(tree: ast.Module):
    """Every import statement of the module, function bodies included (what runs when it is called)."""
    return (n for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom)))


def import_graph(files: dict[str, Path], root: Path = ROOT, *, function_bodies: bool = False) -> dict[str, dict[str, str]]:
    """module -> {imported project module: 'file:line'}. Importing a.b.c also runs a and a.b,
    so those are edges too, except the importer's own ancestors (already initialised first).
    ``function_bodies``: the imports inside functions too (a circle there is one a reader follows)."""
    graph: dict[str, dict[str, str]] = {m: {} for m in files}
    imports = _every_import if function_bodies else _load_time_imports
    for module, path in files.items():
        is_package = path.name == "__init__.py"
        own = set(_ancestors(module)) | {module}
        for node in imports(ast.parse(path.read_text(), str(path))):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                if node.level:
                    base = module.split(".")
                    if not is_package:
                        base = base[:-1]
                    base = base[:len(base) - (node.level - 1)]
                    base_name = ".".join(base + ([node.module] if node.module else []))
                else:
                    base_name = node.module
                targets = [base_name] + [f"{base_name}.{a.name}" for a in node.names]
            where = f"{path.relative_to(root)}:{node.lineno}"
            for target in targets:
                for t in [*_ancestors(target), target]:
                    if t in files and t not in own:
                        graph[module].setdefault(t, where)
    return graph


def find_cycles(graph: dict[str, dict[str, str]]) -> list[list[str]]:
    """One cycle (as a closed path [a, b, ..., a]) per strongly connected component that has one."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def strongconnect(v):  # Tarjan, iterative
        work = [(v, iter(sorted(graph.get(v, ()))))]
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        while work:
            node, edges = work[-1]
            for w in edges:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                    break
                if w in on_stack:
                    low[node] = min(low[node], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == node:
                            break
                    components.append(comp)

    for v in sorted(graph):
        if v not in index:
            strongconnect(v)

    cycles = []
    for comp in components:
        members = set(comp)
        start = min(comp)
        if len(comp) == 1 and start not in graph.get(start, {}):
            continue
        # breadth-first from start back to start, inside the component: a shortest cycle
        parent: dict[str, str] = {}
        frontier = [start]
        while frontier and start not in parent:
            nxt = []
            for u in frontier:
                for w in sorted(graph[u]):
                    if w in members and w not in parent:
                        parent[w] = u
                        nxt.append(w)
            frontier = nxt
        path = [start]
        while True:
            path.append(parent[path[-1]])
            if path[-1] == start:
                break
        cycles.append(path[::-1])
    return cycles


def _describe(cycle: list[str], graph) -> str:
    return " -> ".join(cycle) + "\n      " + "\n      ".join(
        f"{a} -> {b} at {graph[a][b]}" for a, b in zip(cycle, cycle[1:]))


def test_cycle_finder_finds_cycles():
    """The detector itself: a cycle, a self-import and an acyclic diamond."""
    g = {"a": {"b": "x"}, "b": {"c": "x"}, "c": {"a": "x", "d": "x"}, "d": {}, "e": {"e": "x"},
         "f": {"g": "x", "h": "x"}, "g": {"i": "x"}, "h": {"i": "x"}, "i": {}}
    assert sorted(map(tuple, find_cycles(g))) == [("a", "b", "c", "a"), ("e", "e")]
    assert find_cycles({k: v for k, v in g.items() if k in "fghi"}) == []


def test_import_graph_resolves_relative_and_package_imports(tmp_path):
    (tmp_path / "p" / "q").mkdir(parents=True)
    sources = {
        "p/__init__.py": "from .a import x\n",
        "p/a.py": "from . import b\nimport typing\nif typing.TYPE_CHECKING:\n    from p import c\n"
                  "def f():\n    from p import c\n",
        "p/b.py": "from .q.r import y\ntry:\n    import p.c\nexcept ImportError:\n    pass\n",
        "p/c.py": "class K:\n    from . import a\n",
        "p/q/__init__.py": "",
        "p/q/r.py": "from .. import a\n",
    }
    files = {}
    for rel, text in sources.items():
        (tmp_path / rel).write_text(text)
        parts = rel[:-3].split("/")
        files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = tmp_path / rel
    graph = import_graph(files, tmp_path)
    assert {m: sorted(e) for m, e in graph.items()} == {
        "p": ["p.a"], "p.a": ["p.b"], "p.b": ["p.c", "p.q", "p.q.r"], "p.c": ["p.a"],
        "p.q": [], "p.q.r": ["p.a"]}
    assert ["p.a", "p.b", "p.c", "p.a"] in find_cycles(graph)
    every = import_graph(files, tmp_path, function_bodies=True)
    assert sorted(every["p.a"]) == ["p.b", "p.c"]   # the function body's and the TYPE_CHECKING import


def test_no_import_cycles():
    files = _module_files()
    dirs = _package_dirs()
    for pkg in dirs:  # every mapped folder contributed modules
        assert any(m == pkg or m.startswith(pkg + ".") for m in files), f"no modules found for {pkg}"
    graph = import_graph(files)
    assert sum(map(len, graph.values())) > len(files) // 2, "suspiciously few imports: parsing broke?"
    cycles = find_cycles(graph)
    assert not cycles, "import cycles between the project's modules (module-level imports):\n  " + \
        "\n  ".join(_describe(c, graph) for c in cycles)


def test_no_import_cycles_through_function_bodies():
    """The same with every import, function bodies included: a lazy import keeps start-up light, it
    does not make a circle of modules any easier to read."""
    graph = import_graph(_module_files(), function_bodies=True)
    cycles = find_cycles(graph)
    assert not cycles, "import cycles between the project's modules (function bodies included):\n  " + \
        "\n  ".join(_describe(c, graph) for c in cycles)


# --- sizes ---------------------------------------------------------------------------------

MAX_FILE_LINES, MAX_FUNCTION_LINES = 500, 100
# generated tables that may be longer, each with what generates it (none today)
GENERATED: dict[str, str] = {}


def test_files_and_functions_fit_on_a_few_screens():
    """No project module over 500 lines, no function over 100: a file has one concern, a function
    one step, each readable whole."""
    long_files, long_functions = [], []
    paths = [*_module_files().values(), *sorted((ROOT / "docs").glob("*.py")), ROOT / "setup.py"]
    assert len(paths) > 200
    for path in paths:
        rel = str(path.relative_to(ROOT))
        if rel in GENERATED:
            continue
        source = path.read_text()
        if len(source.splitlines()) > MAX_FILE_LINES:
            long_files.append(f"{rel}: {len(source.splitlines())} lines")
        for node in ast.walk(ast.parse(source, rel)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    long_functions.append(f"{rel}:{node.lineno}: {node.name} {length} lines")
    assert not long_files and not long_functions, "\n".join(long_files + long_functions)
