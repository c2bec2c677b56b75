"""`inshade train toy_rings [-o DIR] [--seed S]`: write a toy asset (bundle + scene.json).

The smallest trainer on the trainer contract (inshade/trainer.py): one setting, one preset, a
`train(run)` that writes `run.out` and its metrics.json; the network itself is numpy only."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bundle import Bundle
from inshade.files import atomic_write
from inshade.trainer import Run, Trainer, setting


@dataclass(frozen=True)
class Settings:
    """What a toy_rings asset is built from (metrics.json records it)."""
    seed: int = setting(0, "random seed of the network's weights")


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
    atomic_write(out / "scene.json", json.dumps(scene, indent=2) + "\n")
    return out


def train(run: Run) -> int:
    out = write(run.out, run.settings.seed)
    run.write_metrics({})
    print(f"wrote {out}")
    return 0


# One preset: there is nothing to train, so nothing to make longer.
TRAINER = Trainer("toy_rings", __doc__, Settings, {"quick": {}}, train, folder=lambda s: "toy_rings",
                  folder_hint="toy_rings")
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
