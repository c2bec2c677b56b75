"""The repository speaks the product's words: no talk of the process that made it (issues, notes
files it does not have) in code, reports or JSON keys, and no machine's own folders (a home
directory, a checkout's absolute path) in any committed file. Elsewhere, scratch paths under /tmp in
recorded commands are what the user typed and stay; the bench reports (docs/bench/) record portable
paths instead (``inshade.bench.harness.portable_path``): repository-relative, or ``<scratch>/NAME``
for a temporary folder of the machine that wrote them."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PROCESS_TALK = re.compile(r"\bthe issue\b|\bissue \d+\b|\bissue #\d+|\bmoonshot\b|\bnotes/\d{3}\.md\b", re.I)
MACHINE_PATH = re.compile(r"(?<![\w.])/(?:root|home/[\w.-]+|Users/[\w.-]+|work)/")
# a temporary folder: /tmp, macOS's per-user /var/folders, pytest's tmp_path
SCRATCH_PATH = re.compile(r"(?<![\w.])/(?:private/)?(?:tmp|var/folders)/|pytest-of-")
# outside a code span a page reads <scratch> as an HTML tag and shows nothing
BARE_PLACEHOLDER = re.compile(r"<scratch>")
TEXT = {".py", ".glsl", ".md", ".json", ".toml", ".txt", ".cfg", ".yaml", ".yml", ".sh", ""}


def tracked_text_files() -> list[Path]:
    out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    files = [ROOT / name for name in out.decode().split("\0") if name]
    return [f for f in files if f.suffix in TEXT and f.is_file() and f.name != Path(__file__).name]


def offending_lines(pattern: re.Pattern, files) -> list[str]:
    hits = []
    for f in files:
        try:
            text = f.read_text()
        except UnicodeDecodeError:
            continue
        for number, line in enumerate(text.splitlines(), 1):
            if pattern.search(line):
                hits.append(f"{f.relative_to(ROOT)}:{number}: {line.strip()[:120]}")
    return hits


@pytest.fixture(scope="module")
def files():
    found = tracked_text_files()
    assert len(found) > 100
    return found


def test_no_process_talk_in_code_reports_or_keys(files):
    assert not offending_lines(PROCESS_TALK, files)


def test_no_machine_paths_in_committed_files(files):
    assert not offending_lines(MACHINE_PATH, files)


def bench_reports(files) -> list[Path]:
    return [f for f in files if f.is_relative_to(ROOT / "docs" / "bench")]


def test_bench_reports_record_no_scratch_folder(files):
    reports = bench_reports(files)
    assert len(reports) > 20
    assert not offending_lines(SCRATCH_PATH, reports)


def test_bench_pages_show_placeholders_in_code(files):
    pages = [f for f in bench_reports(files) if f.suffix == ".md"]
    hits = [line for f in pages for number, line in enumerate(f.read_text().splitlines(), 1)
            if BARE_PLACEHOLDER.search(re.sub(r"`[^`]*`", "", line))]
    assert not hits


@pytest.mark.parametrize("line, talk, path", [
    ("# the issue's target for the march", True, False),
    ("Target (issue 17): >= 35 dB", True, False),
    ('"moonshot": {', True, False),
    ("(Walloner 2024, notes/003.md §2)", True, False),
    ('"command": "x --cache=/root/.cache/inshade/transfer"', False, True),
    ("Mesh: `/work/main/trained/prt_mesh/mesh.ply`", False, True),
    ("--out /home/someone/out", False, True),
    ("the GL commands fn issues, in seconds", False, False),
    ("inshade train prt --sdf /tmp/plants.json --out /tmp/prt_plants", False, False),
    ("python -m inshade.techniques.prt.transfer_net --out=trained/prt_creature/transfer", False, False),
])
def test_the_patterns_find_what_they_mean(line, talk, path):
    assert bool(PROCESS_TALK.search(line)) == talk
    assert bool(MACHINE_PATH.search(line)) == path


@pytest.mark.parametrize("line, scratch", [
    ('  "origin": "asset /tmp/di_assets/di_footprint",', True),
    ("- mesh: `/tmp/inshade_mesh/bunny.ply` (22610 faces)", True),
    ('"folder": "/private/tmp/uvf/uvfree_material_fruit_balanced_u8"', True),
    ("`inshade train di_texture skimage:retina -o /var/folders/x7/T/rd/di_texture_retina_12x`", True),
    ('"asset": "/home/me/pytest-of-me/pytest-3/test_bench0/asset"', True),
    ('  "origin": "asset `<scratch>/di_footprint`",', False),
    ('"folder": "trained/uvfree_material_fruit_balanced"', False),
    ("`inshade train di_texture skimage:retina -o <scratch>/di_texture_retina_12x`", False),
    ('"image": "skimage.data.astronaut", "note": "writes to a tmp/ folder"', False),
])
def test_the_scratch_pattern_finds_temporary_folders(line, scratch):
    assert bool(SCRATCH_PATH.search(line)) == scratch


def test_reports_record_portable_paths(tmp_path, monkeypatch):
    from inshade.bench.harness import REPOSITORY, portable_command, portable_path

    assert portable_path("/tmp/di_assets/di_footprint") == "<scratch>/di_footprint"
    assert portable_path("/tmp/inshade_mesh/bunny.ply/") == "<scratch>/bunny.ply"
    assert portable_path(tmp_path / "out") == "<scratch>/out"
    assert portable_path(REPOSITORY / "trained" / "di_footprint") == "trained/di_footprint"
    assert portable_path(REPOSITORY / "trained" / "x" / ".." / "di_sdf") == "trained/di_sdf"
    monkeypatch.chdir(REPOSITORY)
    assert portable_path("trained/di_footprint") == "trained/di_footprint"
    monkeypatch.chdir(tmp_path)   # a relative path is where it points from the working folder
    assert portable_path("trained/di_footprint") == "<scratch>/di_footprint"
    link = tmp_path / "checkout"
    link.symlink_to(REPOSITORY)
    assert portable_path(link / "docs" / "bench") == "docs/bench"

    typed = "inshade train di_texture skimage:retina --size 1024 --ratio 12 --preset ship -o {}"
    assert portable_command(typed.format("/tmp/me/rd/di_texture_retina_12x")) == \
        typed.format("<scratch>/di_texture_retina_12x")   # only the path changes
    assert portable_command(typed.format("trained/di_texture_retina_12x")) == typed.format("trained/di_texture_retina_12x")
    assert portable_command(f"x --out={REPOSITORY}/trained/a --cache '/tmp/my cache/t' (/tmp/z)") == \
        "x --out=trained/a --cache '<scratch>/t' (<scratch>/z)"
    assert portable_command("see https://example.com/a, 3/4 of it") == "see https://example.com/a, 3/4 of it"
    assert portable_command(None) is None
