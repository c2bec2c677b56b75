"""The bench contract (inshade.bench.contract): options made from a settings dataclass with their help
as written, --quick as data (overriding, or filling only what was left at its default), a suite
preset's command line from its values, and the one-line error of a bench option."""
from __future__ import annotations

import argparse
from dataclasses import dataclass

import pytest

from inshade.bench.contract import Bench, clock_option, option, sized
from inshade.bench.harness import BenchError


def _ints(text: str) -> list[int]:
    return [int(v) for v in text.split(",")]


@dataclass
class Settings:
    out: str = option("bench-out/toy", "output folder (default %(default)s)")
    size: int = option(64, "side")
    widths: list[int] = option((16, 32), "hidden widths", parse=_ints)
    scales: tuple[int, ...] | None = option(None, "scales", nargs="*")
    quick: bool = option(False, "tiny run")
    clock: str = clock_option("wall")


def _bench(**kw) -> Bench:
    def run(s):
        if s.size < 1:
            raise BenchError("--size: must be >= 1")
        seen.append(s)
        return 0

    seen = []
    bench = Bench("toy", "`inshade bench toy`: a toy.", Settings, run, **kw)
    return bench, seen


def test_options_keep_their_help_defaults_and_types():
    bench, _ = _bench()
    parser = bench.add_arguments(argparse.ArgumentParser())
    args = parser.parse_args(["--widths", "8,4", "--scales", "3", "4"])
    assert args.widths == [8, 4] and args.scales == [3, 4] and args.size == 64 and args.clock == "wall"
    assert parser.parse_args([]).widths == [16, 32]
    assert "output folder (default bench-out/toy)" in " ".join(parser.format_help().split())
    with pytest.raises(SystemExit):
        parser.parse_args(["--clock", "sundial"])


def test_quick_overrides_or_fills_the_defaults_only():
    bench, seen = _bench(quick={"size": 8, "widths": [4]})
    assert bench.main(["--quick", "--size", "32"]) == 0
    assert seen[-1].size == 8 and seen[-1].widths == [4]
    bench, seen = _bench(quick={"size": 8, "widths": [4]}, quick_keeps_given=True)
    assert bench.main(["--quick", "--size", "32"]) == 0
    assert seen[-1].size == 32 and seen[-1].widths == [4]
    assert bench.main(["--size", "32"]) == 0 and seen[-1].widths == [16, 32]


def test_a_suite_preset_is_its_command_line():
    bench, _ = _bench(sizes={"cpu": sized(5, size=16, widths=[8, 16], scales=(3, 4), quick=True), "device": sized(9)},
                      headlines=lambda r: [])
    entry = bench.suite
    assert entry.sizes["cpu"].argv == ("--size", "16", "--widths", "8,16", "--scales", "3", "4", "--quick")
    assert entry.sizes["device"].argv == () and entry.sizes["device"].budget_s == 9
    parsed = bench.add_arguments(argparse.ArgumentParser()).parse_args(entry.sizes["cpu"].argv)
    assert parsed.widths == [8, 16] and parsed.scales == [3, 4] and parsed.quick


def test_unknown_settings_and_presets_are_refused():
    with pytest.raises(TypeError, match="quick sets unknown settings"):
        _bench(quick={"nope": 1})
    with pytest.raises(TypeError, match="unknown presets"):
        _bench(sizes={"gpu": sized(1)})


def test_a_bench_error_is_one_line(capsys):
    bench, _ = _bench()
    assert bench.main(["--size", "0"]) == 2
    assert capsys.readouterr().err.strip() == "inshade: error: --size: must be >= 1"
