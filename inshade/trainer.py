"""The trainer contract: a technique's settings are one typed dataclass, its presets are data, and
this layer makes the rest -- the ``inshade train NAME`` options, ``--preset`` and ``--device``,
the asset folder (``-o``/``--force``), the recorded command line, ``metrics.json`` and the
one-line errors.

    @dataclass(frozen=True)
    class Settings:
        image: str = setting(None, "image file or skimage:NAME", positional="IMAGE")
        ratio: float = setting(6.0, "compression ratio vs 8-bit")
        steps: int = setting(1500, "training steps")

    TRAINER = Trainer("di_texture", __doc__, Settings, presets={"quick": {}, "ship": {"steps": 12000}},
                      train=build, folder=lambda s: f"di_texture_{s.image}")
    add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main

Resolution, one rule for every trainer: an option given on the command line wins, else the
preset's value, else the field's default. ``preset_settings(preset, asset)`` is what ``--preset
PRESET`` resolves to with no other option (plus a shipped asset's own inputs, ``ship_assets``):
what a shipped asset's ``metrics.json`` records, so ``--preset ship`` with those inputs rebuilds it.

Presets may differ per value of one setting (``preset_by="which"``: ``presets[preset][value]``, the
learned BRDF's ggx and disney recipes), and a setting may belong to some values of another only
(``only={"which": ("disney",)}``): it is not recorded for the others, and refused there when given.
"""
from __future__ import annotations

import argparse
import collections
import dataclasses
import inspect
import json
import shlex
import sys
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from inshade import asset_folder, command
from inshade.devices import DeviceError, add_device_argument
from inshade.files import atomic_write


class SettingError(ValueError):
    """An option given for a run it does not belong to."""


class _Given(tuple):
    """The values "any value but None": ``only={"gltf": GIVEN}`` makes a setting belong to the runs
    that give that other setting (e.g. a material index only where a file is named)."""

    def __contains__(self, value) -> bool:
        return value is not None


GIVEN = _Given(("given",))


def setting(default, help: str, *, choices=None, positional: str | None = None, flag: str | None = None,
            metavar: str | None = None, only: Mapping[str, tuple] | None = None):
    """A settings field: its default, its ``--help`` line, the values it may take, and how the
    command line spells it (``positional="IMAGE"``: a positional argument; ``flag``: another
    option name than ``--field-name``). ``only={"which": ("disney",)}``: a setting of those values
    of another setting only (``GIVEN``: of the runs that give it)."""
    return field(default=default, metadata={"help": help, "choices": choices, "positional": positional,
                                            "flag": flag, "metavar": metavar, "only": only})


# The fit settings many trainers share, each worded once; a trainer whose steps, batch or rate
# mean something of its own (per head, BRDF samples, a decoder's rate) words its own ``setting``.
def steps_setting(default):
    return setting(default, "training steps")


def lr_setting(default):
    return setting(default, "Adam learning rate")


def batch_setting(default):
    return setting(default, "samples per step")


def seed_setting(default=0):
    return setting(default, "random seed")


def precision_setting(default: str | None = "f32", only: Mapping[str, tuple] | None = None):
    return setting(default, "dense weight storage: f32, f16 or i8; below f32 the fit ends with a quantization-aware "
                            "fine-tune (models/quantize_aware.py)", choices=("f32", "f16", "i8"), only=only)


def finetune_setting(default: int = 200, only: Mapping[str, tuple] | None = None):
    return setting(default, "steps of the quantization-aware fine-tune (precision f16 or i8)", only=only)


def check_fit(settings, error: type[Exception]) -> None:
    """Refuse negative ``--steps`` or an empty ``--batch`` with the technique's ``error``."""
    if settings.steps < 0 or settings.batch < 1:
        raise error("--steps must be >= 0 and --batch >= 1")


def print_notes(notes) -> None:
    """What loading an input changed (a resize, a channel count), one ``inshade: note:`` line each."""
    for n in notes:
        print(f"inshade: note: {n}", file=sys.stderr)


def without_history(metrics: Mapping) -> dict:
    """A fit's metrics less the per-step ``history``: the summary metrics.json records."""
    return {k: v for k, v in metrics.items() if k != "history"}


def _applies(f: dataclasses.Field, values: Mapping) -> bool:
    """Whether the setting ``f`` belongs to a run of these setting ``values`` (its ``only``)."""
    only = f.metadata.get("only")
    return not only or all(values[name] in allowed for name, allowed in only.items())


def recorded(settings) -> dict:
    """The settings a run records: every field that belongs to it."""
    values = dataclasses.asdict(settings)
    return {f.name: values[f.name] for f in dataclasses.fields(settings) if _applies(f, values)}


def _told_per_preset(values: Mapping[tuple, object]) -> str:
    """A setting's value under each (preset, preset_by value): per preset its most common value, then
    the values of the preset_by choices that differ ("ship: 40000, prt_plants 60000")."""
    out = []
    for preset in dict.fromkeys(p for p, _ in values):
        mine = {c: v for (p, c), v in values.items() if p == preset}
        if len(mine) == 1:     # a setting of one choice only: name it
            (c, v), = mine.items()
            out.append(f"{preset} {c}: {_shown(v)}" if c is not None else f"{preset}: {_shown(v)}")
            continue
        common = collections.Counter(map(repr, mine.values())).most_common(1)[0][0]
        usual = next(v for v in mine.values() if repr(v) == common)
        odd = ", ".join(f"{c} {_shown(v)}" for c, v in mine.items() if repr(v) != common)
        out.append(f"{preset}: {_shown(usual)}" + (f", {odd}" if odd else ""))
    return "; ".join(out)


def scalar_type(annotation) -> tuple[type, bool, bool]:
    """(element type, optional, a sequence) of a field annotation such as ``int | None`` or
    ``tuple[float, ...]``."""
    args = typing.get_args(annotation)
    optional = type(None) in args
    if optional:
        annotation = next(a for a in args if a is not type(None))
    origin = typing.get_origin(annotation)
    if origin in (tuple, list):
        return typing.get_args(annotation)[0], optional, True
    if origin in (typing.Union, types.UnionType):
        raise TypeError(f"setting type {annotation!r}: one type (optionally | None) per setting")
    return annotation, optional, False


@dataclass(frozen=True)
class Run:
    """One resolved training run, handed to the technique's ``train``."""
    settings: object                  # the technique's Settings instance
    preset: str
    device: object                    # torch.device (resolved before any work)
    out: Path                         # the claimed asset folder
    command: str                      # the command line as the user would type it again
    args: argparse.Namespace          # the parsed options (the technique's extra options too)

    def record(self) -> dict:
        """What metrics.json records about the run: command, preset and resolved settings."""
        return {"command": self.command, "preset": self.preset, "settings": recorded(self.settings)}

    def write_metrics(self, metrics: Mapping, name: str = "metrics.json") -> Path:
        """``out/metrics.json``: the run's record, then ``metrics`` (written atomically)."""
        path = self.out / name
        atomic_write(path, json.dumps({**self.record(), **metrics}, indent=1) + "\n")
        return path

    def finish(self, out: Path, metrics: Mapping, summary: str) -> int:
        """A fit's end: metrics.json records ``metrics`` less the per-step history, and one line says
        what was written (``summary``: the numbers that matter). Returns the exit status."""
        self.write_metrics(without_history(metrics))
        print(f"wrote {out}: {summary}")
        return 0


@dataclass(frozen=True)
class Trainer:
    """A technique's trainer: settings, presets and the function that trains and writes."""
    name: str                                        # inshade train NAME
    doc: str | None                                  # the module docstring: the --help description
    settings: type                                   # a dataclass of setting(...) fields
    presets: Mapping[str, Mapping]                   # preset -> the fields it sets (-> value -> fields: preset_by)
    train: Callable[[Run], int | None]               # trains, writes run.out, prints its summary
    folder: Callable[..., str]                       # settings (, args) -> the default asset folder's name
    default_preset: str = "quick"
    ship_assets: Mapping[str, Mapping] = field(default_factory=dict)   # shipped folder -> its inputs
    extra_arguments: Callable[[argparse.ArgumentParser], None] | None = None   # options that are not settings
    check: Callable[[object], None] | None = None    # raises the technique's error for a bad setting
    errors: tuple = ()                               # exceptions that become `inshade: error:` lines
    preset_by: str | None = None                     # presets differ per this setting's value
    resume: tuple[str, ...] = ()                     # the run's own checkpoint files: a folder holding
                                                     # only them is an unfinished run, not an asset
    folder_hint: str | None = None                   # the default folder's name in --help (e.g. NAME_<image>)

    def __post_init__(self):
        names = {f.name for f in dataclasses.fields(self.settings)}
        if self.preset_by is not None and self.preset_by not in names:
            raise TypeError(f"{self.name}: preset_by {self.preset_by!r} is not a setting")
        for preset, table in self.presets.items():
            for values in (table.values() if self.preset_by else (table,)):
                unknown = set(values) - names
                if unknown:
                    raise TypeError(f"{self.name}: preset {preset!r} sets unknown settings {sorted(unknown)}")
        if self.default_preset not in self.presets:
            raise TypeError(f"{self.name}: default preset {self.default_preset!r} is not one of {list(self.presets)}")

    # -- resolution --------------------------------------------------------------------------

    def defaults(self, preset: str, choice=None) -> dict:
        """Every setting's value under ``preset`` with no option given (``choice``: the ``preset_by``
        setting's value; unset, the preset's first)."""
        if preset not in self.presets:
            raise ValueError(f"--preset: {preset!r} is not one of {', '.join(self.presets)}")
        values = self.presets[preset]
        if self.preset_by is not None:
            choice = next(iter(values)) if choice is None else choice
            values = {self.preset_by: choice, **values[choice]}
        return {f.name: values.get(f.name, f.default) for f in dataclasses.fields(self.settings)}

    def preset_settings(self, preset: str, asset: str | None = None) -> dict:
        """What ``--preset PRESET`` resolves to (what metrics.json records as "settings") for the
        shipped asset folder ``asset`` (its own inputs from ``ship_assets``)."""
        inputs = self.ship_assets[asset] if asset else {}
        values = {**self.defaults(preset, inputs.get(self.preset_by) if self.preset_by else None), **inputs}
        values = {f.name: values[f.name] for f in dataclasses.fields(self.settings) if _applies(f, values)}
        return json.loads(json.dumps(values))     # as metrics.json holds them (a tuple reads back as a list)

    def resolve(self, args: argparse.Namespace):
        """The Settings instance of parsed ``args``: option given, else preset, else default."""
        values = self.defaults(args.preset, getattr(args, self.preset_by) if self.preset_by else None)
        given = [f for f in dataclasses.fields(self.settings) if getattr(args, f.name) is not None]
        for f in given:
            value = getattr(args, f.name)
            values[f.name] = tuple(value) if isinstance(value, list) else value
        for f in given:
            if not _applies(f, values):
                wanted = " and ".join(f"{name} {' or '.join(map(str, allowed))}"
                                      for name, allowed in f.metadata["only"].items())
                raise SettingError(f"{_spelling(f)}: only with {wanted}")
        settings = self.settings(**values)
        if self.check is not None:
            self.check(settings)
        return settings

    # -- command line ------------------------------------------------------------------------

    def add_arguments(self, parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
        hints = typing.get_type_hints(self.settings)
        choices = {p: list(table) if self.preset_by else [None] for p, table in self.presets.items()}
        shown = {(p, c): self.defaults(p, c) for p, cs in choices.items() for c in cs}
        for f in dataclasses.fields(self.settings):
            meta = f.metadata
            kind, optional, sequence = scalar_type(hints[f.name])
            per_preset = {k: v[f.name] for k, v in shown.items() if _applies(f, v)}
            if f.name == self.preset_by:    # its help says what it defaults to
                told = None if f.default is None else f"default {_shown(f.default)}"
            elif len(set(map(repr, per_preset.values()))) > 1:
                told = _told_per_preset(per_preset)
            else:
                told = f"default {_shown(next(iter(per_preset.values()), f.default))}"
            required = meta["positional"] and f.default is None
            kw = dict(help=meta["help"] if required or told is None else f"{meta['help']} ({told})", default=None,
                      choices=meta["choices"])
            if meta["metavar"]:
                kw["metavar"] = meta["metavar"]
            if kind is bool:
                kw.pop("choices")
                kw["action"] = argparse.BooleanOptionalAction
            else:
                kw["type"] = kind
                if sequence:
                    kw["nargs"] = "+"
            if meta["positional"]:
                kw.pop("default")
                if not required:
                    kw["nargs"] = "?"
                parser.add_argument(f.name, metavar=meta["positional"], **kw)
            else:
                parser.add_argument(_spelling(f), dest=f.name, **kw)
        parser.add_argument("--preset", choices=list(self.presets), default=self.default_preset,
                            help=f"{self.preset_help()} (default %(default)s)")
        asset_folder.add_arguments(parser, self.folder_hint or f"{self.name}_<name>")
        add_device_argument(parser)
        if self.extra_arguments is not None:
            self.extra_arguments(parser)
        return parser

    def preset_help(self) -> str:
        def listed(values):
            return ", ".join(f"{k} {_shown(v)}" for k, v in values.items()) or "the defaults"

        if self.preset_by is None:
            parts = [f"{p} = {listed(values)}" for p, values in self.presets.items()]
        else:
            parts = [f"{p} = " + " / ".join(f"{c}: {listed(values)}" for c, values in table.items())
                     for p, table in self.presets.items()]
        return "settings by name: " + "; ".join(parts) + "; an option given explicitly wins"

    def run(self, args: argparse.Namespace, argv: list[str]) -> int:
        from inshade.devices import resolve_device

        device = resolve_device(args.device)     # first: a missing CUDA device fails before any work
        settings = self.resolve(args)
        takes_args = len(inspect.signature(self.folder).parameters) > 1     # a name from an input option
        name = self.folder(settings, args) if takes_args else self.folder(settings)
        out = asset_folder.claim(args.out, name, force=args.force, resume=self.resume)
        run = Run(settings, args.preset, device, out, shlex.join(["inshade", "train", self.name, *argv]), args)
        return int(self.train(run) or 0)

    def main(self, argv=None) -> int:
        argv = list(sys.argv[1:] if argv is None else argv)
        return command.main(f"inshade train {self.name}", self.doc, self.add_arguments,
                            lambda args: self.run(args, argv), argv,
                            errors=(DeviceError, SettingError, *self.errors))


def _spelling(f: dataclasses.Field) -> str:
    """How the command line spells the setting ``f``."""
    return f.metadata["positional"] or f.metadata["flag"] or "--" + f.name.replace("_", "-")


def _shown(value) -> str:
    if isinstance(value, float) and value.is_integer() and abs(value) >= 1:
        return f"{value:g}"
    return str(value)
