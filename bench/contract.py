"""The bench contract: a bench's settings are one typed dataclass, its ``--quick`` run and its sizes in
``inshade bench suite`` are data, and this layer makes the rest -- the ``inshade bench NAME`` options
(each help line as the bench words it, ``%(default)s`` expanded), the one-line errors, and the suite
entry (``SUITE``: its command line per preset, claims and headline rows).

    @dataclass
    class Settings:
        out: str = option("bench-out/toy", "output folder")
        size: int = option(64, "uv grid side (default %(default)s)")
        quick: bool = option(False, "tiny run for tests")

    BENCH = Bench("toy", __doc__, Settings, run, quick={"size": 8}, claims=CLAIMS, headlines=headlines,
                  sizes={"cpu": sized(5, size=16), "device": sized(5, size=256)})
    add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite

The fields reuse the trainer contract's ``setting`` (help, choices, flag, metavar, positional); a bench
adds ``parse`` (a function of the option's text, e.g. a comma-separated list) and ``nargs``. A
positional setting (``positional="assets"``, the name its help shows) left off the command line holds
what argparse gives it (``[]`` for ``nargs="*"``), as a trainer's positional does. Settings are
not frozen: a run may keep what it derives from them (parsed lists, its clock) beside them.
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import sys
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from inshade import command
from inshade.bench.entry import PRESETS, Claim, Sizing, SuiteEntry
from inshade.bench.harness import BenchError, cold_shader_cache
from inshade.trainer import scalar_type, setting

CLOCKS = ("auto", "gpu", "wall")


def option(default, help: str | None = None, *, parse: Callable[[str], object] | None = None,
           nargs: str | None = None, required: bool = False, choices=None, flag: str | None = None,
           metavar: str | None = None, positional: str | None = None):
    """A bench setting: a trainer ``setting`` whose help is shown as written, plus ``parse`` (the
    option's type: a function of its text), ``nargs`` and ``required``."""
    base = setting(default, help, choices=choices, flag=flag, metavar=metavar, positional=positional)
    return field(default=base.default,
                 metadata={**base.metadata, "parse": parse, "nargs": nargs, "required": required})


def clock_option(default: str = "auto"):
    """``--clock``: the GL timing every frame-timing bench offers (harness ``clock_for``)."""
    return option(default, "GL timing: timer query (gpu), draw + glFinish wall time (wall), or auto = gpu "
                           "on a hardware renderer, wall on a software one (default %(default)s)", choices=CLOCKS)


def rounds_option(default: int = 7):
    """``--rounds``: the timed rounds of harness ``interleave``."""
    return option(default, "timed rounds (default %(default)s)")


def warmup_option(default: int = 2):
    """``--warmup``: harness ``interleave``'s untimed draws of each variant before the rounds."""
    return option(default, "untimed draws per variant (default %(default)s)")


@dataclass(frozen=True)
class Size:
    """A bench in one suite preset: the settings it sets and the wall time it should take."""
    budget_s: float
    values: Mapping[str, object]


def sized(budget_s: float, **values) -> Size:
    return Size(budget_s, values)


def _spelling(f: dataclasses.Field) -> str:
    return f.metadata["flag"] or "--" + f.name.replace("_", "-")


@dataclass(frozen=True)
class Bench:
    """A bench: its settings, the function that runs them, its ``--quick`` values and its suite entry."""
    name: str                                        # inshade bench NAME
    doc: str | None                                  # the module docstring: the --help description
    settings: type                                   # a dataclass of option(...) fields
    run: Callable[[object], int | None]              # runs the resolved settings, writes the reports
    sizes: Mapping[str, Size] = field(default_factory=dict)   # suite preset -> Size
    headlines: Callable[[Mapping], list[dict]] | None = None  # the suite's summary rows of the JSON
    claims: Mapping[str, Claim] = field(default_factory=dict)
    quick: Mapping[str, object] = field(default_factory=dict)  # what --quick sets
    quick_keeps_given: bool = False                  # --quick fills only settings left at their defaults
    cold_cache: bool = False                         # Mesa's shader cache off for the run (cold compile times)
    errors: tuple | Callable[[], tuple] = (BenchError,)   # exceptions that become `inshade: error:` lines
                                                     # (a function: imported only when the bench runs)
    prog: str | None = None                          # the usage line's command (default inshade bench NAME)
    formatter: type = argparse.HelpFormatter

    def __post_init__(self):
        names = {f.name for f in dataclasses.fields(self.settings)}
        for what, values in [("quick", self.quick), *((f"sizes[{p!r}]", s.values) for p, s in self.sizes.items())]:
            unknown = set(values) - names
            if unknown:
                raise TypeError(f"{self.name}: {what} sets unknown settings {sorted(unknown)}")
        unknown = set(self.sizes) - set(PRESETS)
        if unknown:
            raise TypeError(f"{self.name}: sizes for unknown presets {sorted(unknown)} (known: {', '.join(PRESETS)})")

    # -- command line ------------------------------------------------------------------------

    def add_arguments(self, parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
        hints = typing.get_type_hints(self.settings)
        for f in dataclasses.fields(self.settings):
            meta = f.metadata
            kind, _, sequence = scalar_type(hints[f.name])
            kw = {"default": self._default(f, hints), "help": meta["help"]}
            if kind is bool:
                kw["action"] = "store_true"
            else:
                kw["type"] = meta["parse"] or kind
                if sequence and meta["parse"] is None:
                    kw["nargs"] = meta["nargs"] or "+"
            for key in ("choices", "metavar", "required"):
                if meta[key]:
                    kw[key] = meta[key]
            if meta["positional"]:
                del kw["default"]   # argparse's own value when left off, as a trainer's positional
                parser.add_argument(f.name, **{"metavar": meta["positional"], **kw})
            else:
                parser.add_argument(_spelling(f), dest=f.name, **kw)
        return parser

    @staticmethod
    def _default(f: dataclasses.Field, hints: Mapping):
        """A field's default as the parsed options hold it (a list field's tuple default as a list)."""
        return list(f.default) if typing.get_origin(hints[f.name]) is list else f.default

    def resolve(self, args):
        """The Settings of parsed ``args``, ``--quick`` applied."""
        settings = self.settings(**{f.name: getattr(args, f.name) for f in dataclasses.fields(self.settings)})
        return self.apply_quick(settings)

    def apply_quick(self, settings):
        """``settings`` with the ``--quick`` values where it asks for them (all of them, or with
        ``quick_keeps_given`` those still at their defaults); the same object, changed in place."""
        if getattr(settings, "quick", False):
            hints = typing.get_type_hints(self.settings)
            defaults = {f.name: self._default(f, hints) for f in dataclasses.fields(self.settings)}
            for name, value in self.quick.items():
                if not self.quick_keeps_given or getattr(settings, name) == defaults[name]:
                    setattr(settings, name, value)
        return settings

    def main(self, argv=None) -> int:
        argv = list(sys.argv[1:] if argv is None else argv)
        return command.main(self.prog or f"inshade bench {self.name}", self.doc, self.add_arguments,
                            self._run, argv,
                            errors=self.errors() if callable(self.errors) else self.errors, formatter=self.formatter)

    def _run(self, args) -> int | None:
        # Cold compile times: Mesa's on-disk shader cache would otherwise hide the JIT on re-runs
        # (effective for the GL contexts this run makes first).
        with cold_shader_cache() if self.cold_cache else contextlib.nullcontext():
            return self.run(self.resolve(args))

    # -- inshade bench suite -----------------------------------------------------------------

    def argv(self, values: Mapping[str, object]) -> tuple[str, ...]:
        """The command line that sets ``values`` (a preset's), in their order."""
        fields = {f.name: f for f in dataclasses.fields(self.settings)}
        out: list[str] = []
        for name, value in values.items():
            f = fields[name]
            if f.metadata["positional"]:
                out += [str(v) for v in value] if isinstance(value, (list, tuple)) else [str(value)]
            elif value is True:
                out.append(_spelling(f))
            elif isinstance(value, (list, tuple)):
                words = [str(v) for v in value]
                out += [_spelling(f), ",".join(words)] if f.metadata["parse"] else [_spelling(f), *words]
            else:
                out += [_spelling(f), str(value)]
        return tuple(out)

    @property
    def suite(self) -> SuiteEntry:
        return SuiteEntry(sizes={p: Sizing(self.argv(s.values), s.budget_s) for p, s in self.sizes.items()},
                          headlines=self.headlines, claims=self.claims)
