"""The repository speaks the product's words: no talk of the process that made it (issues, notes
files it does not have) in code, reports or JSON keys, and no machine's own folders (a home
directory, a checkout's absolute path) in any committed file. Scratch paths under /tmp in recorded
commands are what the user typed and stay."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PROCESS_TALK = re.compile(r"\bthe issue\b|\bissue \d+\b|\bissue #\d+|\bmoonshot\b|\bnotes/\d{3}\.md\b", re.I)
MACHINE_PATH = re.compile(r"(?<![\w.])/(?:root|home/[\w.-]+|Users/[\w.-]+|work)/")
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
