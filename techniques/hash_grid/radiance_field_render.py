"""The hash-grid radiance field's pass as the runtime sees it (torch-free: the technique record
imports it): the march settings read from the field bundle's ``render`` metadata, the generated
chunk <radiance_field_config>, the scene check and the program spec.

The bundles (radiance_field.py documents them in full): the field, prefix ``hgrf``, inputs
``x`` [3] (a position in the box, [0, 1]^3) and ``d`` [3] (the unit ray direction), outputs
``density`` [1] and ``rgb`` [3]; the occupancy grid, prefix ``hgocc``, input ``x`` [3], output
``occupancy`` [1], one 3D lookup array of G^3 cells (G = render.occupancy_resolution).

The field bundle's ``render`` (every field required, each checked here with a message naming it):
  aabb                  [[x0, y0, z0], [x1, y1, z1]]: the box in world units, a cube (x = (p - min) / side)
  step                  dt, the march's fixed step in box units, in (0, 1]
  max_steps             samples per ray at most, 1..MAX_STEPS
  background            [r, g, b], linear: what an unoccluded ray sees
  sigma_scale           extinction per box unit = density x sigma_scale, in (0, 1e6)
  occupancy_resolution  G, occupancy cells per box side, 2..MAX_OCCUPANCY
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from inshade.technique import Choice, ProgramSpec, prefixed_bundle

KIND = "hash_grid_radiance_field"
PROGRAM = "passes/radiance_field_hash_grid.frag"
CONFIG_CHUNK = "radiance_field_config"
PREFIX_FIELD, PREFIX_OCCUPANCY = "hgrf", "hgocc"
FIELD_PORTS = ([("x", 3), ("d", 3)], [("density", 1), ("rgb", 3)])
OCCUPANCY_PORTS = ([("x", 3)], [("occupancy", 1)])
STOP = 1e-4            # transmittance that ends a ray (instant-NGP's early termination)
MAX_STEPS = 8192
MAX_OCCUPANCY = 512
# u_hgrf_view (the pass's header says what each draws): the composited radiance, the held-out ground
# truth at the scene's camera, the two split, their difference, or the network evaluations per pixel;
# u_hgrf_empty_space: skip unoccupied cells, or evaluate every sample
VIEWS = ("radiance", "reference", "split", "error", "samples")
EMPTY_SPACE = ("skip", "evaluate")
REFERENCE_UNIFORM = "u_hgrf_reference"     # the scene texture holding the ground truth (8-bit sRGB)
UNIFORM_DEFAULTS = {"u_hgrf_view": VIEWS.index("radiance"), "u_hgrf_empty_space": EMPTY_SPACE.index("skip"),
                    "u_hgrf_split": 0.5, "u_hgrf_error_scale": 10.0}
SETTINGS = {
    "view": {"type": "choice", "default": "radiance", "choices": list(VIEWS), "uniform": "u_hgrf_view",
             "label": "view (split: left reference, right radiance)"},
    "empty_space": {"type": "choice", "default": "skip", "choices": list(EMPTY_SPACE),
                    "uniform": "u_hgrf_empty_space", "label": "empty space (occupancy grid)"},
    "split": {"type": "float", "default": 0.5, "min": 0.0, "max": 1.0, "uniform": "u_hgrf_split",
              "label": "split (reference | radiance)"},
    "error_scale": {"type": "float", "default": 10.0, "min": 1.0, "max": 100.0, "uniform": "u_hgrf_error_scale",
                    "label": "error x"},
}


@dataclass(frozen=True)
class MarchSettings:
    aabb_min: tuple
    side: float
    step: float
    max_steps: int
    background: tuple
    sigma_scale: float
    occupancy_resolution: int
    stop: float = STOP

    @property
    def inv_side(self) -> float:
        return 1.0 / self.side

    def to_render(self) -> dict:
        """The bundle's ``render`` field for these settings."""
        top = [v + self.side for v in self.aabb_min]
        return {"aabb": [list(self.aabb_min), top], "step": self.step, "max_steps": self.max_steps,
                "background": list(self.background), "sigma_scale": self.sigma_scale,
                "occupancy_resolution": self.occupancy_resolution}


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def march_settings(render, where: str) -> MarchSettings:
    """MarchSettings of a field bundle's ``render``; ValueError naming the field (module docstring)."""
    if not isinstance(render, dict):
        raise ValueError(f"{where}: render: must be an object with aabb, step, max_steps, background, "
                         f"sigma_scale and occupancy_resolution, got {render!r}")
    aabb = render.get("aabb")
    if (not isinstance(aabb, (list, tuple)) or len(aabb) != 2
            or not all(isinstance(c, (list, tuple)) and len(c) == 3 and all(map(_number, c)) for c in aabb)):
        raise ValueError(f"{where}: render.aabb: must be [[x0, y0, z0], [x1, y1, z1]] numbers, got {aabb!r}")
    sides = [float(b) - float(a) for a, b in zip(*aabb)]
    if min(sides) <= 0 or max(sides) - min(sides) > 1e-6 * max(sides):
        raise ValueError(f"{where}: render.aabb: must be a cube with max > min (sides {sides})")
    step, steps, bg = render.get("step"), render.get("max_steps"), render.get("background")
    if not _number(step) or not 0.0 < step <= 1.0:
        raise ValueError(f"{where}: render.step: must be a number in (0, 1] (the march's dt in box units), "
                         f"got {step!r}")
    if isinstance(steps, bool) or not isinstance(steps, int) or not 1 <= steps <= MAX_STEPS:
        raise ValueError(f"{where}: render.max_steps: must be an int in 1..{MAX_STEPS}, got {steps!r}")
    if not isinstance(bg, (list, tuple)) or len(bg) != 3 or not all(map(_number, bg)):
        raise ValueError(f"{where}: render.background: must be [r, g, b] numbers, got {bg!r}")
    scale = render.get("sigma_scale")
    if not _number(scale) or not 0.0 < scale < 1e6:
        raise ValueError(f"{where}: render.sigma_scale: must be a number in (0, 1e6) (extinction per box unit "
                         f"= density x sigma_scale), got {scale!r}")
    res = render.get("occupancy_resolution")
    if isinstance(res, bool) or not isinstance(res, int) or not 2 <= res <= MAX_OCCUPANCY:
        raise ValueError(f"{where}: render.occupancy_resolution: must be an int in 2..{MAX_OCCUPANCY} "
                         f"(occupancy cells per box side), got {res!r}")
    return MarchSettings(tuple(float(v) for v in aabb[0]), sides[0], float(step), steps,
                         tuple(float(v) for v in bg), float(scale), res)


def config_chunk(m: MarchSettings) -> str:
    """<radiance_field_config>: the march settings as the defines lib/radiance_field_march reads."""
    from inshade.codegen.glsl import flt

    def vec3(v):
        return f"vec3({', '.join(flt(x) for x in v)})"

    return "\n".join([f"#define HGRF_AABB_MIN {vec3(m.aabb_min)}", f"#define HGRF_INV_SIDE {flt(m.inv_side)}",
                      f"#define HGRF_STEP {flt(m.step)}", f"#define HGRF_MAX_STEPS {m.max_steps}",
                      f"#define HGRF_STOP {flt(m.stop)}", f"#define HGRF_SIGMA_SCALE {flt(m.sigma_scale)}",
                      f"#define HGRF_BACKGROUND {vec3(m.background)}",
                      f"#define HGRF_OCCUPANCY_RES {m.occupancy_resolution}", ""])


def _chunks(scene, bundles, networks, codegen_options) -> dict:
    field = prefixed_bundle(bundles, networks, PREFIX_FIELD, PROGRAM)
    return {CONFIG_CHUNK: config_chunk(march_settings(field.meta.get("render"), f"bundle {field.name!r}"))}


def _ports(bundle):
    return [(p.name, p.dim) for p in bundle.inputs], [(p.name, p.dim) for p in bundle.outputs]


def _spelled(ports) -> str:
    return ", ".join(f"{n}[{d}]" for n, d in ports)


def validate(scene) -> None:
    """Networks hgrf (the field) and hgocc (its occupancy grid) with the ports above; the field's
    march settings; an occupancy grid of render.occupancy_resolution cells per side; the reference
    texture the reference, split and error views read."""
    from inshade.bundle import load

    if not any(t.uniform == REFERENCE_UNIFORM for t in scene.textures):
        raise ValueError(f"textures: {PROGRAM} needs a texture for \"{REFERENCE_UNIFORM}\" (the ground truth at the "
                         f"scene's camera, an 8-bit sRGB image without mipmaps)")
    found = {}
    for prefix, ports, what in ((PREFIX_FIELD, FIELD_PORTS, "the radiance field"),
                                (PREFIX_OCCUPANCY, OCCUPANCY_PORTS, "its occupancy grid")):
        nets = [n for n in scene.networks if n.prefix == prefix]
        if len(nets) != 1:
            raise ValueError(f"networks: {PROGRAM} needs one network with prefix \"{prefix}\" ({what})")
        bundle = load(nets[0].bundle)
        if _ports(bundle) != (ports[0], ports[1]):
            ins, outs = _ports(bundle)
            raise ValueError(f"bundle {bundle.name!r}: {what} must map {_spelled(ports[0])} to {_spelled(ports[1])}; "
                             f"the bundle has inputs {_spelled(ins)} and outputs {_spelled(outs)}")
        found[prefix] = bundle
    field, occupancy = found[PREFIX_FIELD], found[PREFIX_OCCUPANCY]
    m = march_settings(field.meta.get("render"), f"bundle {field.name!r}")
    nodes = [(n.type, list(n.params.get("resolution", []))) for n in occupancy.nodes]
    if nodes != [("lookup_array", [m.occupancy_resolution] * 3)]:
        got = ", ".join(f"{kind} {'x'.join(map(str, res))}".rstrip() for kind, res in nodes)
        raise ValueError(f"bundle {occupancy.name!r}: the occupancy grid must be one 3D lookup_array of "
                         f"{m.occupancy_resolution}^3 cells (the field's render.occupancy_resolution), got {got}")


PROGRAM_SPEC = ProgramSpec(
    PROGRAM, geometry="fullscreen", bundle_kinds=(KIND,), uniforms=UNIFORM_DEFAULTS, chunks=_chunks,
    validate=validate, choices=(Choice("u_hgrf_view", "HGRF_VIEW", VIEWS),
                                Choice("u_hgrf_empty_space", "HGRF_EMPTY", EMPTY_SPACE)))
