"""`inshade bench web`'s browser runtimes side by side: every runtime runs the same network on the same
batch in headless Chromium, and each result is compared with torch (numbers live in the bench's report,
not here)."""
from __future__ import annotations

import json

from inshade.web.bench import main
from inshade.web.bench_peers import RUNTIMES


def test_every_runtime_runs_the_batch_and_the_report_has_them(tmp_path, capsys):
    out = tmp_path / "bench"
    assert main(["--no-assets", "--peer-widths", "16", "--peer-depths", "2", "--peer-encodings", "raw",
                 "--peer-size", "16", "--repeats", "1", "--out", str(out)]) == 0
    report = json.loads((out / "web.json").read_text())
    rows = report["peers"]["16x2 raw"]
    assert list(rows) == list(RUNTIMES), rows
    for runtime, row in rows.items():
        assert "error" not in row, (runtime, row)
        # no sin / cos in a raw network: every runtime holds torch's numbers to the rule
        assert row["within_rule"], (runtime, row["max_scaled_error"])
        assert len(row["times"]) == 1 and row["device"]
    md = (out / "web.md").read_text()
    assert "## The browser runtimes side by side (256 samples per batch)" in md
    assert "| 16x2 raw | inshade WebGPU | WebGPU google / swiftshader |" in md
    assert (out / "web.png").stat().st_size > 0
