"""The bench harness every `inshade bench NAME` is written on (torch-free; GL and matplotlib are
imported only when used).

- ``machine(gl)``: the machine record of every result (GL_VENDOR / GL_RENDERER / GL_VERSION, GLSL
  version, software renderer or not, CPUs, Python, the Mesa variables that change timings).
- ``portable_path(path)`` / ``portable_command(text)``: the paths a report records, the same on every
  machine: repository-relative inside the checkout, ``<scratch>/NAME`` for a folder elsewhere (a
  temporary folder of the machine that ran it).
- Clocks: ``clock_for(ctx)`` picks a GL timer query (``GL_TIME_ELAPSED``, ns) on a hardware driver
  and ``draw(); glFinish()`` wall time otherwise; every timing records the clock it used. On Mesa
  llvmpipe the timer query is supported but wrong (it reported 17 ms for a draw whose
  ``glFinish`` wall time was 132 ms), so software renderers get the wall clock.
- ``measure(fn)``: warm-up calls, then the median and spread (min, max, quartiles) of N timed calls.
- ``interleave({name: fn})``: rounds in which every variant is timed once, the order alternating
  (A B, B A, A B, ...: ABBA over two rounds) so load drift hits all variants alike (``ab(a, b)``
  for two); ``compare`` / ``paired_ratio(numerators, denominators)`` turn per-round values into a ``Ratio``: the median
  of the per-round ratios and their min..max. The verdict is "faster" / "slower" only when every
  round agrees (min..max does not contain 1): with n rounds and no real difference that happens
  with probability 2^(1-n) (a sign test; 1.6 % at 7 rounds). Otherwise "no difference", never a
  speed-up or slow-down read off noise; fewer than ``MIN_ROUNDS`` rounds never give a verdict.
- ``write_report(out, stem, result, markdown, plot)``: ``stem.json`` (with the machine record),
  ``stem.md`` and ``stem.png`` (matplotlib, Agg), each rendered to a temporary file in the same
  folder first and moved into place with ``os.replace`` only when all three succeeded, so a failed
  run leaves no partial or mismatched file behind.
"""
from __future__ import annotations

import contextlib
import json
import math
import os
import platform
import re
import statistics
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from inshade.files import atomic_files, atomic_write  # noqa: F401 (re-exported for benches)
from inshade.files import atomic_files as atomic_path  # noqa: F401

MIN_ROUNDS = 3


class BenchError(ValueError):
    """A bench option or input the user can fix: ``inshade: error: ...`` and exit status 2 (pass
    ``errors=(BenchError,)`` to ``inshade.command.main``)."""

MESA_VARIABLES = ("LP_NUM_THREADS", "MESA_SHADER_CACHE_DISABLE", "GALLIUM_DRIVER", "MESA_GL_VERSION_OVERRIDE")


# ---------------------------------------------------------------------------------------------
# machine record

@contextlib.contextmanager
def cold_shader_cache():
    """Mesa's on-disk shader cache off for the GL contexts made inside (cold compile times: the cache
    would hide the JIT on re-runs), unless the caller chose; the process's environment is restored
    after, so contexts made later (another bench, a window) keep their cache."""
    name = "MESA_SHADER_CACHE_DISABLE"
    chosen = name in os.environ
    os.environ.setdefault(name, "true")
    try:
        yield
    finally:
        if not chosen:
            os.environ.pop(name, None)


def machine(gl: Mapping | None = None, **extra) -> dict:
    """The "machine" record of every benchmark's JSON, from ``runtime.context.gl_info`` (the shared
    context's when ``gl`` is None). ``extra`` entries are added (e.g. torch's version)."""
    if gl is None:
        from inshade.runtime.context import gl_info, shared_context

        gl = gl_info(shared_context())
    record = {"gl_vendor": gl["vendor"], "gl_renderer": gl["renderer"], "gl_version": gl["version"],
              "glsl_version": gl.get("glsl_version"), "software_renderer": bool(gl["software"]),
              "cpu_count": os.cpu_count(), "cpu": platform.processor() or platform.machine(),
              "platform": platform.platform(), "python": platform.python_version()}
    record.update({name: os.environ.get(name) for name in MESA_VARIABLES})
    record.update(extra)
    return record


def machine_markdown(m: Mapping) -> str:
    """One markdown bullet naming the driver, e.g. for the head of a report."""
    soft = " (software rasteriser: CPU timings, not GPU timings)" if m.get("software_renderer") else ""
    return (f"- GL_RENDERER: `{m['gl_renderer']}`; GL_VERSION: `{m['gl_version']}`; "
            f"GL_VENDOR: `{m['gl_vendor']}`{soft}")


# ---------------------------------------------------------------------------------------------
# paths in a report

REPOSITORY = Path(__file__).resolve().parents[1]   # bench/ sits at the checkout's top level
SCRATCH = "<scratch>"
# an absolute path starting a word or an option's value, or quoted whole (it may hold spaces)
_ABSOLUTE = re.compile(r"""(?<![^\s=])(['"])(/[^'"]*)\1|(?<![^\s='"`(])/[^\s'"`)]+""")


def asset_folders(names) -> list[Path]:
    """The asset folders named (default: every shipped one, under trained/), or BenchError naming the
    first that is not a folder."""
    root = Path(__file__).resolve().parents[1] / "trained"
    assets = [Path(a) for a in names] or sorted(p for p in root.iterdir() if p.is_dir())
    missing = [str(a) for a in assets if not a.is_dir()]
    if missing:
        raise BenchError(f"{missing[0]}: no such asset folder")
    return assets


def portable_path(path: str | os.PathLike) -> str:
    """A path as a report records it, the same on every machine: inside the repository as its
    repository-relative path (``trained/di_footprint``); elsewhere as its name under ``<scratch>``
    (``<scratch>/di_footprint``), a folder of the machine that ran the bench, meaningless elsewhere.
    A relative path is taken from the working folder. Markdown shows a ``<scratch>`` path in a code
    span (bare, it is read as an HTML tag)."""
    given = Path(os.path.abspath(Path(path).expanduser()))
    for candidate in (given, given.resolve()):   # the checkout reached through a link, too
        if candidate.is_relative_to(REPOSITORY):
            return candidate.relative_to(REPOSITORY).as_posix()
    return f"{SCRATCH}/{given.name}" if given.name else SCRATCH


def portable_command(text: str | None) -> str | None:
    """A recorded command line (or a note holding paths) with each absolute path made
    ``portable_path``; the rest verbatim. Relative paths stay: they are what was typed, relative to
    wherever it ran."""
    if text is None:
        return None
    return _ABSOLUTE.sub(lambda m: m.group(1) + portable_path(m.group(2)) + m.group(1) if m.group(1)
                         else portable_path(m.group(0)), text)


# ---------------------------------------------------------------------------------------------
# clocks

class WallClock:
    """``fn(); finish()`` wall time in seconds (``finish`` = ``ctx.finish`` for GL work)."""

    name = "wall"

    def __init__(self, finish: Callable[[], object] | None = None, note: str = ""):
        self.finish, self.note = finish, note

    def time(self, fn: Callable[[], object]) -> float:
        start = time.perf_counter()
        fn()
        if self.finish is not None:
            self.finish()
        return time.perf_counter() - start


class GpuClock:
    """GL_TIME_ELAPSED of the GL commands ``fn`` issues, in seconds (moderngl ``ctx.query(time=True)``)."""

    name = "gpu"
    note = "GL_TIME_ELAPSED timer query"

    def __init__(self, ctx):
        self.ctx = ctx
        self.query = ctx.query(time=True)

    def time(self, fn: Callable[[], object]) -> float:
        with self.query:
            fn()
        return self.query.elapsed * 1e-9


def clock_for(ctx=None, prefer: str = "auto", software: bool | None = None):
    """The clock to time GL work on ``ctx``: ``prefer`` "gpu" (timer query, falling back to the wall
    clock when queries are unsupported), "wall" (``glFinish`` wall time; also the only choice
    without a context), or "auto": "gpu" on a hardware renderer, "wall" on a software one (llvmpipe's
    timer query under-reports)."""
    if prefer not in ("auto", "gpu", "wall"):
        raise ValueError(f"unknown clock {prefer!r} (auto, gpu, wall)")
    if ctx is None:
        return WallClock(note="wall clock (no GL context)")
    finish = ctx.finish
    if software is None:
        from inshade.runtime.context import SOFTWARE_RENDERERS

        software = any(n in ctx.info["GL_RENDERER"].lower() for n in SOFTWARE_RENDERERS)
    if prefer == "wall" or (prefer == "auto" and software):
        why = "software renderer: its timer query under-reports" if prefer == "auto" else "requested"
        return WallClock(finish, note=f"draw + glFinish wall time ({why})")
    try:
        return GpuClock(ctx)
    except Exception as exc:  # noqa: BLE001 - no ARB_timer_query / GL_TIME_ELAPSED here
        return WallClock(finish, note=f"draw + glFinish wall time (timer query unsupported: {exc})")


def clock_record(clock) -> dict:
    return {"clock": clock.name, "clock_note": getattr(clock, "note", "")}


# ---------------------------------------------------------------------------------------------
# timings

@dataclass
class Timing:
    """Timed samples (seconds) of one thing, and the clock that timed them."""

    samples: list[float]
    clock: str = "wall"
    warmup: int = 0

    @property
    def median(self) -> float:
        return statistics.median(self.samples)

    @property
    def min(self) -> float:
        return min(self.samples)

    @property
    def max(self) -> float:
        return max(self.samples)

    def quartiles(self) -> tuple[float, float]:
        if len(self.samples) < 2:
            return self.samples[0], self.samples[0]
        q = statistics.quantiles(self.samples, n=4, method="inclusive")
        return q[0], q[2]

    def to_dict(self) -> dict:
        q1, q3 = self.quartiles()
        return {"clock": self.clock, "warmup": self.warmup, "n": len(self.samples), "median_s": self.median,
                "min_s": self.min, "max_s": self.max, "q1_s": q1, "q3_s": q3, "samples_s": list(self.samples)}


def measure(fn: Callable[[], object], *, repeats: int = 5, warmup: int = 1, clock=None) -> Timing:
    """``warmup`` untimed calls, then ``repeats`` timed ones (at least one) on ``clock`` (default:
    wall clock, no finish)."""
    clock = clock or WallClock()
    for _ in range(max(0, warmup)):
        fn()
    return Timing([clock.time(fn) for _ in range(max(1, repeats))], clock.name, max(0, warmup))


def interleave(variants: Mapping[str, Callable[[], object]], *, rounds: int = 7, warmup: int = 1, clock=None,
               progress: Callable[[int, int], object] | None = None) -> dict[str, Timing]:
    """Time every variant once per round, the order reversed every other round (ABBA), after
    ``warmup`` untimed calls of each. Sample i of every returned Timing is from round i."""
    clock = clock or WallClock()
    names = list(variants)
    for name in names:
        for _ in range(max(0, warmup)):
            variants[name]()
    samples = {name: [] for name in names}
    for i in range(max(1, rounds)):
        for name in (names if i % 2 == 0 else names[::-1]):
            samples[name].append(clock.time(variants[name]))
        if progress is not None:
            progress(i + 1, max(1, rounds))
    return {name: Timing(samples[name], clock.name, max(0, warmup)) for name in names}


@dataclass
class Ratio:
    """Per-round ratios r_i = numerator_i / denominator_i (> 1: the denominator's side is faster)."""

    per_round: list[float]
    median: float = field(init=False)
    low: float = field(init=False)
    high: float = field(init=False)

    def __post_init__(self):
        finite = [r for r in self.per_round if math.isfinite(r)]
        self.median = statistics.median(finite) if finite else math.nan
        self.low = min(self.per_round) if finite == self.per_round and finite else -math.inf
        self.high = max(self.per_round) if finite == self.per_round and finite else math.inf

    @property
    def verdict(self) -> str:
        """"faster" (every round > 1), "slower" (every round < 1) or "no difference"."""
        if len(self.per_round) < MIN_ROUNDS:
            return "no difference"
        if self.low > 1.0:
            return "faster"
        if self.high < 1.0:
            return "slower"
        return "no difference"

    @classmethod
    def from_dict(cls, d: Mapping) -> Ratio:
        """Back from ``to_dict`` (an unbounded round, stored as null, stays unbounded)."""
        return cls([math.inf if v is None else v for v in d["per_round"]])

    def to_dict(self) -> dict:
        return {"median": _finite(self.median), "low": _finite(self.low), "high": _finite(self.high),
                "rounds": len(self.per_round), "verdict": self.verdict,
                "per_round": [_finite(r) for r in self.per_round]}

    def describe(self, faster: str = "faster", slower: str = "slower") -> str:
        """e.g. "2.01x faster (1.95-2.08)", "0.48x: slower (0.45-0.52)", "no difference (0.91-1.12)"."""
        span = f"({_fmt_x(self.low)}–{_fmt_x(self.high)})"
        if len(self.per_round) < MIN_ROUNDS:
            return f"{_fmt_x(self.median)}: no verdict ({len(self.per_round)} round{'s' * (len(self.per_round) != 1)})"
        v = self.verdict
        if v == "no difference":
            return f"no difference {span}"
        return f"{_fmt_x(self.median)} {faster if v == 'faster' else slower} {span}"


def paired_ratio(numerators: Sequence[float], denominators: Sequence[float]) -> Ratio:
    """Ratio of paired per-round values. A value <= 0 on either side (a cost lost in noise) leaves
    that round's ratio undefined (NaN), so the interval is unbounded and the verdict is "no
    difference": noise never prints as a negative speed-up."""
    if len(numerators) != len(denominators):
        raise ValueError("paired_ratio needs as many numerators as denominators")
    return Ratio([a / b if a > 0 and b > 0 else math.nan for a, b in zip(numerators, denominators)])


def compare(baseline: Timing, candidate: Timing) -> Ratio:
    """Speed-up of ``candidate`` over ``baseline`` per round (baseline time / candidate time), from
    two Timings of the same ``interleave`` run."""
    return paired_ratio(baseline.samples, candidate.samples)


def ab(baseline: Callable[[], object], candidate: Callable[[], object], *, rounds: int = 7, warmup: int = 1,
       clock=None) -> tuple[Ratio, dict[str, Timing]]:
    """Interleaved A/B: the candidate's speed-up over the baseline (``compare``) and both Timings
    (keys "baseline", "candidate")."""
    t = interleave({"baseline": baseline, "candidate": candidate}, rounds=rounds, warmup=warmup, clock=clock)
    return compare(t["baseline"], t["candidate"]), t


def paired_difference(a: Sequence[float], b: Sequence[float]) -> Timing:
    """Per-round a - b (e.g. a variant's time minus a baseline pass's) as a Timing."""
    return Timing([x - y for x, y in zip(a, b)])


def _finite(v: float):
    return v if math.isfinite(v) else None


def _fmt_x(v: float) -> str:
    if v is None or math.isnan(v):
        return "—"
    if math.isinf(v):
        return "∞" if v > 0 else "−∞"
    return f"{v:.2f}x"


# ---------------------------------------------------------------------------------------------
# reports

def markdown_table(headers: Sequence[str], rows: Sequence[Sequence], align: str | None = None) -> list[str]:
    """Lines of a markdown table; ``align`` one character a column: l, r or c."""
    marks = {"l": "---", "r": "---:", "c": ":---:"}
    align = align or "l" * len(headers)
    lines = ["| " + " | ".join(headers) + " |", "|" + "|".join(marks[a] for a in align) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines



def matplotlib_pyplot():
    """matplotlib.pyplot on the Agg backend (imported on first use)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def label_axes(ax, xlabel: str, ylabel: str) -> None:
    """A report plot's axes named, over the light grid every report draws."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)


def save_figure(fig, path: Path, title: str, result: Mapping, dpi: int = 110) -> None:
    """A report's figure finished the one way: titled with the GL_RENDERER, laid out, written, closed."""
    fig.suptitle(f"{title} — {result['machine']['gl_renderer']}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    matplotlib_pyplot().close(fig)


def write_report(out: Path | str, stem: str, result: dict, markdown: str | Callable[[dict], str],
                 plot: Callable[[dict, Path], object] | None = None, *, echo: bool = True) -> dict[str, Path]:
    """Write ``stem.json``, ``stem.md`` and (with ``plot(result, path)``) ``stem.png`` into ``out``.

    ``result`` must carry a ``machine`` record. All files are rendered to temporary files in
    ``out`` first, then moved into place; if any step fails none is replaced and the temporary
    files are removed. With ``echo`` the markdown is printed to stdout. Returns {suffix: path}.
    """
    if "machine" not in result:
        raise ValueError("a bench result needs its 'machine' record (inshade.bench.harness.machine)")
    out = Path(out)
    md = markdown(result) if callable(markdown) else markdown
    targets = {"json": out / f"{stem}.json", "md": out / f"{stem}.md"}
    if plot is not None:
        targets["png"] = out / f"{stem}.png"
    with atomic_files(*targets.values()) as temps:
        temps = dict(zip(targets, temps))
        temps["json"].write_text(json.dumps(result, indent=2) + "\n")
        temps["md"].write_text(md if md.endswith("\n") else md + "\n")
        if plot is not None:
            plot(result, temps["png"])
            if not temps["png"].stat().st_size:
                raise RuntimeError(f"the plot of {stem} wrote nothing")
    if echo:
        print(md)
    return targets
