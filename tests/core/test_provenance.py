"""Provenance that is true: every command a shipped asset records (metrics.json, bundle.json) is a
command today's CLI takes, with options today's parsers accept (a renamed trainer or option shows
here, not when a user tries to rebuild an asset)."""
from __future__ import annotations

import argparse
import importlib
import json
import shlex
from pathlib import Path

import pytest

from inshade.cli import aliases, trainers

ROOT = Path(__file__).resolve().parents[2]


def _commands():
    found = {}

    def walk(value, where):
        if isinstance(value, dict):
            for k, v in value.items():
                if k == "command" and isinstance(v, str):
                    found.setdefault(v, where)
                else:
                    walk(v, where)
        elif isinstance(value, list):
            for v in value:
                walk(v, where)

    for path in sorted((ROOT / "trained").rglob("*.json")):
        if path.name in ("metrics.json", "bundle.json"):
            walk(json.loads(path.read_text()), str(path.relative_to(ROOT)))
    return sorted(found.items(), key=lambda kv: kv[1])


COMMANDS = _commands()


def test_there_are_commands_to_check():
    assert len(COMMANDS) >= 20


@pytest.mark.parametrize("command, where", COMMANDS, ids=[w for _, w in COMMANDS])
def test_recorded_command_parses_with_todays_cli(command, where):
    argv = shlex.split(command)
    if argv[:2] == ["python", "-m"]:
        module, rest = argv[2], argv[3:]
    else:
        assert argv[0] == "inshade", f"{where}: {command}"
        words = argv[1:]
        if words[0] in aliases():
            words = [*aliases()[words[0]], *words[1:]]
        assert words[0] == "train" and words[1] in trainers(), f"{where}: no command `inshade {' '.join(words[:2])}`"
        module, rest = trainers()[words[1]][0], words[2:]
    parser = argparse.ArgumentParser(prog=module)
    importlib.import_module(module).add_arguments(parser)
    try:
        parser.parse_args(rest)
    except SystemExit:
        pytest.fail(f"{where}: `{command}` no longer parses with {module}")
