"""A procedural atrium of the Sponza kind for sub-scene PRT (Learnt Transfer, Dhawal et al. 2022 §4.4): an
analytic SDF description (geometry/sdf.py) that the sdf passes trace in the shader.

``atrium(scale=1.0)`` -> the description dict (``format: inshade.geometry.sdf``): a 16 x 12 floor (scaled),
two colonnades of seven columns along x at z = +-3.5 carrying arched beams (a box minus six
cylinders along z), covered walks (a roof slab between each colonnade and its outer wall), outer
walls at z = +-6, coloured banners hanging from the beams into the courtyard (the cloth), a
fountain (basin, rim, bowl) and four bushes in the courtyard (the plants). Its bound radius is
10.5 x scale: 6x prt_creature's 1.75 (at least 4x the other PRT assets).
``FLOOR_PLAN`` is the (x0, z0, x1, z1) rectangle regions.py splits at scale 1.

``python -m inshade.techniques.prt.atrium OUT.json [scale]`` writes it (atomically). numpy only.
"""
from __future__ import annotations

import json
import sys

from inshade.files import atomic_write

FLOOR_PLAN = (-8.0, -6.0, 8.0, 6.0)
BOUND_RADIUS = 10.5

STONE = [0.72, 0.68, 0.6]
FLOOR = [0.55, 0.52, 0.48]
CLOTH = ([0.62, 0.12, 0.1], [0.12, 0.25, 0.55])
LEAF = [0.2, 0.45, 0.15]
WATER = [0.35, 0.5, 0.6]


def _t(child: dict, translate=(0.0, 0.0, 0.0), **extra) -> dict:
    return {"type": "transform", "child": child, "translate": [float(v) for v in translate], **extra}


def _colonnade(z: float) -> dict:
    """Seven columns (x = -6..6) under a beam with six arches (x = -5..5) at depth z."""
    columns = {"type": "repeat", "spacing": [2.0, 0.0, 0.0], "count": [3, 0, 0], "child": {
        "type": "union", "k": 0.05, "children": [
            _t({"type": "cylinder", "radius": 0.28, "height": 1.5}, (0.0, 1.5, 0.0)),
            _t({"type": "box", "size": [0.4, 0.12, 0.4]}, (0.0, 0.12, 0.0)),
            _t({"type": "box", "size": [0.38, 0.1, 0.38]}, (0.0, 2.95, 0.0))]}}
    arch = _t({"type": "cylinder", "radius": 0.82, "height": 0.5},
              rotate={"axis": [1.0, 0.0, 0.0], "angle": 90.0})
    arches = {"type": "repeat", "spacing": [4.0, 0.0, 0.0], "count": [1, 0, 0], "child": {
        "type": "union", "children": [_t(arch, (-1.0, 0.0, 0.0)), _t(arch, (1.0, 0.0, 0.0))]}}
    beam = {"type": "subtract", "children": [
        _t({"type": "box", "size": [7.0, 0.55, 0.3]}, (0.0, 3.55, 0.0)),
        _t(arches, (0.0, 3.0, 0.0))]}
    return _t({"type": "union", "children": [columns, beam]}, (0.0, 0.0, z), albedo=STONE)


def _banners(z: float, colour) -> dict:
    """Three cloths hanging from the beam's courtyard face (x = -4, 0, 4), slightly tilted."""
    cloth = _t({"type": "round_box", "size": [0.55, 1.0, 0.08], "radius": 0.04},
               rotate={"axis": [1.0, 0.0, 0.0], "angle": 8.0 if z > 0 else -8.0})
    return _t({"type": "repeat", "spacing": [4.0, 0.0, 0.0], "count": [1, 0, 0], "child": cloth},
              (0.0, 2.75, z), albedo=list(colour))


def _walk(z: float) -> dict:
    """A covered walk: the roof slab from the colonnade to the outer wall, and that wall."""
    side = 1.0 if z > 0 else -1.0
    roof = _t({"type": "box", "size": [7.4, 0.15, 1.4]}, (0.0, 4.25, side * 4.7))
    wall = _t({"type": "box", "size": [7.4, 2.2, 0.2]}, (0.0, 2.2, side * 6.0))
    return {"type": "union", "children": [roof, wall], "albedo": STONE}


def _fountain() -> dict:
    basin = {"type": "union", "k": 0.05, "children": [
        _t({"type": "cylinder", "radius": 1.3, "height": 0.25}, (0.0, 0.25, 0.0), albedo=STONE),
        _t({"type": "torus", "major": 1.3, "minor": 0.12}, (0.0, 0.5, 0.0), albedo=STONE),
        _t({"type": "cylinder", "radius": 0.15, "height": 0.6}, (0.0, 0.8, 0.0), albedo=STONE),
        _t({"type": "sphere", "radius": 0.45}, (0.0, 1.45, 0.0), albedo=WATER)]}
    return basin


def _bushes() -> dict:
    bush = {"type": "union", "k": 0.15, "children": [
        _t({"type": "sphere", "radius": 0.5}, (0.0, 0.45, 0.0)),
        _t({"type": "sphere", "radius": 0.35}, (0.3, 0.75, 0.15)),
        _t({"type": "sphere", "radius": 0.3}, (-0.25, 0.8, -0.1))]}
    return {"type": "union", "albedo": LEAF,
            "children": [_t(bush, (x, 0.0, z)) for x in (-4.5, 4.5) for z in (-1.6, 1.6)]}


def atrium(scale: float = 1.0) -> dict:
    """The atrium's SDF description (see the module docstring); ``scale`` > 0 scales it uniformly."""
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not scale > 0:
        raise ValueError(f"scale: must be a number > 0, got {scale!r}")
    floor = _t({"type": "box", "size": [8.0, 0.1, 6.2]}, (0.0, -0.1, 0.0), albedo=FLOOR)
    parts = [floor, _colonnade(3.5), _colonnade(-3.5), _walk(3.5), _walk(-3.5),
             _banners(3.05, CLOTH[0]), _banners(-3.05, CLOTH[1]), _fountain(), _bushes()]
    root = {"type": "union", "children": parts}
    if scale != 1.0:
        root = _t(root, scale=float(scale))
    s = float(scale)
    return {"format": "inshade.geometry.sdf", "version": 1, "name": "atrium",
            "notes": "procedural atrium (techniques/prt/atrium.py): colonnades, arches, banners, fountain, bushes",
            "bound": {"center": [0.0, 2.0 * s, 0.0], "radius": BOUND_RADIUS * s},
            "trace": {"max_steps": 256, "step_scale": 0.9, "hit_eps": 0.002 * s, "normal_eps": 0.002 * s},
            "root": root}


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0 if argv else 2
    scale = float(argv[1]) if len(argv) > 1 else 1.0
    atomic_write(argv[0], json.dumps(atrium(scale), indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
