"""The trainer contract (inshade/trainer.py): typed settings and presets as data make the options,
the resolution (given option > preset > default), the recorded settings and the errors."""
from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

import pytest

from inshade.trainer import Run, Trainer, setting


@dataclass(frozen=True)
class Toy:
    source: str = setting(None, "what to fit", positional="SOURCE")
    steps: int = setting(100, "training steps")
    lr: float = setting(1e-2, "learning rate")
    width: int | None = setting(None, "hidden width (None: from the budget)")
    shape: str = setting("ring", "what to draw", choices=("ring", "disc"))
    lambdas: tuple[float, ...] = setting((0.0, 0.5), "weights to sweep")
    mips: bool = setting(True, "train with mips")


def _trainer(runs: list, **kw) -> Trainer:
    def train(run: Run) -> int:
        runs.append(run)
        run.write_metrics({"psnr": 30.0})
        return 0

    return Trainer("toy", "A toy trainer.\n\nMore.", Toy, {"quick": {}, "ship": {"steps": 900, "lr": 1e-3}},
                   train, folder=lambda s: f"toy_{s.source}", ship_assets={"toy_a": {"source": "a"}}, **kw)


def test_given_option_wins_over_preset_over_default(tmp_path):
    runs: list[Run] = []
    t = _trainer(runs)
    assert t.main(["x", "--preset", "ship", "--lr", "0.5", "--lambdas", "1", "2", "--no-mips",
                   "-o", str(tmp_path / "out"), "--device", "cpu"]) == 0
    s = runs[0].settings
    assert (s.steps, s.lr, s.lambdas, s.mips, s.width, s.shape) == (900, 0.5, (1.0, 2.0), False, None, "ring")
    record = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert record["preset"] == "ship" and record["psnr"] == 30.0
    assert record["command"].startswith("inshade train toy x --preset ship --lr 0.5")
    assert record["settings"] == {"source": "x", "steps": 900, "lr": 0.5, "width": None, "shape": "ring",
                                  "lambdas": [1.0, 2.0], "mips": False}


def test_preset_settings_is_what_the_preset_resolves_to():
    t = _trainer([])
    assert t.preset_settings("quick") == {"source": None, "steps": 100, "lr": 1e-2, "width": None, "shape": "ring",
                                          "lambdas": [0.0, 0.5], "mips": True}
    assert t.preset_settings("ship", "toy_a")["source"] == "a" and t.preset_settings("ship")["steps"] == 900
    args = t.add_arguments(argparse.ArgumentParser()).parse_args(["y", "--preset", "ship"])
    assert vars(t.resolve(args)) == {**t.preset_settings("ship"), "source": "y", "lambdas": (0.0, 0.5)}


def test_help_shows_each_presets_value():
    text = _trainer([]).add_arguments(argparse.ArgumentParser()).format_help()
    assert "quick: 100; ship: 900" in text and "default ring" in text and "--no-mips" in text


def test_bad_settings_and_refused_folders_are_one_line(tmp_path, capsys):
    def check(s):
        if s.steps < 1:
            raise ValueError("--steps must be >= 1")

    runs: list[Run] = []
    t = _trainer(runs, check=check, errors=(ValueError,))
    assert t.main(["x", "--steps", "0", "-o", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.strip() == "inshade: error: --steps must be >= 1"
    (tmp_path / "held").mkdir()
    (tmp_path / "held" / "bundle.json").write_text("{}")
    assert t.main(["x", "-o", str(tmp_path / "held"), "--device", "cpu"]) == 2
    assert "already holds an asset" in capsys.readouterr().err and runs == []
    with pytest.raises(SystemExit):
        t.main(["x", "--shape", "square"])


def test_a_preset_naming_an_unknown_setting_is_refused():
    with pytest.raises(TypeError, match="unknown settings"):
        Trainer("toy", None, Toy, {"quick": {"stepz": 1}}, lambda run: 0, folder=lambda s: "toy")


@dataclass(frozen=True)
class Shape:
    which: str = setting(None, "what to fit", choices=("ring", "disc"), positional="WHICH")
    steps: int = setting(None, "training steps")
    holes: int | None = setting(None, "holes in the disc", only={"which": ("disc",)})
    seed: int = setting(0, "random seed")


def _per_shape(runs: list) -> Trainer:
    """Presets per value of one setting, a setting of one value only, a folder named from an input option."""
    def train(run: Run) -> int:
        runs.append(run)
        run.write_metrics({})
        return 0

    return Trainer("shape", "A trainer of two recipes.", Shape,
                   {"ship": {"ring": {"steps": 900}, "disc": {"steps": 300, "holes": 2}},
                    "quick": {"ring": {"steps": 9}, "disc": {"steps": 3, "holes": 1}}},
                   train, folder=lambda s, args: f"shape_{s.which}_{args.tag}", default_preset="ship",
                   ship_assets={"shape_ring": {"which": "ring"}, "shape_disc": {"which": "disc"}},
                   extra_arguments=lambda p: p.add_argument("--tag", default="a"), preset_by="which")


def test_presets_per_value_record_only_the_settings_of_that_value(tmp_path):
    runs: list[Run] = []
    t = _per_shape(runs)
    assert t.main(["disc", "--steps", "5", "-o", str(tmp_path / "d"), "--device", "cpu"]) == 0
    assert t.main(["ring", "--preset", "quick", "-o", str(tmp_path / "r"), "--device", "cpu"]) == 0
    assert (runs[0].settings.steps, runs[0].settings.holes, runs[1].settings.holes) == (5, 2, None)
    def read(name):
        return json.loads((tmp_path / name / "metrics.json").read_text())["settings"]

    assert read("d") == {"which": "disc", "steps": 5, "holes": 2, "seed": 0}
    assert read("r") == {"which": "ring", "steps": 9, "seed": 0}
    assert t.preset_settings("ship", "shape_ring") == {"which": "ring", "steps": 900, "seed": 0}
    assert t.preset_settings("quick", "shape_disc") == {"which": "disc", "steps": 3, "holes": 1, "seed": 0}
    assert t.preset_settings("quick") == t.preset_settings("quick", "shape_ring")     # unset: the first value


def test_a_setting_given_for_another_value_is_one_line(tmp_path, capsys):
    runs: list[Run] = []
    assert _per_shape(runs).main(["ring", "--holes", "1", "-o", str(tmp_path / "o"), "--device", "cpu"]) == 2
    assert capsys.readouterr().err.strip() == "inshade: error: --holes: only with which disc" and runs == []


def test_per_value_help_and_a_folder_named_from_an_input_option(tmp_path, monkeypatch):
    runs: list[Run] = []
    t = _per_shape(runs)
    text = " ".join(t.add_arguments(argparse.ArgumentParser()).format_help().split())
    assert "(ship: 900, disc 300; quick: 9, disc 3)" in text
    assert "ship disc: 2; quick disc: 1" in text and "ship = ring: steps 900 / disc: steps 300, holes 2" in text
    monkeypatch.chdir(tmp_path)
    assert t.main(["ring", "--tag", "b", "--device", "cpu"]) == 0
    assert runs[0].out == Path("inshade-out/shape_ring_b")


def test_a_folder_holding_only_the_runs_checkpoint_is_resumed_not_refused(tmp_path):
    runs: list[Run] = []
    t = _trainer(runs, resume=("checkpoint.safetensors",))
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "checkpoint.safetensors").write_bytes(b"")
    assert t.main(["x", "-o", str(tmp_path / "out"), "--device", "cpu"]) == 0 and len(runs) == 1
    assert t.main(["x", "-o", str(tmp_path / "out"), "--device", "cpu"]) == 2      # now it holds an asset
