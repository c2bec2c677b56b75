"""A plants-like analytic SDF for learnt transfer on thin geometry (the paper's
weakest scenes are PLANTS and DINING-TABLE): a potted plant of three whorls of thin leaves (rounded
boxes 0.024 thick, i.e. 24 hit_eps, tilted up, five per whorl by polar repetition), a stem, a
terracotta pot with soil, on a round floor slab. Deterministic JSON (geometry/sdf.py format).

    python -m inshade.techniques.prt.plants trained/prt_plants/sdf.json
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

LEAF = (0.22, 0.012, 0.06)          # half extents: length, thickness, width
LEAF_GREEN = [0.22, 0.5, 0.18]
WHORLS = ((-0.12, 20.0, 0.0, 1.0), (0.12, 30.0, 36.0, 0.9), (0.34, 42.0, 18.0, 0.75))   # y, tilt, turn, scale


def _leaf_whorl(y: float, tilt: float, turn: float, scale: float) -> dict:
    leaf = {"type": "round_box", "size": list(LEAF), "radius": 0.008}
    placed = {"type": "transform", "translate": [0.3, 0.0, 0.0], "child": leaf}
    tilted = {"type": "transform", "rotate": {"axis": [0, 0, 1], "angle": tilt}, "child": placed}
    ring = {"type": "repeat_polar", "count": 5, "child": tilted}
    return {"type": "transform", "translate": [0.0, y, 0.0], "rotate": {"axis": [0, 1, 0], "angle": turn},
            "scale": scale, "child": ring}


def plants_sdf() -> dict:
    leaves = {"type": "union", "k": 0.0, "albedo": LEAF_GREEN,
              "children": [_leaf_whorl(*w) for w in WHORLS]}
    stem = {"type": "capsule", "a": [0.0, -0.4, 0.0], "b": [0.0, 0.42, 0.0], "radius": 0.025,
            "albedo": [0.3, 0.42, 0.2]}
    pot = {"type": "transform", "translate": [0.0, -0.6, 0.0], "albedo": [0.62, 0.32, 0.2], "child": {
        "type": "subtract", "k": 0.01, "children": [
            {"type": "cylinder", "radius": 0.3, "height": 0.2},
            {"type": "transform", "translate": [0.0, 0.12, 0.0], "child": {"type": "cylinder", "radius": 0.26,
                                                                            "height": 0.12}}]}}
    soil = {"type": "transform", "translate": [0.0, -0.46, 0.0], "albedo": [0.24, 0.17, 0.11],
            "child": {"type": "cylinder", "radius": 0.26, "height": 0.02}}
    floor = {"type": "transform", "translate": [0.0, -0.83, 0.0], "albedo": [0.72, 0.72, 0.7],
             "child": {"type": "cylinder", "radius": 0.75, "height": 0.03}}
    return {"format": "inshade.geometry.sdf", "version": 1, "name": "plants",
            "bound": {"center": [0.0, -0.15, 0.0], "radius": 1.15},
            "trace": {"max_steps": 256, "step_scale": 0.9, "hit_eps": 0.001, "normal_eps": 0.001},
            "root": {"type": "union", "k": 0.0, "children": [leaves, stem, pot, soil, floor]}}


def main(argv=None) -> int:
    from inshade.files import atomic_write
    from inshade.geometry.sdf import parse_sdf

    argv = list(sys.argv[1:] if argv is None else argv)
    if len(argv) != 1:
        print("usage: python -m inshade.techniques.prt.plants OUT.json", file=sys.stderr)
        return 2
    data = plants_sdf()
    parse_sdf(data)                 # checked as the renderer will read it
    atomic_write(Path(argv[0]), json.dumps(data, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
