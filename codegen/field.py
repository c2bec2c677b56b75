"""A radiance field's march settings (a network mapping position + direction, 6 lanes, to rgb +
density, 4 lanes), as the chunk ``field_config`` that ``shaders/lib/field_march`` reads, in GLSL
defines or WGSL constants: what the field pass of your own networks (``inshade.export(..., as_="field")``)
and export-three's material march with.

The bundle holds them as ``meta["render"]["field"]``: ``box`` [[x, y, z], [x, y, z]] (world bounds
the network is marched through), ``step`` (dt, world units), ``max_steps``, ``background`` [r, g, b].
"""
from __future__ import annotations

from .constants import constant_lines

CHUNK = "field_config"
STOP = 1e-3      # the march stops once transmittance falls below this


def _number(v, lo, hi, where, what):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo < v <= hi:
        raise ValueError(f"{where}: render.field.{what}: must be a number in ({lo:g}, {hi:g}], got {v!r}")
    return float(v)


def field_settings(bundle) -> dict:
    """The march of a field bundle's ``render.field``, checked; ValueError naming the field."""
    where = f"bundle {bundle.name!r}"
    if bundle.in_dim != 6 or bundle.out_dim != 4:
        raise ValueError(f"{where}: a field maps position + direction (6 lanes) to rgb + density (4 lanes); it has "
                         f"{bundle.in_dim} -> {bundle.out_dim}")
    spec = (bundle.meta.get("render") or {}).get("field")
    if not isinstance(spec, dict):
        raise ValueError(f"{where}: render.field: missing ({{box, step, max_steps, background}})")
    box = spec.get("box")
    if (not isinstance(box, list) or len(box) != 2 or not all(isinstance(c, list) and len(c) == 3 for c in box)
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for c in box for v in c)
            or not all(a < b for a, b in zip(*box))):
        raise ValueError(f"{where}: render.field.box: must be [[x0, y0, z0], [x1, y1, z1]] with x0 < x1 ..., "
                         f"got {box!r}")
    bg = spec.get("background", [0.0, 0.0, 0.0])
    if not isinstance(bg, list) or len(bg) != 3 or not all(isinstance(v, (int, float)) for v in bg):
        raise ValueError(f"{where}: render.field.background: must be [r, g, b], got {bg!r}")
    steps = spec.get("max_steps")
    if isinstance(steps, bool) or not isinstance(steps, int) or not 1 <= steps <= 4096:
        raise ValueError(f"{where}: render.field.max_steps: must be an int in 1..4096, got {steps!r}")
    return {"box": [[float(v) for v in c] for c in box], "step": _number(spec.get("step"), 0.0, 1e6, where, "step"),
            "max_steps": steps, "background": [float(v) for v in bg]}


def _values(s: dict) -> list[tuple[str, str, object]]:
    """(name, type, value) of every setting the march reads."""
    return [("FIELD_BOX_LO", "vec3", s["box"][0]), ("FIELD_BOX_HI", "vec3", s["box"][1]),
            ("FIELD_STEP", "float", s["step"]), ("FIELD_MAX_STEPS", "int", s["max_steps"]),
            ("FIELD_STOP", "float", STOP), ("FIELD_BACKGROUND", "vec3", s["background"])]


def field_chunks(bundle, language: str = "glsl") -> dict:
    """{"field_config": the settings of the field ``bundle``} as GLSL defines or WGSL constants."""
    return {CHUNK: "\n".join(constant_lines(_values(field_settings(bundle)), language)) + "\n"}
