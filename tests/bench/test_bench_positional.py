"""A bench's positional setting (``option(..., positional=NAME)``): shown under its name in --help,
argparse's empty list when left off, and written as bare words in a suite preset's command line."""
from __future__ import annotations

import argparse
from dataclasses import dataclass

from inshade.bench.contract import Bench, option, sized


@dataclass
class Settings:
    assets: list[str] = option((), "asset folders", positional="ASSET", nargs="*")
    out: str = option("bench-out/toy", "output folder")


def _bench() -> tuple[Bench, list]:
    seen: list = []
    bench = Bench("toy", "`inshade bench toy`: a toy.", Settings, seen.append, headlines=lambda r: [],
                  sizes={"cpu": sized(5, assets=("trained/a", "trained/b"))})
    return bench, seen


def test_a_positional_setting_parses_and_shows_under_its_name():
    bench, seen = _bench()
    assert bench.main(["x", "y", "--out", "o"]) == 0 and seen[-1] == Settings(["x", "y"], "o")
    assert bench.main([]) == 0 and seen[-1].assets == []
    text = bench.add_arguments(argparse.ArgumentParser(prog="toy")).format_usage()
    assert "[--out OUT] [ASSET ...]" in text


def test_a_positional_setting_is_bare_words_in_the_suite_command_line():
    bench, _ = _bench()
    assert bench.suite.sizes["cpu"].argv == ("trained/a", "trained/b")
    assert bench.argv({"out": "o", "assets": ["a"]}) == ("--out", "o", "a")
