"""`inshade bench suite`: every registered bench declares its suite entry (sizes per preset that
parse with the bench's own options, claims, headline rows), the suite names no bench, the renderer
slug, a tiny suite (one real bench, fakes for the rest) that writes its summary, a failing bench
recorded without stopping the suite, and a plug-in technique's bench sized, run and summarised from
its own folder."""
import argparse
import importlib
import json
import os
import re
import shutil
import sys
import time
from pathlib import Path

import pytest

from inshade import technique
from inshade.bench import suite
from inshade.bench.entry import PRESETS, Sizing, SuiteEntry
from inshade.cli import main as cli_main

REPO = Path(__file__).resolve().parents[2]
PLUGINS = Path(__file__).resolve().parents[1] / "plugins"
FAKE_GL = {"vendor": "Test", "renderer": "Fake GPU 9000/PCIe/SSE2", "version": "4.5", "glsl_version": "4.50",
           "software": False}


def test_slug_of_renderer_strings():
    assert suite.slug("llvmpipe (LLVM 15.0.6, 256 bits)") == "llvmpipe-llvm-15-0-6-256-bits"
    assert suite.slug("NVIDIA H200/PCIe/SSE2") == "nvidia-h200"
    assert suite.slug("Mesa Intel(R) UHD Graphics 620 (KBL GT2)") == "mesa-intel-r-uhd-graphics-620-kbl-gt2"
    assert suite.slug(" /x") == "unknown-renderer"


def test_every_registered_bench_declares_its_suite_entry():
    # a technique registered with a bench whose module declares no SUITE (sizes for both presets,
    # claims, a headline parser) fails this
    names = set(suite.registered())
    assert "suite" not in names and "mlp" in names
    for name, module in suite.registered().items():
        found = suite.entry(name)
        assert isinstance(found, SuiteEntry), f"{module} must declare SUITE = SuiteEntry(...)"
        assert set(found.sizes) == set(PRESETS), name
        assert all(s.budget_s > 0 for s in found.sizes.values()), name
        assert found.claims, name
    assert suite.entry("nope") is None


def test_suite_names_no_bench():
    # each bench's sizes, claims and headline parser live in its own module, its paper in its record
    text = (REPO / "bench" / "suite.py").read_text()
    names = {t.name for t in technique.techniques()} | set(suite.registered())
    found = sorted(n for n in names if re.search(rf"\b{re.escape(n)}\b", text))
    assert not found, f"bench/suite.py names {found}"


def test_a_suite_entry_checks_its_sizes():
    with pytest.raises(ValueError, match="unknown preset 'gpu'"):
        SuiteEntry(sizes={"gpu": Sizing((), 1)}, headlines=lambda r: [])
    with pytest.raises(ValueError, match="budget > 0"):
        SuiteEntry(sizes={"cpu": Sizing((), 0)}, headlines=lambda r: [])


def test_device_preset_fits_its_minutes():
    total = sum(suite.entry(name).sizes["device"].budget_s for name in suite.registered())
    assert total <= 60 * suite.DEVICE_MINUTES, total


@pytest.mark.parametrize("preset", suite.PRESETS)
def test_preset_command_lines_parse_with_each_bench(preset):
    # an option a bench renamed or dropped shows here, not half way through a GPU run
    for name, module in suite.registered().items():
        parser = argparse.ArgumentParser(prog=name)
        importlib.import_module(module).add_arguments(parser)
        args = parser.parse_args([*suite.entry(name).sizes[preset].argv, "--out", "x"])
        assert args.out == "x", name


REPORTS = sorted([REPO / "docs" / "bench" / f"{name}.json" for name in suite.registered()]
                 + [p for p in (REPO / "docs" / "bench").glob("*/*.json") if p.stem in suite.registered()])


@pytest.mark.parametrize("path", REPORTS, ids=lambda p: str(p.relative_to(REPO / "docs" / "bench")))
def test_headlines_read_each_committed_report(path):
    # docs/bench/NAME.json is the last full run of each bench, docs/bench/<renderer>/ the suite's
    # runs: the summary must read every schema they show
    rows = suite.headlines(path.stem, json.loads(path.read_text()))
    assert rows, path
    for row in rows:
        assert not row["ours"].startswith("could not read"), row["ours"]
        assert row["measure"] and row["paper"], row
        if row["ours_over_paper"] is not None:
            assert row["ours_over_paper"] > 0


def test_a_headline_from_a_json_of_another_shape_is_a_row_not_a_crash():
    rows = suite.headlines("prt", {"frames": "not a list"})
    assert len(rows) == 1 and rows[0]["ours"].startswith("could not read prt.json: TypeError")


def _fake_bench(stem, source=None):
    """A bench main that writes ``stem.json`` (a copy of a committed report, or a bare record)."""
    def main(argv):
        out = Path(argv[argv.index("--out") + 1])
        text = source.read_text() if source else json.dumps({"machine": {}})
        (out / f"{stem}.json").write_text(text)
        return 0
    return main


def test_tiny_suite_writes_the_summary_and_records_failures(tmp_path, gl, capsys):
    from inshade.bench import mlp
    from inshade.runtime.context import gl_info

    def broken(argv):
        raise RuntimeError("driver lost\nsecond line")

    def refuses(argv):
        print("inshade: error: --assets: trained/x: not an asset", file=sys.stderr)
        return 2

    def silent(argv):
        return 0

    plan = {"mlp": Sizing(("--quick",), 60),
            "di_brdf": Sizing((), 5),
            "prt": Sizing((), 5),
            "di_sdf": Sizing(("--frames", "1"), 5),
            "neural_appearance": Sizing((), 5),
            "newcomer": None}
    mains = {"mlp": mlp.main, "di_brdf": _fake_bench("di_brdf", REPO / "docs/bench/di_brdf.json"),
             "prt": broken, "di_sdf": refuses, "neural_appearance": silent}
    out = tmp_path / "suite"
    result = suite.run_suite(out, plan, mains, preset="test", gl=gl_info(gl), log=lambda text: None)

    status = {b["name"]: (b["status"], b["error"]) for b in result["benches"]}
    assert status["mlp"] == ("ok", None) and status["di_brdf"] == ("ok", None)
    assert status["prt"] == ("failed", "RuntimeError: driver lost second line")
    assert status["di_sdf"] == ("failed", "--assets: trained/x: not an asset")
    assert status["neural_appearance"] == ("failed", "exited 0 but wrote no neural_appearance.json")
    assert status["newcomer"][0] == "not run" and "no 'test' sizing" in status["newcomer"][1]
    assert "RuntimeError: driver lost" in capsys.readouterr().err   # the traceback is shown

    for name in ("summary.json", "summary.md", "summary.png", "mlp.json", "mlp.md", "mlp.png"):
        assert (out / name).stat().st_size > 0, name
    saved = json.loads((out / "summary.json").read_text())
    assert saved["machine"]["gl_renderer"] == gl_info(gl)["renderer"] and saved["preset"] == "test"
    assert saved["budget_s"] == 80 and saved["seconds"] > 0
    assert {h["bench"] for h in saved["headlines"]} == {"mlp", "di_brdf"}
    disney = next(h for h in saved["headlines"] if h["bench"] == "di_brdf")
    assert disney["paper_value"] == pytest.approx(0.742 / 0.255)
    mlp_bench = next(b for b in saved["benches"] if b["name"] == "mlp")
    # the summary records the folder as any machine would type it (a scratch folder by its name)
    assert mlp_bench["argv"] == ["--quick", "--out", f"<scratch>/{out.name}"] and mlp_bench["json"] == "mlp.json"

    md = (out / "summary.md").read_text()
    assert md.splitlines()[2] == f"**GL_RENDERER: `{gl_info(gl)['renderer']}`**"
    assert "| prt | failed |" in md and "RuntimeError: driver lost second line" in md
    assert "0.742 / 0.255 ms: 2.9x" in md and "[mlp.md](mlp.md)" in md
    assert "`inshade bench di_sdf --frames 1`" in md


def test_a_report_left_by_an_earlier_run_is_not_taken_for_this_one(tmp_path):
    (tmp_path / "di_brdf.json").write_text(json.dumps({"machine": {}}))
    past = time.time() - 3600
    os.utime(tmp_path / "di_brdf.json", (past, past))
    record = suite.run_bench("di_brdf", lambda argv: 0, ["--out", str(tmp_path)], tmp_path)
    assert (record["status"], record["error"]) == ("failed", "exited 0 but wrote no di_brdf.json")


def test_an_option_the_bench_rejects_is_its_error_line(tmp_path):
    from inshade.techniques.di_brdf import bench

    record = suite.run_bench("di_brdf", bench.main, ["--rounds", "many", "--out", str(tmp_path)], tmp_path)
    assert record["status"] == "failed"
    assert "argument --rounds: invalid int value: 'many'" in record["error"]


def test_summary_names_the_renderer_and_the_budget(tmp_path):
    plan = {"di_brdf": Sizing((), 1)}
    shutil.copy(REPO / "docs/bench/di_brdf.json", tmp_path / "source.json")
    result = suite.run_suite(tmp_path, plan, {"di_brdf": _fake_bench("di_brdf", tmp_path / "source.json")},
                             preset="device", gl=FAKE_GL, log=lambda text: None)
    md = suite.markdown(result)
    assert "**GL_RENDERER: `Fake GPU 9000/PCIe/SSE2`**" in md and "preset `device`" in md
    assert "(budget 1 s)" in md


def test_command_line(capsys):
    assert cli_main(["bench", "suite", "--preset", "device", "--dry-run"]) == 0
    out = capsys.readouterr().out
    for name in suite.registered():
        assert f"inshade bench {name} " in out
    assert "in all" in out

    assert cli_main(["bench", "suite", "--preset", "cpu", "--only", "mlp,nope"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("inshade: error: --only: unknown bench nope (known: mlp, ") and "\n" not in err

    with pytest.raises(SystemExit) as exc:
        cli_main(["bench", "suite", "--preset", "gpu"])
    assert exc.value.code == 2


def test_a_ratio_without_finite_bounds_reads_as_unknown():
    # the harness stores a non-finite per-round bound as None (few rounds, a base as slow as the variant)
    row = {"filter": "fast", "lights": 4, "analytic_minus_base_ms": 2.6, "learned_minus_base_ms": 2.8,
           "speedup": {"median": 1.2, "low": None, "high": None, "verdict": "no difference"}}
    rows = suite.headlines("di_brdf", {"size": 256, "models": {"disney": {"rows": [row]}}})
    assert rows[0]["ours"].startswith("1.20x (?-?, no difference)") and rows[0]["ours_value"] == 1.2


@pytest.fixture
def toy_rings(monkeypatch):
    """The toy_rings plug-in (tests/plugins/toy_rings: record, trainer, bench), registered for one test."""
    monkeypatch.syspath_prepend(str(PLUGINS))
    toy = importlib.import_module("toy_rings")
    technique.register(toy.TECHNIQUE)
    yield toy
    technique.unregister("toy_rings")


def test_a_plug_in_bench_is_planned_run_and_summarised_from_its_folder(toy_rings, tmp_path, gl, capsys):
    from toy_rings import bench

    assert suite.entry("toy_rings") is bench.SUITE
    assert suite.plan_for("cpu", ["toy_rings"]) == {"toy_rings": bench.SUITE.sizes["cpu"]}
    assert cli_main(["bench", "suite", "--preset", "device", "--dry-run"]) == 0
    assert "inshade bench toy_rings --size 256" in capsys.readouterr().out

    out = tmp_path / "suite"
    assert cli_main(["bench", "suite", "--preset", "cpu", "--only", "toy_rings", "--out", str(out)]) == 0
    saved = json.loads((out / "summary.json").read_text())
    assert [(b["name"], b["status"], b["argv"]) for b in saved["benches"]] == [
        ("toy_rings", "ok", ["--size", "16", "--repeats", "2", "--out", f"<scratch>/{out.name}"])]
    [row] = saved["headlines"]
    assert row["bench"] == "toy_rings" and row["paper_says"] == "a million pixels a second"
    assert row["ours_over_paper"] == pytest.approx(row["ours_value"] / 1e6)
    md = (out / "summary.md").read_text()
    assert "Sine rings, a toy (inshade tests)" in md and "`inshade bench toy_rings --size 16 --repeats 2`" in md
