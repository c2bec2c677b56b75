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
    r"""["']date_utc["']\s*:\s*utc_now|\[["']date_utc["']\]\s*=""": (
        {"inshade/provenance.py"},
        "a provenance or metrics record gets its time from inshade.provenance.recorded_at()"),
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


# A scene.json is written through the typed builder, which spells the format's header once; the parser
# names the format it checks and shows one file in its docstring.
SCENE_LITERAL = re.compile(r"""["']format["']\s*:\s*["']inshade\.scene["']|format\s*=\s*["']inshade\.scene["']""")
SCENE_WRITERS = {"scene/builder.py", "scene/description.py"}


def test_scenes_are_written_through_the_builder():
    found = [f"{f}:{n}: {line.strip()[:100]}" for f in _code() if f not in SCENE_WRITERS
             for n, line in enumerate((ROOT / f).read_text().splitlines(), 1) if SCENE_LITERAL.search(line)]
    assert not found, ("scene.json data spelled by hand; build it with inshade.scene.builder (scene_json and "
                       "its parts):\n" + "\n".join(found))


# An optimisation loop (an optimiser built, gradients cleared, a backward pass, a stepped scheduler) is
# spelled in the fit loop only: every trainer hands it its parameters and a per-step loss, so steps,
# schedule, progress, checkpoints and resuming behave alike everywhere.
HAND_LOOP = {
    r"optim\.[A-Z]\w*\(": "an optimiser is built by inshade.models.fit_loop (adam; lbfgs for full-batch finishes)",
    r"\.zero_grad\(|\.backward\(": "the fit loop clears gradients and backpropagates each step's loss (fit_loop.fit)",
    r"lr_scheduler\.LambdaLR\(": "a per-step schedule is fit_loop.fit's lr_factor (fit_loop.cosine)",
}
FIT_LOOP = {"models/fit_loop.py"}


def test_optimisation_loops_run_through_the_fit_loop():
    rules = [(re.compile(pattern), why) for pattern, why in HAND_LOOP.items()]
    found = [f"{f}:{n}: {line.strip()[:100]} ({why})" for f in _code() if f not in FIT_LOOP
             for n, line in enumerate((ROOT / f).read_text().splitlines(), 1)
             for rx, why in rules if rx.search(line)]
    assert not found, "a hand-written optimisation loop:\n" + "\n".join(found)
