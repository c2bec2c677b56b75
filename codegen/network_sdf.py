"""GLSL for network SDFs: any bundle with 3 inputs and 1 output (an MLP fitted to a mesh, a
lookup-array cascade, ...) becomes the ``sdf_scene`` chunk that ``shaders/lib/sdf.glsl`` includes,
so every SDF pass (sdf_diffuse, the PRT passes) traces it exactly as it traces an analytic scene.

The contract (torch twin: models/network_sdf.py ``NetworkSdfModule``), stored in the bundle as
``meta["render"]["sdf"] = {"center": [x, y, z], "radius": r, "trace": {...}, "albedo": [r, g, b]}``:

- the network sees the position normalised to the unit ball of the bound sphere,
  ``q = (p - center) * (1 / radius)`` (the reciprocal rounded to float32 once, no division);
- its single output is a distance in *normalised* units; ``scene_sdf`` returns it times
  ``radius``, so distances, ``hit_eps`` and ``normal_eps`` are in world units like an analytic
  scene's;
- ``trace`` takes the analytic scenes' fields (geometry/sdf.py TRACE_DEFAULTS: max_steps,
  step_scale, hit_eps, normal_eps); a network is not an exact distance, so its ``step_scale``
  should come from a Lipschitz bound (the MLP SDF trainer picks ``min(0.9, 1 / L)``);
- ``albedo`` is one constant colour (linear RGB).

``network_sdf_chunks`` returns two chunks: ``sdf_scene`` (the defines, ``scene_sdf``,
``scene_albedo``) which includes ``sdf_network`` (codegen/network.py's output). Bind the
``Generated``'s resources (weight textures, UBOs, lookup textures) with
``viewer.network.NetworkResources``. Same bundle and options -> same bytes. numpy only.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from inshade.bundle import Bundle, BundleError
from inshade.geometry.sdf import DEFAULT_ALBEDO, TRACE_DEFAULTS, f32

from .constants import constant_lines, literal
from .glsl import flt
from .network import Generated, generate
from .sdf import SDF_CHUNK

NETWORK_CHUNK = "sdf_network"
DEFAULT_PREFIX = "sdfnet"   # sdfnet_eval: clear of lib/sdf's sdf_* functions


@dataclass
class NetworkSdfScene:
    """What lib/sdf and models/sdf need of a scene besides the distance itself (the analytic
    ``SdfScene``'s ``center``/``radius``/``trace``/``name``), plus the constant albedo."""

    center: tuple = (0.0, 0.0, 0.0)
    radius: float = 1.0
    trace: dict = field(default_factory=lambda: dict(TRACE_DEFAULTS))
    albedo: tuple = DEFAULT_ALBEDO
    name: str = ""

    def __post_init__(self):
        self.center = tuple(f32(c) for c in self.center)
        self.radius = f32(self.radius)
        self.albedo = tuple(f32(c) for c in self.albedo)
        self.trace = check_trace({**TRACE_DEFAULTS, **dict(self.trace)})

    @property
    def inv_radius(self) -> float:
        """float32(1 / radius): the normalisation multiplies by it (no division, see codegen/sdf.py)."""
        return f32(1.0 / float(self.radius))

    def to_dict(self) -> dict:
        """The bundle's ``render.sdf`` metadata."""
        return {"center": list(self.center), "radius": self.radius, "trace": dict(self.trace),
                "albedo": list(self.albedo)}

    @classmethod
    def from_bundle(cls, bundle: Bundle) -> "NetworkSdfScene":
        """Read ``render.sdf``; BundleError names the file and the field."""
        where = check_io(bundle)
        meta = (bundle.meta.get("render") or {}).get("sdf")
        if not isinstance(meta, dict):
            raise BundleError(where, "render.sdf", "missing: a network SDF needs {center, radius, trace, albedo}")
        extra = sorted(set(meta) - {"center", "radius", "trace", "albedo"})
        if extra:
            raise BundleError(where, f"render.sdf.{extra[0]}", "unknown field (known: albedo, center, radius, trace)")
        center = _numbers(meta.get("center"), 3, where, "render.sdf.center")
        (radius,) = _numbers([meta.get("radius")], 1, where, "render.sdf.radius")
        if radius <= 0:
            raise BundleError(where, "render.sdf.radius", f"must be > 0, got {radius}")
        albedo = _numbers(meta.get("albedo", list(DEFAULT_ALBEDO)), 3, where, "render.sdf.albedo")
        trace = meta.get("trace", {})
        if not isinstance(trace, dict):
            raise BundleError(where, "render.sdf.trace", "must be an object")
        try:
            trace = check_trace({**TRACE_DEFAULTS, **trace})
        except ValueError as exc:
            raise BundleError(where, "render.sdf." + str(exc).split(":", 1)[0], str(exc).split(": ", 1)[-1]) from None
        return cls(tuple(center), radius, trace, tuple(albedo), bundle.name)


def check_io(bundle: Bundle):
    """A network SDF maps 3 inputs to 1 output (BundleError otherwise); returns the bundle's file."""
    where = bundle.path / "bundle.json" if bundle.path else "<bundle>"
    if bundle.in_dim != 3 or bundle.out_dim != 1:
        raise BundleError(where, "inputs" if bundle.in_dim != 3 else "outputs",
                          f"a network SDF maps 3 inputs to 1 output, this bundle has "
                          f"{bundle.in_dim} -> {bundle.out_dim}")
    return where


def check_trace(trace: dict) -> dict:
    """Sphere-tracing settings as geometry/sdf.py accepts them; ValueError 'trace.FIELD: ...'."""
    out = {}
    for k, v in trace.items():
        if k not in TRACE_DEFAULTS:
            raise ValueError(f"trace.{k}: unknown field (known: {', '.join(TRACE_DEFAULTS)})")
        if k == "max_steps":
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 1 <= v <= 1024:
                raise ValueError(f"trace.max_steps: must be an int in 1..1024, got {v!r}")
            out[k] = int(v)
        else:
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"trace.{k}: must be a finite number > 0, got {v!r}")
            out[k] = f32(v)
    if out["step_scale"] > 1.0:
        raise ValueError(f"trace.step_scale: must be in (0, 1], got {out['step_scale']}")
    return out


def _numbers(v, n, where, fld) -> list[float]:
    if not isinstance(v, (list, tuple)) or len(v) != n or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v):
        raise BundleError(where, fld, f"must be {n} finite number{'s' if n > 1 else ''}, got {v!r}")
    return [float(x) for x in v]


NORMAL_TAPS = 6   # lib/sdf's SDF_NORMAL_TAPS: central differences on three axes


def network_sdf_chunk(scene: NetworkSdfScene, generated: Generated) -> str:
    """The ``sdf_scene`` chunk around a generated network (its function from ``generated``), in the
    network's language (GLSL, or WGSL where it was generated for WebGPU)."""
    tr = scene.trace
    constants = [("SDF_MAX_STEPS", "int", tr["max_steps"]), ("SDF_STEP_SCALE", "float", tr["step_scale"]),
                 ("SDF_HIT_EPS", "float", tr["hit_eps"]), ("SDF_NORMAL_EPS", "float", tr["normal_eps"]),
                 ("SDF_BOUND_CENTER", "vec3", scene.center), ("SDF_BOUND_RADIUS", "float", scene.radius)]
    wgsl = generated.plan.target == "wgsl"
    head = ["// Generated by inshade.codegen.network_sdf from a network SDF bundle. Do not edit.",
            f"// scene: {scene.name or '(unnamed)'}; distance = radius * net((p - center) * (1 / radius))",
            *([] if wgsl else [f"#include <{NETWORK_CHUNK}>"]),
            *constant_lines(constants, "wgsl" if wgsl else "glsl"), ""]
    albedo = literal("vec3", scene.albedo, "wgsl" if wgsl else "glsl")
    if wgsl:
        body = ["fn scene_sdf(p: vec3<f32>/*net_textures*/) -> f32 {",
                f"    var x: array<vec4<f32>, {generated.in_blocks}>;",
                f"    x[0] = vec4<f32>((p - SDF_BOUND_CENTER) * {flt(scene.inv_radius)}, 0.0);",
                f"    let y = {generated.function}(x/*net_texture_names*/);",
                "    return y[0].x * SDF_BOUND_RADIUS;", "}", "",
                "fn scene_albedo(p: vec3<f32>) -> vec3<f32> {", f"    return {albedo};", "}", ""]
    else:
        body = ["float scene_sdf(vec3 p) {",
                f"    vec4 x[{generated.in_blocks}];",
                f"    vec4 y[{generated.out_blocks}];",
                f"    x[0] = vec4((p - SDF_BOUND_CENTER) * {flt(scene.inv_radius)}, 0.0);",
                f"    {generated.function}(x, y);",
                "    return y[0].x * SDF_BOUND_RADIUS;", "}", "",
                "vec3 scene_albedo(vec3 p) {", f"    return {albedo};", "}", ""]
    return "\n".join(head + body)


def network_sdf_chunks(bundle: Bundle, prefix: str = DEFAULT_PREFIX, scene: NetworkSdfScene | None = None,
                       **generate_options) -> tuple[dict[str, str], Generated]:
    """(``chunks=`` for a program that includes lib/sdf, the network's ``Generated``).
    ``generate_options`` go to ``codegen.network.generate`` (storage, target, lut_filter, ...);
    ``scene`` overrides the bundle's ``render.sdf`` (e.g. a torch module's, before export)."""
    check_io(bundle)
    scene = scene if scene is not None else NetworkSdfScene.from_bundle(bundle)
    calls = int(scene.trace["max_steps"]) + NORMAL_TAPS   # sdf_hit's loop: the march, then the taps
    generated = generate(bundle, prefix=prefix, calls=calls, **generate_options)
    return {SDF_CHUNK: network_sdf_chunk(scene, generated), NETWORK_CHUNK: generated.chunk}, generated
