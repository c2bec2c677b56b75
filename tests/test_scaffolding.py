"""Techniques share their scaffolding: what every trainer, importer and bench records is made in one
place, so a search for its literal form outside that place finds nothing."""
from __future__ import annotations

import re
import subprocess

from test_architecture import ROOT

# literal form -> the one module that may spell it, and why it lives there
SHARED = {
    r"datetime\.(datetime\.)?(now|utcnow)\(|time\.strftime\(": (
        {"inshade/provenance.py", "viewer/capture.py"},
        "a record's time is inshade.provenance.utc_now() (the viewer's screenshot names use the local clock)"),
}


def _code() -> list[str]:
    out = subprocess.run(["git", "ls-files", "*.py"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    return [f for f in out.split() if not f.startswith("tests/") and (ROOT / f).is_file()]


def test_records_are_made_in_one_place():
    found = []
    files = _code()
    assert len(files) > 200
    for pattern, (allowed, why) in SHARED.items():
        rx = re.compile(pattern)
        for f in files:
            if f in allowed:
                continue
            for n, line in enumerate((ROOT / f).read_text().splitlines(), 1):
                if rx.search(line):
                    found.append(f"{f}:{n}: {line.strip()[:100]} ({why})")
    assert not found, "\n".join(found)
