"""The docs' generated pages, written from the code's own registries at every build so that they
cannot fall behind it.

mkdocs runs this file through the gen-files plugin (mkdocs.yml): the component reference from the
component folders (`components/`) and the emitters' codegen options, the command-line
reference from the argparse parsers (`inshade/cli.py` and every trainer's and bench's own), the
operations each source lowers (`inshade convert --ops`), the shipped assets (their `scene.json`
settings, `metrics.json` recipes and previews) and the list of benchmark records under
`docs/bench/`. A page that exists by hand (its prose) gets the generated part appended.

`python docs/gen_reference.py OUT` writes the same pages into the folder OUT, to read them.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import inspect
import json
import os
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
TRAINED = ROOT / "trained"
# argparse wraps help to the terminal's width; a fixed one keeps the pages the same on every machine
HELP_COLUMNS = "100"
CATEGORIES = (("layer", "Layers"), ("activation", "Elementwise functions"), ("encoding", "Encodings"),
              ("lookup", "Lookups"))


def _where(obj) -> str:
    """The repository file that defines obj, as a path from the root."""
    try:
        return Path(inspect.getsourcefile(obj)).resolve().relative_to(ROOT).as_posix()
    except (TypeError, ValueError):
        return "?"


def _text(text: str) -> str:
    """Plain text as markdown: formulas (`x * scale`, `n_freqs`, `[x]`) stay as written, code spans
    are kept."""
    parts = str(text).split("`")
    for i in range(0, len(parts), 2):
        parts[i] = re.sub(r"([*_\\[\]])", r"\\\1", parts[i])
    return "`".join(parts)


def _cell(text: str) -> str:
    return _text(text).replace("|", "\\|").replace("\n", " ")


def _value(v) -> str:
    if v is ...:
        return "required"
    if v is None:
        return "absent"
    return f"`{json.dumps(v)}`"


def _kind(kind) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    return " or ".join(k.__name__ for k in kinds)


# --- components ------------------------------------------------------------------------------

def torch_twins() -> dict:
    """type -> torch class, where torch is installed (the reference runs without it)."""
    try:
        import inshade.models  # noqa: F401  (registers the classes)
        from inshade.models.registry import TORCH_COMPONENTS
    except ImportError:
        return {}
    return dict(TORCH_COMPONENTS)


def component_reference() -> str:
    from inshade.codegen.registry import EMITTERS, OPTIONS
    from inshade.components import COMPONENTS, registry

    twins = torch_twins()
    out = ["", "## Every component type", "",
           f"{len(COMPONENTS)} types, grouped by what they do. *Parameters* go in a node's `params`; "
           "*codegen options* are chosen when GLSL is generated (`generate(bundle, options=...)`, or the "
           "`inshade codegen` / `render` flags) and never change the bundle.", ""]
    for category, title in CATEGORIES:
        names = [t for t, s in COMPONENTS.items() if s.category == category]
        if not names:
            continue
        out += [f"### {title}", ""]
        for t in names:
            spec = COMPONENTS[t]
            out += [f"#### `{t}`", "", _text(spec.doc.strip()), ""]
            if spec.params:
                out += ["| parameter | type | default | must be |", "|---|---|---|---|"]
                for name, p in spec.params.items():
                    out.append(f"| `{name}` | {_kind(p.kind)} | {_value(p.default)} | {_cell(p.doc)} |")
                out.append("")
            for name, (choices, default) in OPTIONS.get(t, {}).items():
                listed = " \\| ".join(f"`{c}`" for c in choices)
                out.append(f"- codegen option `{t}.{name}`: {listed} (default `{default}`)")
            spec_module = sys.modules[registry.defined_where("spec", t)]
            files = [f"spec: `{_where(spec_module)}`"]
            files.append(f"GLSL: `{_where(EMITTERS[t])}`" if t in EMITTERS else "GLSL: none")
            if t in twins:
                files.insert(1, f"torch: `{_where(twins[t])}`")
            out += [f"- {', '.join(files)}", ""]
    unknown = sorted({s.category for s in COMPONENTS.values()} - {c for c, _ in CATEGORIES})
    if unknown:   # a new category must get a heading here, not vanish from the page
        raise SystemExit(f"gen_reference: no heading for component categories {unknown}")
    return "\n".join(out) + "\n"


# --- the command line -----------------------------------------------------------------------

def _help(parser: argparse.ArgumentParser) -> str:
    return parser.format_help().rstrip()


def _block(text: str) -> list[str]:
    return ["```text", text, "```", ""]


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """name -> parser of every subcommand of `parser` (argparse keeps them in its subparsers action)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def command_helps() -> dict[str, str]:
    """command -> its one-line help, as `inshade --help` lists it."""
    from inshade.cli import build_parser

    for action in build_parser()._actions:
        if isinstance(action, argparse._SubParsersAction):
            return {a.dest: a.help or "" for a in action._choices_actions}
    return {}


def _module_help(kind: str, name: str, module: str, text: str) -> list[str]:
    """`inshade KIND NAME --help`, built from the module's own parser; a module whose optional
    extra is missing here is named instead of failing the build."""
    try:
        mod = importlib.import_module(module)
    except ModuleNotFoundError as e:
        if (e.name or "inshade").startswith("inshade"):
            raise
        return [f"*Options not listed: `{e.name}` is not installed where this page was built "
                f"(`inshade {kind} {name} --help` lists them).*", ""]
    parser = argparse.ArgumentParser(prog=f"inshade {kind} {name}", description=text)
    mod.add_arguments(parser)
    return _block(_help(parser))


@contextlib.contextmanager
def _columns(width: str):
    before = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = width
    try:
        yield
    finally:
        if before is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = before


def cli_reference() -> str:
    with _columns(HELP_COLUMNS):
        return _cli_reference()


def _cli_reference() -> str:
    from inshade.cli import benches, build_parser, trainers

    top = build_parser()
    helps = command_helps()
    out = ["", "## Every command's options", "",
           "The help each command prints (`inshade COMMAND --help`), as this version has it.", "",
           "### `inshade`", "", *_block(_help(top))]
    tables = {"train": trainers(), "bench": benches()}
    for name, parser in subcommands(top).items():
        out += [f"### `inshade {name}`", "", helps.get(name, ""), ""]
        if name in tables:
            out += _block(_help(parser))
            for target, (module, text) in tables[name].items():
                out += [f"#### `inshade {name} {target}`", "", text, ""]
                out += _module_help(name, target, module, text)
        else:
            out += _block(_help(parser))
    return "\n".join(out) + "\n"


def ops_reference() -> str:
    from inshade.convert.commands import ops_text

    return "\n".join(["", "## The full list", "", "`inshade convert --ops` prints:", "",
                      *_block(ops_text().rstrip())])


# --- shipped assets ---------------------------------------------------------------------------

def technique_of(folder: str, names) -> str | None:
    found = [n for n in names if folder == n or folder.startswith(n + "_")]
    return max(found, key=len) if found else None


def _settings_table(scene) -> list[str]:
    rows = ["| setting | shown as | values | default |", "|---|---|---|---|"]
    for s in scene.settings.values():
        if s.type == "choice":
            values = " \\| ".join(f"`{c}`" for c in s.choices)
        elif s.type == "bool":
            values = "`true` \\| `false`"
        else:
            values = f"{s.min:g} .. {s.max:g}"
        label = _cell(s.label) if s.label and s.label != s.name else ""
        rows.append(f"| `{s.name}` | {label} | {values} | `{json.dumps(s.default)}` |")
    return rows + [""]


def assets_reference(copy) -> str:
    """The shipped assets, one section each; copy(src, dest) puts a preview into the site."""
    from inshade import technique
    from inshade.scene.description import load_scene

    names = [t.name for t in technique.techniques()]
    out = ["", f"{sum(1 for d in TRAINED.iterdir() if (d / 'scene.json').is_file())} assets under `trained/`, "
           "each drawn with `inshade render NAME -o x.png` and opened with `inshade view NAME`. "
           "Settings are given as `--set NAME=VALUE` (`inshade info NAME` lists them too); "
           "the recipe is the command recorded in the asset's `metrics.json`.", ""]
    for folder in sorted(d for d in TRAINED.iterdir() if (d / "scene.json").is_file()):
        scene = load_scene(folder)
        tech = technique_of(folder.name, names)
        out += [f"## `{folder.name}`", "", _cell(scene.title or folder.name), ""]
        if tech:
            out += [f"Technique: [`{tech}`](../techniques/{tech}.md)", ""]
        for png in sorted((DOCS / "pictures" / "assets" / folder.name).glob("preview*.png")):   # made by docs/make_pictures.py
            dest = f"reference/previews/{folder.name}{png.stem[len('preview'):]}.png"
            copy(png, dest)
            out.append(f"![{folder.name} {png.stem}](previews/{Path(dest).name}){{ loading=lazy width=256 }}")
        out.append("")
        metrics = folder / "metrics.json"
        recipe = json.loads(metrics.read_text()) if metrics.is_file() else {}
        if recipe.get("command"):
            out += ["```bash", recipe["command"], "```", ""]
        seconds = recipe.get("train_seconds")
        if isinstance(seconds, (int, float)):
            threads = recipe.get("train_threads")
            on = f" on {threads} CPU thread{'s' if threads != 1 else ''}" if isinstance(threads, int) else ""
            out += [f"Training took {seconds:.0f} s{on} (`metrics.json`: `train_seconds`).", ""]
        out += _settings_table(scene)
    return "\n".join(out) + "\n"


# --- benchmark records ------------------------------------------------------------------------

def bench_records() -> str:
    out = ["", "## Every record", "",
           "Written by `inshade bench NAME --out docs/bench` (JSON + this markdown + a plot):", "",
           "| record | title |", "|---|---|"]
    for md in sorted((DOCS / "bench").rglob("*.md")):
        rel = md.relative_to(DOCS).as_posix()
        first = md.read_text().splitlines()[0] if md.read_text().strip() else ""
        title = re.sub(r"^#+\s*", "", first) or md.stem
        out.append(f"| [{rel[len('bench/'):]}]({rel}) | {_cell(title)} |")
    return "\n".join(out) + "\n"


# --- writing ------------------------------------------------------------------------------------

def pages(copy) -> dict[str, str]:
    """docs path -> generated markdown (appended to the hand-written page of that path, if any)."""
    return {"reference/components.md": component_reference(),
            "reference/cli.md": cli_reference(),
            "reference/ops.md": ops_reference(),
            "reference/assets.md": assets_reference(copy),
            "benchmarks.md": bench_records()}


def write(open_) -> None:
    def copy(src: Path, dest: str) -> None:
        with open_(dest, "wb") as f:
            f.write(src.read_bytes())

    for path, text in pages(copy).items():
        with open_(path, "a") as f:
            f.write(text)


def _folder_opener(out: Path):
    def open_(path: str, mode: str):
        target = out / path
        target.parent.mkdir(parents=True, exist_ok=True)
        if mode == "a" and not target.exists() and (DOCS / path).is_file():
            target.write_text((DOCS / path).read_text())
        return open(target, mode)
    return open_


if __name__ == "<run_path>":   # run by mkdocs-gen-files during a build
    import mkdocs_gen_files

    write(mkdocs_gen_files.open)
elif __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python docs/gen_reference.py OUT")
    write(_folder_opener(Path(sys.argv[1])))
