"""`inshade train toy_rings -o DIR`: write a toy asset (bundle + scene.json), numpy only."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from inshade import command
from inshade.bundle import Bundle


def weights(seed: int = 0) -> dict:
    rng = np.random.default_rng(seed)
    return {"l0.weight": rng.normal(0.0, 6.0, (3, 2)).astype(np.float32),
            "l0.bias": rng.normal(0.0, 1.0, 3).astype(np.float32)}


def write(out, seed: int = 0) -> Path:
    out = Path(out)
    meta = {"format": "inshade.bundle", "version": 1, "kind": "toy_rings", "name": out.name,
            "inputs": [{"name": "uv", "dim": 2, "semantic": "uv"}],
            "nodes": [{"id": "l0", "type": "dense", "inputs": ["uv"], "params": {"out": 3, "bias": True}},
                      {"id": "a0", "type": "sin", "inputs": ["l0"], "params": {}}],
            "outputs": [{"name": "rgb", "node": "a0", "semantic": "linear_rgb"}]}
    Bundle(meta, weights(seed)).save(out)
    scene = {"format": "inshade.scene", "version": 1, "name": out.name, "program": "passes/toy_rings.frag",
             "size": [32, 32], "networks": [{"bundle": ".", "output": "rgb"}],
             "camera": {"type": "plane2d"},
             "settings": {"warmth": {"type": "float", "default": 0.5, "min": 0.0, "max": 1.0,
                                     "frame": "warmth"}}}
    (out / "scene.json").write_text(json.dumps(scene, indent=2) + "\n")
    return out


def add_arguments(parser):
    parser.add_argument("-o", "--out", required=True, help="asset folder to write")
    parser.add_argument("--seed", type=int, default=0)


def run(args) -> int:
    print(f"wrote {write(args.out, args.seed)}")
    return 0


def main(argv=None) -> int:
    return command.main("inshade train toy_rings", __doc__, add_arguments, run, argv)
