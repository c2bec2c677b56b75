"""Analytic SDF scenes as data: one small JSON description, evaluated identically by torch
(models/sdf.py) and by generated GLSL (codegen/sdf.py). numpy only (the runtime is torch-free).

A description file::

    {"format": "inshade.geometry.sdf", "version": 1,
     "bound": {"center": [0, 0, 0], "radius": 2.0},          # sphere tracing only inside it
     "trace": {"max_steps": 256, "step_scale": 0.9, "hit_eps": 1e-3, "normal_eps": 1e-3},
     "root": NODE}

Nodes (``type`` picks one; every node may carry ``"albedo": [r, g, b]`` in [0, 1], linear: the
colour of its subtree's leaves unless a deeper node sets its own; with none at all, 0.8 grey):

- primitives, centred at the origin, y up (Inigo Quilez's exact/bound formulas):
  ``sphere`` {radius} · ``box`` {size: half extents} · ``round_box`` {size, radius}
  (the rounding is inside ``size``) · ``capsule`` {a, b, radius} · ``torus`` {major, minor}
  (in the xz plane) · ``cylinder`` {radius, height: half height, axis y, capped} ·
  ``plane`` {normal, offset}: dot(p, n) - offset, n normalised here.
- booleans over ``children`` (>= 2), left fold, ``k`` >= 0 the smoothing radius (0 = hard):
  ``union`` (polynomial smooth min), ``subtract`` (first child minus the others, smooth max of
  a and -b), ``intersect`` (smooth max). Colours: union/intersect blend with the same weight h
  as the distances; subtract keeps the first child's colour. Hard (k = 0) union/intersect take
  the nearer/farther child's colour, and the first child's on a tie, i.e. where the distances
  are within ``TIE_EPS`` (shared faces: the difference there is rounding, which differs between
  executors).
- ``transform`` {child, translate?, rotate?: {axis, angle (degrees)}, scale? (uniform, > 0)}:
  the child is scaled, then rotated, then translated; evaluated as
  ``q = R^T (p - t) / s``, ``d = s * child(q)``.
- ``repeat`` {child, spacing: [sx, sy, sz] (0 = that axis is not repeated), count: [nx, ny, nz]}:
  finite grid repetition, 2n+1 copies per repeated axis centred at the origin:
  ``q = p - s * clamp(floor(p / s + 0.5), -n, n)``.
- ``repeat_polar`` {child, count}: ``count`` copies around the y axis (the child's sector is
  centred on +x): angle = atan(z, x), folded into [-pi/count, pi/count).

Exactness: repetition and smooth booleans give a bound, not an exact distance; sphere tracing
steps with ``step_scale`` < 1 and stops within the ``bound`` sphere and ``max_steps``. A ray that
grazes an edge or approaches a surface at a shallow angle crawls (each step shrinks by about
``step_scale * sin(angle)``): such rays need up to ~180 steps in the shipped scenes at 512 px, and
one that runs out of steps is a miss, i.e. a sky-coloured hole in a surface (tests/geometry/test_sdf_leaks.py).
Hence the default of 256; only the crawling rays pay for it.

Every problem is one ``SdfError`` naming the file and the field (``root.children[1].radius``).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from inshade.json_header import check_header

DEFAULT_ALBEDO = (0.8, 0.8, 0.8)
PRIMITIVES = ("sphere", "box", "round_box", "capsule", "torus", "cylinder", "plane")
BOOLEANS = ("union", "subtract", "intersect")
NODE_TYPES = PRIMITIVES + BOOLEANS + ("transform", "repeat", "repeat_polar")
TRACE_DEFAULTS = {"max_steps": 256, "step_scale": 0.9, "hit_eps": 1e-3, "normal_eps": 1e-3}
_FIELDS = {
    "sphere": {"radius"}, "box": {"size"}, "round_box": {"size", "radius"},
    "capsule": {"a", "b", "radius"}, "torus": {"major", "minor"}, "cylinder": {"radius", "height"},
    "plane": {"normal", "offset"},
    "union": {"children", "k"}, "subtract": {"children", "k"}, "intersect": {"children", "k"},
    "transform": {"child", "translate", "rotate", "scale"}, "repeat": {"child", "spacing", "count"},
    "repeat_polar": {"child", "count"},
}
_OPTIONAL = {"k", "translate", "rotate", "scale"}


class SdfError(ValueError):
    """An SDF description that cannot be used; the message names the file and the field."""


def f32(v) -> float:
    """The float32 value every executor uses for a constant."""
    return float(np.float32(v))


# hard union/intersect colour ties: distances this close pick the first child (above any rounding
# difference the 1e-5 parity rule allows between executors; far below hit_eps)
TIE_EPS = f32(1e-4)


@dataclass
class Node:
    type: str
    params: dict                     # float32-rounded numbers / tuples, ready for both executors
    children: list = field(default_factory=list)
    albedo: tuple | None = None      # None: inherit the children's colours (operators) / default (leaves)


@dataclass
class SdfScene:
    root: Node
    center: tuple
    radius: float
    trace: dict
    name: str = ""
    path: Path | None = None

    def to_dict(self) -> dict:
        return {"bound": {"center": list(self.center), "radius": self.radius}, "trace": dict(self.trace)}


# parsing ---------------------------------------------------------------------------------------------
def load_sdf(path) -> SdfScene:
    """Read and check an SDF description file (SdfError naming the file and the field)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except OSError as exc:
        raise SdfError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except json.JSONDecodeError as exc:
        raise SdfError(f"{path}: not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") from None
    try:
        scene = parse_sdf(data)
    except SdfError as exc:
        raise SdfError(f"{path}: {exc}") from None
    scene.path = path
    scene.name = scene.name or path.stem
    return scene


def parse_sdf(data) -> SdfScene:
    check_header(data, "inshade.geometry.sdf", ("format", "version", "name", "notes", "bound", "trace", "root"),
                 SdfError)
    bound = data.get("bound")
    if not isinstance(bound, dict):
        raise SdfError("bound: must be {\"center\": [x, y, z], \"radius\": r}")
    center = _vec(bound.get("center"), 3, "bound.center")
    radius = _pos(bound.get("radius"), "bound.radius")
    trace = dict(TRACE_DEFAULTS)
    given = data.get("trace", {})
    if not isinstance(given, dict):
        raise SdfError("trace: must be an object")
    for k, v in given.items():
        if k not in TRACE_DEFAULTS:
            raise SdfError(f"trace.{k}: unknown field (known: {', '.join(TRACE_DEFAULTS)})")
        if k == "max_steps":
            if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= 1024:
                raise SdfError(f"trace.max_steps: must be an int in 1..1024, got {v!r}")
            trace[k] = v
        else:
            trace[k] = _pos(v, f"trace.{k}")
    if not trace["step_scale"] <= 1.0:
        raise SdfError(f"trace.step_scale: must be in (0, 1], got {trace['step_scale']}")
    if "root" not in data:
        raise SdfError("root: missing (the scene's top node)")
    root = parse_node(data["root"], "root")
    return SdfScene(root, center, radius, trace, name=str(data.get("name", "")))


def parse_node(d, where: str) -> Node:
    if not isinstance(d, dict):
        raise SdfError(f"{where}: must be an object with a \"type\"")
    kind = d.get("type")
    if kind not in NODE_TYPES:
        raise SdfError(f"{where}.type: unknown node type {kind!r} (known: {', '.join(NODE_TYPES)})")
    allowed = _FIELDS[kind] | {"type", "albedo", "name"}
    extra = sorted(set(d) - allowed)
    if extra:
        raise SdfError(f"{where}.{extra[0]}: not a field of a {kind} node (fields: {', '.join(sorted(allowed))})")
    missing = sorted(_FIELDS[kind] - _OPTIONAL - set(d))
    if missing:
        raise SdfError(f"{where}.{missing[0]}: missing (a {kind} node needs {', '.join(sorted(_FIELDS[kind] - _OPTIONAL))})")
    albedo = None
    if "albedo" in d:
        albedo = _vec(d["albedo"], 3, f"{where}.albedo")
        if not all(0.0 <= a <= 1.0 for a in albedo):
            raise SdfError(f"{where}.albedo: components must be in [0, 1], got {list(d['albedo'])}")
    p, children = {}, []
    w = lambda k: f"{where}.{k}"  # noqa: E731
    if kind == "sphere":
        p["radius"] = _pos(d["radius"], w("radius"))
    elif kind == "box":
        p["size"] = _vec(d["size"], 3, w("size"), positive=True)
    elif kind == "round_box":
        p["radius"] = _pos(d["radius"], w("radius"), zero=True)
        size = _vec(d["size"], 3, w("size"), positive=True)
        if min(size) <= p["radius"]:
            raise SdfError(f"{w('size')}: every half extent must exceed the rounding radius {p['radius']}")
        p["size"] = size
    elif kind == "capsule":
        p["a"], p["b"] = _vec(d["a"], 3, w("a")), _vec(d["b"], 3, w("b"))
        if p["a"] == p["b"]:
            raise SdfError(f"{w('b')}: must differ from a (use a sphere)")
        p["radius"] = _pos(d["radius"], w("radius"))
    elif kind == "torus":
        p["major"], p["minor"] = _pos(d["major"], w("major")), _pos(d["minor"], w("minor"))
    elif kind == "cylinder":
        p["radius"], p["height"] = _pos(d["radius"], w("radius")), _pos(d["height"], w("height"))
    elif kind == "plane":
        n = np.asarray(_vec(d["normal"], 3, w("normal")), np.float64)
        if np.linalg.norm(n) < 1e-6:
            raise SdfError(f"{w('normal')}: must not be zero")
        p["normal"] = tuple(f32(v) for v in n / np.linalg.norm(n))
        p["offset"] = _num(d["offset"], w("offset"))
    elif kind in BOOLEANS:
        kids = d["children"]
        if not isinstance(kids, list) or len(kids) < 2:
            raise SdfError(f"{w('children')}: must be a list of at least 2 nodes")
        children = [parse_node(c, f"{where}.children[{i}]") for i, c in enumerate(kids)]
        p["k"] = _pos(d.get("k", 0.0), w("k"), zero=True)
    elif kind == "transform":
        children = [parse_node(d["child"], w("child"))]
        p["translate"] = _vec(d.get("translate", [0, 0, 0]), 3, w("translate"))
        rot = d.get("rotate")
        m = np.eye(3)
        if rot is not None:
            if not isinstance(rot, dict) or set(rot) != {"axis", "angle"}:
                raise SdfError(f"{w('rotate')}: must be {{\"axis\": [x, y, z], \"angle\": degrees}}")
            axis = np.asarray(_vec(rot["axis"], 3, w("rotate.axis")), np.float64)
            if np.linalg.norm(axis) < 1e-6:
                raise SdfError(f"{w('rotate.axis')}: must not be zero")
            m = rotation_matrix(axis, math.radians(_num(rot["angle"], w("rotate.angle"))))
        # q = R^T (p - t): rows of R^T, float32, shared by both executors.
        p["inv_rotation"] = tuple(tuple(f32(v) for v in row) for row in m.T)
        p["rotated"] = rot is not None
        p["scale"] = _pos(d.get("scale", 1.0), w("scale"))
    elif kind == "repeat":
        children = [parse_node(d["child"], w("child"))]
        p["spacing"] = _vec(d["spacing"], 3, w("spacing"))
        if any(s < 0 for s in p["spacing"]) or not any(s > 0 for s in p["spacing"]):
            raise SdfError(f"{w('spacing')}: must be >= 0 with at least one axis > 0, got {d['spacing']!r}")
        count = d["count"]
        if not (isinstance(count, list) and len(count) == 3 and all(
                isinstance(c, int) and not isinstance(c, bool) and 0 <= c <= 64 for c in count)):
            raise SdfError(f"{w('count')}: must be 3 ints in 0..64 (copies each side), got {count!r}")
        p["count"] = tuple(float(c) for c in count)
    elif kind == "repeat_polar":
        children = [parse_node(d["child"], w("child"))]
        c = d["count"]
        if isinstance(c, bool) or not isinstance(c, int) or not 1 <= c <= 256:
            raise SdfError(f"{w('count')}: must be an int in 1..256, got {c!r}")
        p["count"] = c
        p["sector"] = f32(2.0 * math.pi / c)
        p["inv_sector"] = f32(c / (2.0 * math.pi))
    return Node(kind, p, children, albedo)


def rotation_matrix(axis, angle: float) -> np.ndarray:
    """Right-handed rotation by ``angle`` radians about ``axis`` (Rodrigues), float64."""
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def _num(v, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise SdfError(f"{where}: must be a finite number, got {v!r}")
    return f32(v)


def _pos(v, where: str, zero: bool = False) -> float:
    x = _num(v, where)
    if x < 0 or (x == 0 and not zero):
        raise SdfError(f"{where}: must be {'>= 0' if zero else '> 0'}, got {v!r}")
    return x


def _vec(v, n: int, where: str, positive: bool = False) -> tuple:
    if not isinstance(v, (list, tuple)) or len(v) != n:
        raise SdfError(f"{where}: must be {n} numbers, got {v!r}")
    out = tuple(_num(x, where) for x in v)
    if positive and min(out) <= 0:
        raise SdfError(f"{where}: must be {n} numbers > 0, got {list(v)}")
    return out
