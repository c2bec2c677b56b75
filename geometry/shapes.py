"""Built-in meshes a scene names as data instead of a file: ``"mesh": {"shape": "teapot", "segments": 12}``.

- ``teapot(segments=8)``: the Utah teapot (geometry/teapot.py: Newell's 32 Bezier patches, its uv
  atlas documented there), y up, base at y = 0, 3.15 high.
- ``sphere(radius=1, segments=32)``: a uv sphere about the origin, ``2 * segments`` columns around
  y and ``segments`` rows pole to pole; u = longitude / 2 pi (0 at +x, counter-clockwise seen from
  above, the u = 0 / 1 seam split), v = 0 at the south pole to 1 at the north pole.
- ``plane(size=2, segments=1)``: a square in y = 0 facing +y, centred on the origin, ``segments``
  quads a side; u along +x, v along -z (uv (0, 0) at (-size/2, 0, +size/2)), tangent +x.

Each returns a ``trimesh.Trimesh`` with per-vertex uv (``TextureVisuals``, found by
``inshade.geometry.mesh.mesh_uv``), counter-clockwise faces seen from outside, and the same bytes every
run. ``make_shape(spec)`` builds one from a scene's ``{"shape": ..., parameters}`` object, every
problem a ``ShapeError`` naming the field (``mesh.shape``, ``mesh.segments``, ...).

``python -m inshade.geometry.shapes teapot OUT.obj [segments]`` writes one as OBJ (atomically).
numpy + trimesh; no torch.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from inshade.geometry import teapot as _teapot


class ShapeError(ValueError):
    """A shape description that cannot be built; the message names the field."""


def _mesh(vertices, faces, uv) -> trimesh.Trimesh:
    return trimesh.Trimesh(np.asarray(vertices, np.float64), np.asarray(faces, np.int64),
                           visual=trimesh.visual.TextureVisuals(uv=np.asarray(uv, np.float64)), process=False)


def teapot(segments: int = 8) -> trimesh.Trimesh:
    """The Utah teapot, ``segments`` x ``segments`` quads per Bezier patch (32 patches)."""
    try:
        return _mesh(*_teapot.tessellate(segments))
    except ValueError as exc:
        raise ShapeError(str(exc)) from None


def sphere(radius: float = 1.0, segments: int = 32) -> trimesh.Trimesh:
    """A uv sphere: ``2 * segments`` columns, ``segments`` rows; each pole is one vertex per
    column (its own u) so uv stays continuous on every face."""
    nu, nv = 2 * int(segments), int(segments)
    lon = np.linspace(0.0, 2.0 * np.pi, nu + 1)
    lat = np.linspace(-0.5 * np.pi, 0.5 * np.pi, nv + 1)
    la, lo = np.meshgrid(lat, lon, indexing="ij")                  # [nv + 1, nu + 1], row = latitude
    ring = np.cos(la)
    cos_lo, sin_lo = np.cos(lo), np.sin(lo)
    cos_lo[:, -1], sin_lo[:, -1] = cos_lo[:, 0], sin_lo[:, 0]      # the seam's two columns at one place
    pos = radius * np.stack([ring * cos_lo, np.sin(la), -ring * sin_lo], -1).reshape(-1, 3)
    pos[np.abs(la.reshape(-1)) == 0.5 * np.pi] *= [0.0, 1.0, 0.0]   # exact poles (cos(pi/2) is not 0)
    pos = pos + 0.0                                                    # no -0.0 in the output
    uv = np.stack([lo / (2.0 * np.pi), (la + 0.5 * np.pi) / np.pi], -1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(nv), np.arange(nu), indexing="ij")
    v00 = (i * (nu + 1) + j).reshape(-1)
    v01, v10, v11 = v00 + 1, v00 + nu + 1, v00 + nu + 2
    # counter-clockwise seen from outside; the pole rows keep only their non-degenerate triangle
    lower = np.stack([v00, v01, v11], 1)[(i > 0).reshape(-1)]
    upper = np.stack([v00, v11, v10], 1)[(i < nv - 1).reshape(-1)]
    faces = np.concatenate([lower, upper])
    used = np.zeros(len(pos), bool)
    used[faces.reshape(-1)] = True
    remap = np.cumsum(used) - 1
    return _mesh(pos[used], remap[faces], uv[used])


def plane(size: float = 2.0, segments: int = 1) -> trimesh.Trimesh:
    """A ``size`` x ``size`` square in y = 0 facing +y, ``segments`` quads a side."""
    n = int(segments)
    a = np.linspace(0.0, 1.0, n + 1)
    uu, vv = np.meshgrid(a, a, indexing="ij")                      # [n + 1, n + 1], row = u
    pos = np.stack([(uu - 0.5) * size, np.zeros_like(uu), (0.5 - vv) * size], -1).reshape(-1, 3) + 0.0
    uv = np.stack([uu, vv], -1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    v00 = (i * (n + 1) + j).reshape(-1)
    v01, v10, v11 = v00 + 1, v00 + n + 1, v00 + n + 2             # v01: +v (-z), v10: +u (+x)
    faces = np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])
    return _mesh(pos, faces, uv)


@dataclass(frozen=True)
class Param:
    kind: type            # int or float
    default: float
    low: float            # inclusive bounds
    high: float


# name -> (builder, its parameters); the scene's "mesh" object names one of these
SHAPES = {
    "teapot": (teapot, {"segments": Param(int, 8, 1, _teapot.MAX_SEGMENTS)}),
    "sphere": (sphere, {"radius": Param(float, 1.0, 1e-6, 1e6), "segments": Param(int, 32, 3, 512)}),
    "plane": (plane, {"size": Param(float, 2.0, 1e-6, 1e6), "segments": Param(int, 1, 1, 1024)}),
}


def shape_params(spec, where: str = "mesh") -> tuple[str, dict]:
    """(shape name, every parameter with defaults filled in) of ``{"shape": name, ...}``;
    ShapeError naming ``where.field`` for an unknown shape, an unknown field or a bad value."""
    if not isinstance(spec, dict):
        raise ShapeError(f"{where}: must be a mesh file name or {{\"shape\": one of {', '.join(SHAPES)}, ...}}")
    name = spec.get("shape")
    if not isinstance(name, str) or name not in SHAPES:
        raise ShapeError(f"{where}.shape: unknown shape {name!r} (known: {', '.join(SHAPES)})")
    params = SHAPES[name][1]
    extra = sorted(set(spec) - {"shape", *params})
    if extra:
        raise ShapeError(f"{where}.{extra[0]}: unknown field for a {name} (known: {', '.join(['shape', *params])})")
    out = {}
    for key, p in params.items():
        value = spec.get(key, p.default)
        ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
        if ok and p.kind is int:
            ok = isinstance(value, int) or float(value).is_integer()
        if not ok or not p.low <= value <= p.high:
            kind = "an int" if p.kind is int else "a number"
            raise ShapeError(f"{where}.{key}: must be {kind} in [{p.low:g}, {p.high:g}], got {value!r}")
        out[key] = p.kind(value)
    return name, out


def make_shape(spec, where: str = "mesh") -> tuple[str, dict, trimesh.Trimesh]:
    """(name, parameters, mesh) of a scene's ``{"shape": ..., parameters}`` object."""
    name, params = shape_params(spec, where)
    return name, params, SHAPES[name][0](**params)


def main(argv: list[str]) -> int:
    from inshade.files import atomic_write
    from inshade.geometry.mesh import obj_text

    if len(argv) not in (2, 3) or argv[0] not in SHAPES:
        print(f"usage: python -m inshade.geometry.shapes {{{','.join(SHAPES)}}} OUT.obj [segments]", file=sys.stderr)
        return 2
    spec = {"shape": argv[0]}
    if len(argv) == 3:
        spec["segments"] = int(argv[2]) if argv[2].lstrip("-").isdigit() else argv[2]   # else: ShapeError
    try:
        _, _, mesh = make_shape(spec, "shape")
    except ShapeError as exc:
        print(f"inshade.geometry.shapes: error: {exc}", file=sys.stderr)
        return 2
    out = atomic_write(Path(argv[1]), obj_text(mesh))
    print(f"{out}: {argv[0]}, {len(mesh.vertices)} vertices, {len(mesh.faces)} faces")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
