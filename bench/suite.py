"""`inshade bench suite`: every bench in one run, sized by a preset, and a one-page summary of its
headline numbers next to the papers' claims.

Runs every bench ``inshade bench`` mounts (the shared ones and each registered technique's, its
record's ``bench`` field), one after another in this process, each with the command line of
``--preset``. Each bench's module declares that command line per preset and how its JSON reads as
summary rows (``SUITE``, bench/entry.py); the papers come from the technique records, so
this module names no bench:

- ``cpu``: small sizes that finish in a few minutes on a 2-core machine (Mesa llvmpipe);
- ``device``: the sizes for one GPU, all benches together within 8 minutes.

Every bench writes its JSON, markdown and plot into ``--out`` (default
``docs/bench/<renderer-slug>/``, the slug from GL_RENDERER, e.g. ``nvidia-h200``). A bench that
fails (exit status, exception) is recorded with its error line and the suite goes on. Then
``summary.json``, ``summary.md`` and ``summary.png`` (ours / paper per claim): GL_RENDERER, the
paper's number next to ours for each technique's headline measure, and each bench's wall time
against its budget in the preset. The budgets are reported, not enforced: a bench over its budget
still finishes. Exit status 1 when any bench was not ok, 2 for a bad option.
"""
from __future__ import annotations

import contextlib
import gc
import importlib
import io
import json
import os
import re
import shlex
import sys
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from inshade import technique
from inshade.bench.contract import Bench, option
from inshade.provenance import utc_now
from inshade.bench.entry import PRESETS, Sizing, SuiteEntry
from inshade.bench.harness import (BenchError, machine, machine_markdown, markdown_table, matplotlib_pyplot,
                                   portable_path, write_report)
from inshade.technique import Paper

DEVICE_MINUTES = 10         # the device preset's budget, all benches together
NAME = "suite"              # this bench's own name in the bench table (it does not run itself)


# ---------------------------------------------------------------------------------------------
# each bench's entry (its module's SUITE), and the paper behind its claims

def entry(name: str) -> SuiteEntry | None:
    """The suite entry a registered bench's module declares (``SUITE``); None for a bench not
    registered or declaring none (reported as not run, and tests/bench/test_bench_suite.py fails)."""
    module = registered().get(name)
    if module is None:
        return None
    found = getattr(importlib.import_module(module), "SUITE", None)
    if found is not None and not isinstance(found, SuiteEntry):
        raise BenchError(f"{module}.SUITE: expected an inshade.bench.entry.SuiteEntry, got {type(found).__name__}")
    return found


def paper(name: str) -> Paper | None:
    """The paper of the technique behind a bench, from its record (None: a shared bench)."""
    return next((t.paper for t in technique.techniques() if t.name == name and t.bench), None)


def headlines(name: str, result: Mapping) -> list[dict]:
    """The summary rows of one bench's JSON; a JSON its entry cannot read gives one row saying so."""
    found = entry(name)
    if found is None:
        return []
    try:
        return found.headlines(result)
    except (KeyError, IndexError, TypeError, ValueError, StopIteration, ZeroDivisionError) as exc:
        return [{"bench": name, "claim": None, "subject": "", "paper": "", "measure": "headline numbers",
                 "paper_says": "", "paper_value": None, "higher_better": True, "ours": f"could not read {name}.json: "
                 f"{type(exc).__name__}: {exc}", "ours_value": None, "ours_over_paper": None}]


# ---------------------------------------------------------------------------------------------
# running

def slug(renderer: str) -> str:
    """A folder name for a GL_RENDERER string: the part before the first '/' (NVIDIA appends
    '/PCIe/SSE2'), lower case, runs of other characters as '-'.
    'llvmpipe (LLVM 15.0.6, 256 bits)' -> 'llvmpipe-llvm-15-0-6-256-bits'; 'NVIDIA H200/PCIe/SSE2' -> 'nvidia-h200'."""
    text = re.sub(r"[^a-z0-9]+", "-", renderer.split("/", 1)[0].lower()).strip("-")
    return text or "unknown-renderer"


def registered() -> dict[str, str]:
    """name -> module of every bench `inshade bench` mounts, but this one."""
    from inshade.bench import benches

    return {name: module for name, (module, _) in benches().items() if name != NAME}


class _Tee(io.TextIOBase):
    """stderr that is also kept, to find a failing bench's error line."""

    def __init__(self, stream):
        self.stream, self.kept = stream, io.StringIO()

    def write(self, text: str) -> int:
        self.stream.write(text)
        self.kept.write(text)
        return len(text)

    def flush(self) -> None:
        self.stream.flush()

    def isatty(self) -> bool:   # progress bars stay as they would be
        return self.stream.isatty()

    def fileno(self) -> int:
        return self.stream.fileno()

    @property
    def encoding(self):
        return getattr(self.stream, "encoding", "utf-8")


def _error_line(stderr: str) -> str | None:
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("inshade: error:")]
    if errors:
        return errors[-1].removeprefix("inshade: error:").strip()
    return lines[-1] if lines else None


def run_bench(name: str, main: Callable[[list[str]], int], argv: list[str], out: Path) -> dict:
    """Run one bench's main(argv) and return its record: status ok | failed, the error line, the
    wall time, and its JSON result (read only when written by this run)."""
    started_ns, start = time.time_ns(), time.perf_counter()
    tee, error = _Tee(sys.stderr), None
    try:
        with contextlib.redirect_stderr(tee):
            rc = main(argv)
    except SystemExit as exc:   # argparse rejected an option of the preset
        rc = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
        error = None if isinstance(exc.code, int) or exc.code is None else str(exc.code)
    except Exception as exc:  # noqa: BLE001 - one bench's failure must not cost the others' results
        traceback.print_exc()
        rc, error = 1, f"{type(exc).__name__}: {exc}"
    seconds = time.perf_counter() - start
    gc.collect()   # GL objects a failed bench left behind
    record = {"name": name, "argv": argv, "seconds": round(seconds, 2), "status": "ok", "error": None,
              "json": None, "result": None}
    path = out / f"{name}.json"
    if rc:
        error = error or _error_line(tee.kept.getvalue()) or f"exit status {rc}"
    elif not path.is_file() or path.stat().st_mtime_ns < started_ns:
        error = f"exited 0 but wrote no {path.name}"
    else:
        try:
            record["result"] = json.loads(path.read_text())
            record["json"] = path.name
        except (OSError, ValueError) as exc:
            error = f"{path.name}: {exc}"
    if error is not None:
        record.update(status="failed", error=" ".join(str(error).split()))
    return record


def run_suite(out: Path, plan: Mapping[str, Sizing | None], mains: Mapping[str, Callable[[list[str]], int]],
              *, preset: str, gl: Mapping, log=print) -> dict:
    """Run each bench of ``plan`` (name -> its sizing, None: not in the preset) into ``out`` and
    write the summary after each one (a suite stopped half way leaves the summary so far)."""
    out.mkdir(parents=True, exist_ok=True)
    result = {"benchmark": "suite", "preset": preset, "out": portable_path(out), "machine": machine(gl),
              "created": utc_now(),
              "budget_s": sum(s.budget_s for s in plan.values() if s is not None), "seconds": 0.0,
              "benches": [], "headlines": []}
    for name, sizing in plan.items():
        if sizing is None:
            record = {"name": name, "argv": None, "seconds": 0.0, "status": "not run", "budget_s": None,
                      "error": f"no '{preset}' sizing in its bench module's SUITE", "json": None}
        else:
            argv = [*sizing.argv, "--out", str(out)]
            log(f"suite: {name} ({sizing.budget_s:g} s budget): inshade bench {name} {shlex.join(argv)}")
            record = run_bench(name, mains[name], argv, out)
            record["argv"] = [*sizing.argv, "--out", portable_path(out)]   # as any machine would type it
            record["budget_s"] = sizing.budget_s
            record["over_budget"] = record["seconds"] > sizing.budget_s
            bench_result = record.pop("result")
            if bench_result is not None:
                result["headlines"] += headlines(name, bench_result)
            log(f"suite: {name} {record['status']} in {record['seconds']:.1f} s"
                + (f": {record['error']}" if record["error"] else ""))
        result["benches"].append(record)
        result["seconds"] = round(sum(b["seconds"] for b in result["benches"]), 2)
        write_report(out, "summary", result, markdown, plot, echo=False)
    return result


# ---------------------------------------------------------------------------------------------
# report

def _num(v: float | None) -> str:
    return "—" if v is None else f"{v:.3g}"


def _ratio(v: float | None) -> str:
    if v is None:
        return "—"
    return f"{v:.0f}" if v >= 100 else f"{v:.2f}" if v >= 0.1 else f"{v:.2g}"


def markdown(r: Mapping) -> str:
    m = r["machine"]
    failed = [b for b in r["benches"] if b["status"] != "ok"]
    lines = [f"# inshade bench suite: preset `{r['preset']}`", "",
             f"**GL_RENDERER: `{m['gl_renderer']}`**", "",
             machine_markdown(m),
             f"- {r['created']}; {len(r['benches'])} benches, {len(failed)} not ok; wall time {r['seconds']:.0f} s "
             f"(budget {r['budget_s']:.0f} s); each bench's own report: its `NAME.md` / `NAME.json` / `NAME.png` "
             "beside this file", "",
             "## Against the papers", "",
             "Ours is measured on the renderer above; the papers' numbers are from their own GPUs, so a ratio is "
             "a pointer, not a verdict. ours / paper: ours divided by the paper's number, where both are numbers.", ""]
    rows = [[h["bench"], h["subject"] or "—", h["measure"], h["paper_says"] or "—", h["ours"],
             _ratio(h["ours_over_paper"])] for h in r["headlines"]]
    lines += markdown_table(["bench", "subject", "measure", "paper", "ours", "ours / paper"], rows, "lllllr")
    lines += ["", "## Benches", ""]
    rows = [[b["name"], b["status"], f"{b['seconds']:.1f}", _num(b["budget_s"]),
             "over" if b.get("over_budget") else "", f"[{b['name']}.md]({b['name']}.md)" if b["json"] else "—",
             b["error"] or ""] for b in r["benches"]]
    lines += markdown_table(["bench", "status", "seconds", "budget s", "", "report", "error"], rows, "llrrlll")
    lines += ["", "Command lines (each with `--out` this folder):", ""]
    lines += [f"- `inshade bench {b['name']} {shlex.join(b['argv'][:-2])}`" for b in r["benches"] if b["argv"]]
    cited = {p.cite() for p in map(paper, (b["name"] for b in r["benches"])) if p is not None}
    lines += ["", "Papers:", ""] + [f"- {c}" for c in sorted(cited)]
    return "\n".join(lines) + "\n"


def plot(r: Mapping, path: Path) -> None:
    plt = matplotlib_pyplot()
    rows = [h for h in r["headlines"] if h["ours_over_paper"] is not None and h["ours_over_paper"] > 0]
    fig, ax = plt.subplots(figsize=(8, 1.2 + 0.3 * max(1, len(rows))))
    labels = [f"{h['bench']} {h['claim']} {h['subject']}" + ("" if h["higher_better"] else " (lower is better)")
              for h in rows]
    # green: ours beats the paper's number in its own direction (more speed-up, fewer ms)
    good = [(h["ours_over_paper"] >= 1) == h["higher_better"] for h in rows]
    ax.scatter([h["ours_over_paper"] for h in rows], range(len(rows)),
               c=["tab:green" if g else "tab:red" for g in good], zorder=3)
    ax.axvline(1.0, color="k", lw=0.8)
    ax.grid(axis="x", which="major", alpha=0.3)
    ax.set_yticks(range(len(rows)), labels, fontsize=7)
    ax.set_xscale("log")
    ax.invert_yaxis()
    ax.set_xlabel("ours / paper (1 = the paper's number)")
    ax.set_title(f"{r['machine']['gl_renderer']}, preset {r['preset']}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# command line

@dataclass
class Settings:
    preset: str = option(None, "cpu: minutes on a 2-core machine; device: one GPU, <= 8 minutes in all",
                         choices=PRESETS, required=True)
    out: str | None = option(None, "output folder (default docs/bench/<renderer-slug>, e.g. docs/bench/nvidia-h200)")
    only: str | None = option(None, "run only these benches (comma-separated)", metavar="NAME,...")
    dry_run: bool = option(False, "print each bench's command line and budget, run nothing")


def plan_for(preset: str, names: list[str]) -> dict[str, Sizing | None]:
    """name -> its sizing in ``preset`` (from its bench module's SUITE), None where it has none."""
    return {name: found.sizes.get(preset) if (found := entry(name)) else None for name in names}


def run(args) -> int:
    modules = registered()
    names = list(modules)
    if args.only is not None:
        names = [n.strip() for n in args.only.split(",") if n.strip()]
        unknown = [n for n in names if n not in modules]
        if unknown or not names:
            raise BenchError(f"--only: unknown bench {', '.join(unknown) or '(none given)'} "
                             f"(known: {', '.join(modules)})")
    plan = plan_for(args.preset, names)
    if args.dry_run:
        for name, sizing in plan.items():
            print(f"{sizing.budget_s:5.0f} s  inshade bench {name} {shlex.join(sizing.argv)}" if sizing
                  else f"    —    {name}: no '{args.preset}' sizing")
        print(f"{sum(s.budget_s for s in plan.values() if s):5.0f} s  in all")
        return 0
    from inshade.runtime.context import gl_info, shared_context

    # This makes the process's first GL context, so a bench's own MESA_SHADER_CACHE_DISABLE default
    # (the shared benches set one) would come too late: the suite sets it first, unless the environment
    # says otherwise, so that first draws and compile times are cold as each bench reports them.
    os.environ.setdefault("MESA_SHADER_CACHE_DISABLE", "true")
    gl = gl_info(shared_context())
    out = Path(args.out) if args.out else Path("docs/bench") / slug(gl["renderer"])
    print(f"inshade bench suite: GL_RENDERER {gl['renderer']}; preset {args.preset}; writing {out}", file=sys.stderr)

    def loader(module: str):
        def bench_main(argv: list[str]) -> int:
            return importlib.import_module(module).main(argv)
        return bench_main

    result = run_suite(out, plan, {n: loader(modules[n]) for n in plan}, preset=args.preset, gl=gl,
                       log=lambda text: print(text, file=sys.stderr))
    print(markdown(result))
    bad = [b["name"] for b in result["benches"] if b["status"] != "ok"]
    print(f"wrote {out / 'summary.md'} ({len(bad)} of {len(result['benches'])} benches not ok"
          + (f": {', '.join(bad)})" if bad else ")"), file=sys.stderr)
    return 1 if bad else 0


BENCH = Bench(NAME, __doc__, Settings, run)
add_arguments, main = BENCH.add_arguments, BENCH.main
