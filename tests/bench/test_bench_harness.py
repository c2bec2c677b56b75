"""inshade.bench.harness: A/B verdicts from interleaved rounds, atomic reports, the machine record,
the clocks. Synthetic clocks make the timing tests deterministic (no speed is ever asserted)."""
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from inshade.bench import harness
from inshade.bench.harness import Ratio, Timing, compare, interleave, measure, paired_ratio, write_report


class FakeClock:
    """Each variant returns the seconds it "took"; the clock reports that."""

    name = "fake"
    note = "synthetic"

    def time(self, fn):
        return fn()


def _noisy(seconds, rng, noise=0.05):
    return lambda: seconds * (1.0 + noise * rng.standard_normal())


def test_equal_variants_are_no_difference():
    rng = np.random.default_rng(1)
    t = interleave({"A": _noisy(1.0, rng), "B": _noisy(1.0, rng)}, rounds=9, warmup=1, clock=FakeClock())
    r = compare(t["A"], t["B"])
    assert r.low < 1.0 < r.high
    assert r.verdict == "no difference"
    assert r.describe().startswith("no difference")
    # identical timings: every round exactly 1, still no difference
    same = compare(Timing([1.0] * 7), Timing([1.0] * 7))
    assert (same.median, same.low, same.high, same.verdict) == (1.0, 1.0, 1.0, "no difference")


def test_twice_as_fast_is_a_speed_up_whose_spread_excludes_one():
    rng = np.random.default_rng(2)
    t = interleave({"slow": _noisy(2.0, rng), "fast": _noisy(1.0, rng)}, rounds=7, clock=FakeClock())
    r = compare(t["slow"], t["fast"])
    assert r.verdict == "faster"
    assert 1.0 < r.low <= r.median <= r.high
    assert r.median == pytest.approx(2.0, rel=0.1)
    assert r.describe().startswith(f"{r.median:.2f}x faster")
    same_via_ab, timings = harness.ab(_noisy(2.0, rng), _noisy(1.0, rng), rounds=7, clock=FakeClock())
    assert same_via_ab.verdict == "faster" and set(timings) == {"baseline", "candidate"}
    inverse = compare(t["fast"], t["slow"])
    assert inverse.verdict == "slower" and inverse.high < 1.0
    d = r.to_dict()
    assert d["verdict"] == "faster" and d["rounds"] == 7 and len(d["per_round"]) == 7
    assert Ratio.from_dict(json.loads(json.dumps(d))).verdict == "faster"


def test_too_few_rounds_or_a_cost_lost_in_noise_give_no_verdict():
    assert paired_ratio([2.0, 2.0], [1.0, 1.0]).verdict == "no difference"   # < MIN_ROUNDS
    noisy = paired_ratio([1.0, 1.1, 0.9], [0.5, -0.1, 0.4])   # a denominator <= 0: unbounded
    assert math.isinf(noisy.high) and noisy.verdict == "no difference"
    assert noisy.to_dict()["high"] is None
    json.dumps(noisy.to_dict(), allow_nan=False)   # stays valid JSON
    # a numerator <= 0 (docs/bench/brdf.md once printed "-0.06x" speed-ups from such rounds)
    lost = paired_ratio([0.1, -0.05, 0.1, 0.1, 0.1], [1.0, 1.0, 1.0, 1.0, 1.0])
    assert lost.verdict == "no difference" and math.isinf(lost.low) and lost.median == 0.1
    assert "-" not in lost.describe().replace("–", "")


def test_interleave_alternates_the_order_and_warms_up():
    calls = []
    variants = {k: (lambda k=k: calls.append(k) or 1.0) for k in "AB"}
    t = interleave(variants, rounds=4, warmup=2, clock=FakeClock())
    assert "".join(calls) == "AABB" + "AB" + "BA" + "AB" + "BA"
    assert t["A"].warmup == 2 and len(t["A"].samples) == 4 and t["A"].clock == "fake"


def test_measure_reports_median_and_spread():
    values = iter([9.0, 3.0, 1.0, 2.0, 5.0, 4.0])
    t = measure(lambda: next(values), repeats=5, warmup=1, clock=FakeClock())   # 9.0 is the warm-up
    assert t.samples == [3.0, 1.0, 2.0, 5.0, 4.0]
    d = t.to_dict()
    assert (d["median_s"], d["min_s"], d["max_s"], d["n"], d["warmup"]) == (3.0, 1.0, 5.0, 5, 1)
    assert d["q1_s"] == 2.0 and d["q3_s"] == 4.0


# --- reports --------------------------------------------------------------------------------------

def _plot(result, path):
    plt = harness.matplotlib_pyplot()
    fig, ax = plt.subplots(figsize=(2, 2))
    ax.plot(result["values"])
    fig.savefig(path, dpi=40)
    plt.close(fig)


def _result():
    return {"benchmark": "demo", "machine": {"gl_renderer": "test renderer"}, "values": [1, 3, 2]}


def test_report_writes_json_markdown_and_png(tmp_path, capsys):
    paths = write_report(tmp_path / "out", "demo", _result(), lambda r: f"# demo on {r['machine']['gl_renderer']}",
                         _plot)
    assert json.loads(paths["json"].read_text())["values"] == [1, 3, 2]
    assert paths["md"].read_text() == "# demo on test renderer\n"
    assert paths["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["demo.json", "demo.md", "demo.png"]
    assert "# demo on test renderer" in capsys.readouterr().out


@pytest.mark.parametrize("failure", ["plot", "json"])
def test_a_failed_report_leaves_no_partial_file(tmp_path, failure):
    out = tmp_path / "out"
    write_report(out, "demo", _result(), "old", _plot, echo=False)   # an earlier run's report
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def broken_plot(result, path):
        path.write_bytes(b"\x89PNG half")
        raise RuntimeError("plot failed")

    result = _result()
    if failure == "json":
        result["values"] = {1, 2}   # not JSON serialisable
    with pytest.raises((RuntimeError, TypeError)):
        write_report(out, "demo", result, "new", broken_plot if failure == "plot" else _plot, echo=False)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before   # no temporary, nothing replaced


def test_report_needs_the_machine_record(tmp_path):
    with pytest.raises(ValueError, match="machine"):
        write_report(tmp_path, "demo", {"values": []}, "x")


def test_atomic_write_replaces_whole_files(tmp_path):
    p = tmp_path / "a.txt"
    harness.atomic_write(p, "one")
    with pytest.raises(RuntimeError):
        with harness.atomic_path(p) as tmp:
            tmp.write_text("half")
            raise RuntimeError
    assert p.read_text() == "one" and [q.name for q in tmp_path.iterdir()] == ["a.txt"]


# --- machine record and clocks ---------------------------------------------------------------------

def test_machine_record_names_the_driver(gl):
    from inshade.runtime.context import gl_info

    m = harness.machine()
    info = gl_info(gl)
    assert m["gl_renderer"] == info["renderer"] and m["gl_renderer"]
    assert m["gl_vendor"] == info["vendor"] and m["gl_version"] == info["version"]
    assert m["software_renderer"] == info["software"]
    assert m["cpu_count"] and m["python"] and "LP_NUM_THREADS" in m
    assert harness.machine(info, torch="x")["torch"] == "x"
    assert m["gl_renderer"] in harness.machine_markdown(m)


def test_clock_choice(gl):
    from inshade.runtime.context import gl_info

    software = gl_info(gl)["software"]
    auto = harness.clock_for(gl)
    assert auto.name == ("wall" if software else "gpu") and auto.note
    assert harness.clock_for(gl, "wall").name == "wall"
    assert harness.clock_for(None).name == "wall"
    with pytest.raises(ValueError):
        harness.clock_for(gl, "sundial")
    forced = harness.clock_for(gl, "gpu")   # a timer query where GL has one, else the wall clock
    fbo = gl.simple_framebuffer((8, 8))
    try:
        fbo.use()
        seconds = forced.time(lambda: fbo.clear(0.5, 0.5, 0.5, 1.0))
    finally:
        fbo.release()
    assert seconds >= 0.0 and forced.name in ("gpu", "wall")


def test_harness_import_is_torch_and_gl_free():
    code = ("import sys, inshade.bench.harness, inshade.bench; "
            "bad = [m for m in ('torch', 'matplotlib', 'moderngl') if m in sys.modules]; "
            "print(*bad, file=sys.stderr); sys.exit(bool(bad))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_cold_shader_cache_is_restored_after_the_bench(monkeypatch):
    """A bench turns Mesa's shader cache off for its own contexts only: contexts made later in the
    process (the next bench, a window) keep the cache; a choice the caller made is kept."""
    from inshade.bench.harness import cold_shader_cache

    monkeypatch.delenv("MESA_SHADER_CACHE_DISABLE", raising=False)
    with cold_shader_cache():
        assert os.environ["MESA_SHADER_CACHE_DISABLE"] == "true"
    assert "MESA_SHADER_CACHE_DISABLE" not in os.environ
    monkeypatch.setenv("MESA_SHADER_CACHE_DISABLE", "false")
    with cold_shader_cache():
        assert os.environ["MESA_SHADER_CACHE_DISABLE"] == "false"
    assert os.environ["MESA_SHADER_CACHE_DISABLE"] == "false"
