"""The docs site: its reference pages are generated from the registries (docs/gen_reference.py),
so a component or a command without its description fails here, and so does a technique without
its page; the site builds with `mkdocs build --strict` (broken links and missing pages fail); the
README's links point at files that exist."""
from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


@pytest.fixture(scope="module")
def gen():
    spec = importlib.util.spec_from_file_location("gen_reference", DOCS / "gen_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def cli_page(gen):
    return gen.cli_reference()


def test_every_component_has_a_description():
    from inshade.components import COMPONENTS

    assert not [t for t, spec in COMPONENTS.items() if not spec.doc.strip()]


def test_every_component_is_in_the_reference(gen):
    from inshade.components import COMPONENTS

    page = gen.component_reference()
    missing = [t for t in COMPONENTS if f"#### `{t}`" not in page]
    assert not missing, f"not in the component reference: {missing}"
    for t, spec in COMPONENTS.items():   # each section says what the type does, not just its name
        assert gen._text(spec.doc.strip()) in page


def test_every_command_has_help(gen):
    from inshade.cli import benches, build_parser, trainers

    helps = gen.command_helps()
    commands = gen.subcommands(build_parser())
    assert set(helps) == set(commands)
    assert not [c for c in commands if not helps[c].strip()], "commands without a help line"
    for kind, table in (("train", trainers()), ("bench", benches())):
        assert not [n for n, (_, text) in table.items() if not (text or "").strip()], f"{kind} targets without help"


def test_every_command_is_in_the_cli_reference(gen, cli_page):
    from inshade.cli import benches, build_parser, trainers

    missing = [c for c in gen.subcommands(build_parser())
               if f"### `inshade {c}`" not in cli_page or f"usage: inshade {c}" not in cli_page]
    for kind, table in (("train", trainers()), ("bench", benches())):
        missing += [f"{kind} {n}" for n in table if f"usage: inshade {kind} {n}" not in cli_page]
    assert not missing, f"not in the CLI reference (or without their options): {missing}"


def test_the_cli_reference_does_not_depend_on_the_terminal(gen, cli_page, monkeypatch):
    monkeypatch.setenv("COLUMNS", "60")
    assert gen.cli_reference() == cli_page


def test_every_technique_has_a_page_in_the_nav():
    from inshade import techniques

    nav = (ROOT / "mkdocs.yml").read_text()
    # the built-in ones (another test file may have registered a plug-in in this process)
    missing = [name for name in techniques.BUILTIN
               if not (DOCS / "techniques" / f"{name}.md").is_file() or f"techniques/{name}.md" not in nav]
    assert not missing, f"techniques without a page in docs/techniques/ and mkdocs.yml's nav: {missing}"


def test_every_shipped_asset_is_in_the_assets_page(gen):
    page = gen.assets_reference(lambda src, dest: None)
    folders = [d.name for d in (ROOT / "trained").iterdir() if (d / "scene.json").is_file()]
    assert folders and not [f for f in folders if f"## `{f}`" not in page]


def test_readme_links_resolve():
    readme = (ROOT / "README.md").read_text()
    targets = re.findall(r"\]\(([^)#\s]+)[^)]*\)", readme) + re.findall(r'<img src="([^"]+)"', readme)
    local = [t for t in targets if not re.match(r"^[a-z]+:", t)]
    assert local and not [t for t in local if not (ROOT / t).exists()]


def test_readme_is_a_landing_page():
    assert len((ROOT / "README.md").read_text().splitlines()) <= 150


def test_site_builds_strict(tmp_path):
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1", DISABLE_MKDOCS_2_WARNING="true")
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet", "-d", str(tmp_path / "site")],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    assert (tmp_path / "site" / "reference" / "components" / "index.html").is_file()
    assert (tmp_path / "site" / "reference" / "cli" / "index.html").is_file()
