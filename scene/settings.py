"""The knobs a UI may turn: a scene's ``"settings"``, each bound to exactly one thing its value drives
(a uniform, a define, a codegen option, the environment, the per-frame hook or the present pass),
with its type, range or choices; and the built-in codegen options every scene has."""
from __future__ import annotations

import math
from dataclasses import dataclass

from inshade import technique
from inshade.codegen import FILTERS, OPENGL_STORAGE_MODES, OPTIONS, SHORTHANDS

from .common import SceneError
from .tonemap import TONEMAPS

SETTING_TYPES = ("float", "int", "bool", "choice")
# "frame": read only by the program's per-frame hook (ProgramSpec.frame), which turns it into uniforms.
# "present": a uniform of the present pass (the window, the page) that PNGs follow too, never seen by the
# float image (the tone mapper).
BINDINGS = ("uniform", "define", "codegen", "environment", "frame", "present")
# "environment" settings drive the lighting the renderer computes on the CPU (SDF scenes: the
# radiance SH uniform u_sh); a change re-uploads a uniform, no recompile.
ENVIRONMENT_TARGETS = ("sky", "rotation", "intensity")
# Codegen options a setting may drive: "<component type>.<option>" (codegen.OPTIONS) or a shorthand
# ("storage", "lut_filter", codegen.SHORTHANDS) -> its choices.
CODEGEN_OPTIONS = {**{f"{t}.{name}": choices for t, opts in OPTIONS.items() for name, (choices, _) in opts.items()},
                   **{short: OPTIONS[t][name][0] for short, (t, name) in SHORTHANDS.items()}}
# the fields a setting may have
SETTING_KEYS = {"type", "default", "min", "max", "choices", "label", "exposed", *BINDINGS}


def codegen_option_path(target: str) -> tuple[str, str]:
    """(component type, option) a setting's ``codegen`` target names."""
    return SHORTHANDS[target] if target in SHORTHANDS else tuple(target.split(".", 1))


# Codegen options every scene has, even when its file does not expose them in the UI.
BUILTIN_SETTINGS = {
    "storage": {"type": "choice", "default": "auto", "choices": list(OPENGL_STORAGE_MODES), "codegen": "storage",
                "label": "weight storage"},
    "lut_filter": {"type": "choice", "default": "exact", "choices": list(FILTERS), "codegen": "lut_filter",
                   "label": "LUT filtering"},
    # scene labels (scene/labels.py): drawn over the window and the PNG, never in the float image
    "labels": {"type": "bool", "default": True, "frame": "labels", "label": "labels"},
    # the tone mapper of the window, the page and PNGs (scene/tonemap.py); the float image and EXRs stay linear
    "tonemap": {"type": "choice", "default": "none", "choices": list(TONEMAPS), "present": "u_tonemap",
                "label": "tone mapping"},
}


@dataclass
class Setting:
    name: str
    type: str
    default: object
    binding: str              # "uniform" | "define" | "codegen"
    target: str               # uniform name, define name, or generate() keyword
    min: float | None = None
    max: float | None = None
    choices: tuple = ()
    label: str = ""
    exposed: bool = True      # shown in the UI (built-in codegen options are hidden unless declared)
    declared: technique.Choice | None = None   # the program's choice this setting drives (ProgramSpec.choices)

    def index(self, value) -> int:
        """The int a choice value sets on the program: the declared index of a value the program
        declares (an int value of a declared choice is that index already), else its place in
        ``choices``."""
        if self.declared is None:
            return self.choices.index(value)
        return value if isinstance(value, int) else self.declared.index(value)

    def check(self, value, where: str = "setting"):
        """Validate and normalise a value for this setting (SceneError if it does not fit)."""
        w = f"{where} {self.name!r}"
        if self.type == "choice":
            if value not in self.choices:
                raise SceneError(f"{w}: {value!r} is not one of {list(self.choices)}")
            return value
        if self.type == "bool":
            if not isinstance(value, bool) and type(value) is int and value in (0, 1):
                value = bool(value)      # --set labels=0 (the command line parses JSON)
            if not isinstance(value, bool):
                raise SceneError(f"{w}: must be true or false, got {value!r}")
            return value
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise SceneError(f"{w}: must be a finite number, got {value!r}")
        if self.type == "int":
            if int(value) != value:
                raise SceneError(f"{w}: must be an integer, got {value!r}")
            value = int(value)
        else:
            value = float(value)
        if (self.min is not None and value < self.min) or (self.max is not None and value > self.max):
            raise SceneError(f"{w}: {value} is outside [{self.min}, {self.max}]")
        return value


def parse_settings(data, where: str) -> dict:
    """``"settings"``: name -> Setting, the built-in ones first (hidden unless the file declares
    them), each default checked against its own type and range."""
    if not isinstance(data, dict):
        raise SceneError(f"{where}: must be an object {{name: setting}}")
    merged = {k: dict(v, exposed=False) for k, v in BUILTIN_SETTINGS.items()}
    for k, v in data.items():
        merged[k] = dict(v, exposed=True) if isinstance(v, dict) else v
    return {name: _parse_setting(name, s, f"{where}.{name}") for name, s in merged.items()}


def _parse_setting(name: str, s, w: str) -> Setting:
    if not isinstance(s, dict):
        raise SceneError(f"{w}: must be an object")
    kind = s.get("type")
    if kind not in SETTING_TYPES:
        raise SceneError(f"{w}.type: must be one of {list(SETTING_TYPES)}, got {kind!r}")
    binding, target = _binding(s, w)
    extra = sorted(set(s) - SETTING_KEYS)
    if extra:
        raise SceneError(f"{w}.{extra[0]}: unknown field")
    lo, hi = s.get("min"), s.get("max")
    for key, v in (("min", lo), ("max", hi)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))):
            raise SceneError(f"{w}.{key}: must be a number")
    if kind in ("float", "int") and (lo is None or hi is None or lo > hi):
        raise SceneError(f"{w}: a {kind} setting needs a range: \"min\" <= \"max\"")
    choices = s.get("choices", [])
    if not isinstance(choices, list):
        raise SceneError(f"{w}.choices: must be a list, got {choices!r}")
    choices = tuple(choices)
    if kind == "choice":
        if not choices:
            raise SceneError(f"{w}.choices: a choice setting needs a non-empty list")
        if binding == "codegen":
            bad = [c for c in choices if c not in CODEGEN_OPTIONS[target]]
            if bad:
                raise SceneError(f"{w}.choices: {bad[0]!r} is not a {target} option "
                                 f"({', '.join(CODEGEN_OPTIONS[target])})")
    setting = Setting(name, kind, s.get("default"), binding, target, lo, hi, choices,
                      str(s.get("label", name)), bool(s.get("exposed", True)))
    if "default" not in s:
        raise SceneError(f"{w}.default: missing")
    setting.default = setting.check(s["default"], f"{w}.default:")
    return setting


def _binding(s: dict, w: str) -> tuple[str, str]:
    """(binding, target): the one thing a setting's value drives."""
    bound = [b for b in BINDINGS if b in s]
    if len(bound) != 1:
        raise SceneError(f"{w}: needs exactly one of {list(BINDINGS)} (what the value drives)")
    binding = bound[0]
    target = s[binding]
    if not isinstance(target, str) or not (target.isidentifier() or binding == "codegen"):
        raise SceneError(f"{w}.{binding}: must be an identifier, got {target!r}")
    if binding == "environment" and target not in ENVIRONMENT_TARGETS:
        raise SceneError(f"{w}.environment: must be one of {list(ENVIRONMENT_TARGETS)}, got {target!r}")
    if binding == "codegen" and target not in CODEGEN_OPTIONS:
        raise SceneError(f"{w}.codegen: unknown codegen option {target!r} (known: {', '.join(CODEGEN_OPTIONS)})")
    return binding, target


def bind_declared_choices(settings: dict, spec: technique.ProgramSpec) -> None:
    """Settings bound to a uniform or define the program declares a choice for
    (``ProgramSpec.choices``) name only declared values and drive the declared index: a choice
    lists declared names (or declared indices: the index form of a define), an int setting's
    range holds declared indices only."""
    for name, s in settings.items():
        choice = spec.choice(s.target) if s.binding in ("uniform", "define") else None
        if choice is None:
            continue
        w = f"settings.{name}"
        known = ", ".join(choice.values)
        if s.type == "choice":
            bad = [c for c in s.choices if c not in choice.values
                   and not (type(c) is int and c in choice.indices)]
            if bad:
                raise SceneError(f"{w}.choices: {bad[0]!r} is not a {s.target} value of {spec.program} "
                                 f"(known: {known})")
        elif s.type == "int":
            bad = [i for i in range(int(s.min), int(s.max) + 1) if i not in choice.indices]
            if bad:
                raise SceneError(f"{w}: {bad[0]} is not a {s.target} index of {spec.program} "
                                 f"(known: {', '.join(f'{v} {i}' for v, i in zip(choice.values, choice.indices))})")
        else:
            raise SceneError(f"{w}.type: {s.target} is a choice of {spec.program} ({known}): "
                             f"a {s.type} setting cannot drive it")
        s.declared = choice
