"""Hash grid: instant-NGP's multiresolution hash encoding + a small ReLU MLP (Müller et al. 2022),
trained with the torch twin (components/grids/torch_twin.py) and drawn by the shared passes, one application
per entry of ``APPS``:

- ``image``: uv -> sRGB colour of a 2048x2048 collage of photographs (image.py), drawn by
  passes/field2d.frag as neural_image is; shipped as trained/hash_grid_image;
- ``sdf``: q -> signed distance of a watertight mesh (sdf.py), sphere traced by the sdf technique's
  pass through scene.json's ``"sdf": {"network": "."}``; shipped as trained/hash_grid_sdf;
- ``radiance_field``: instant-NGP's NeRF (x, d -> density, rgb) of a procedural scene, trained from
  its own rendered views with occupancy-guided sampling (radiance_field_train.py) and ray marched
  with an occupancy grid by passes/radiance_field_hash_grid.frag; shipped as
  trained/hash_grid_radiance_field.

Command: ``inshade train hash_grid APP [--preset quick|ship] [--device auto|cpu|cuda[:N]] [-o DIR]
[--force] [--steps N] [--budget-kb K] ...``. ``--preset ship`` is exactly what built the shipped asset
of APP (its metrics.json records the preset and the resolved settings); ``quick`` is a tiny run
(seconds); an option given explicitly wins. Every run measures the MLP-only network of the same
bytes beside it when ``--baseline-steps`` is above 0 (ship: on). The sdf application takes
``--mesh PATH`` (default: the procedural rabbit neural_sdf fits) and ``--preview`` (a GL render).
"""
from __future__ import annotations

import argparse
import importlib
from dataclasses import dataclass

from inshade.models.threads import torch_threads
from inshade.trainer import (GIVEN, Run, Trainer, batch_setting, finetune_setting, precision_setting, seed_setting,
                             setting)

from .network import ARCHES, HashGridError


@dataclass(frozen=True)
class App:
    """One application: the module whose ``train(run)`` fits and writes it, and its shipped folder."""
    module: str
    folder: str
    summary: str


# The applications: one entry each (their presets below, their own settings marked only=).
APPS = {
    "image": App("inshade.techniques.hash_grid.image", "hash_grid_image", "uv -> sRGB of a 2048^2 photo collage"),
    "sdf": App("inshade.techniques.hash_grid.sdf", "hash_grid_sdf", "a mesh's signed distance, sphere traced"),
    "radiance_field": App("inshade.techniques.hash_grid.radiance_field_train", "hash_grid_radiance_field",
                          "a procedural scene's radiance field, ray marched with an occupancy grid"),
}
IMAGE, SDF, RF = ("image",), ("sdf",), ("radiance_field",)


@dataclass(frozen=True)
class Settings:
    """What a hash_grid run is built from (metrics.json records those of its application)."""
    app: str = setting(None, "application", choices=tuple(APPS), positional="APP")
    arch: str = setting("hash_grid", "network: the hash grid + MLP, or the MLP-only network of its bytes",
                        choices=ARCHES)
    steps: int = setting(3000, "optimizer steps")
    batch: int = batch_setting(65536)
    seed: int = seed_setting()
    levels: int = setting(16, "grid levels (instant-NGP L)")
    features: int = setting(2, "features per level (F)", choices=(1, 2, 4, 8))
    base_resolution: int = setting(16, "coarsest level's vertices a side (N_min)")
    finest: int = setting(2048, "finest level's vertices a side (N_max): sets the per-level scale")
    log2_table_size: int | None = setting(None, "rows per level, log2 (T); None: the largest within --budget-kb")
    budget_kb: float = setting(1024.0, "bytes of fp16 table + fp32 MLP, KiB")
    width: int = setting(64, "MLP hidden width")
    depth: int = setting(2, "MLP hidden layers")
    grid_lr: float = setting(1e-2, "Adam learning rate of the tables")
    mlp_lr: float = setting(1e-2, "Adam learning rate of the MLP")
    grid_eps: float = setting(1e-15, "Adam epsilon of the tables")
    mlp_eps: float = setting(1e-15, "Adam epsilon of the MLP")
    mlp_l2: float = setting(1e-6, "L2 regularisation of the MLP weights")
    baseline_steps: int = setting(0, "steps of the MLP-only network of equal bytes measured beside it (0: none)")
    baseline_depth: int = setting(3, "MLP-only network's hidden layers")
    baseline_lr: float = setting(1e-3, "MLP-only network's Adam learning rate")
    n_freqs: int = setting(10, "MLP-only network's frequency-encoding octaves")
    size: int = setting(2048, "target resolution (a divisor of 2048: block-averaged)", only={"app": IMAGE})
    baseline_batch: int = setting(16384, "MLP-only network's pixels per step", only={"app": IMAGE})
    precision: str | None = precision_setting(None, only={"app": IMAGE, "precision": GIVEN})
    finetune_steps: int = finetune_setting(only={"app": IMAGE, "precision": GIVEN})
    samples: int = setting(1_000_000, "training points (surface, near, uniform)", only={"app": SDF})
    eikonal: float = setting(0.1, "weight of the eikonal term", only={"app": SDF})
    step_safety: float = setting(1.5, "sphere-tracing step = 1 / (this x the measured slope)", only={"app": SDF})
    hit_eps: float = setting(2e-4, "hit distance, fraction of the bound radius", only={"app": SDF})
    max_steps: int = setting(1024, "sphere-tracing steps per ray at most", only={"app": SDF})
    slope_lattice: int = setting(96, "lattice points a side where the slope is measured", only={"app": SDF})
    mc_resolution: int = setting(256, "marching-cubes grid of the zero-set metric", only={"app": SDF})
    scene: str = setting("still_life", "procedural scene", choices=("still_life",), only={"app": RF})
    train_views: int = setting(96, "training views (upper hemisphere)", only={"app": RF})
    heldout_views: int = setting(8, "held-out views, between the training views", only={"app": RF})
    train_size: int = setting(128, "training views' pixels a side", only={"app": RF})
    heldout_size: int = setting(192, "held-out views' pixels a side (the scene's size)", only={"app": RF})
    samples_per_side: int = setting(384, "march step = box side / this", only={"app": RF})
    occupancy_resolution: int = setting(64, "occupancy grid cells a side", only={"app": RF})
    occupancy_threshold: float = setting(0.01, "occupied: a step's optical thickness above this", only={"app": RF})
    occupancy_every: int = setting(16, "steps between density-grid updates", only={"app": RF})
    empty_weight: float = setting(1.0, "weight of the empty-space density term", only={"app": RF})


# --preset, per application. image ship: instant-NGP's image settings (F 2, N_min 16, 64x2 MLP) with
# the finest level at the collage's 2048 and T from a 960 KiB budget (under 1 MB); 12 levels of 2^15
# rows beat 16 of 2^14 (720 KB) by 0.85 dB sRGB after 400 steps (27.84 / 26.99 dB batch PSNR, shared
# 2-core CPU). sdf ship: 16 levels, the finest at 512 over the rabbit's cube, T 13 from a 640 KiB budget.
PRESETS = {
    "ship": {
        "image": dict(steps=2500, batch=65536, levels=12, finest=2048, size=2048, budget_kb=960.0,
                      baseline_steps=1200),
        "sdf": dict(steps=2000, batch=16384, finest=512, budget_kb=640.0, baseline_steps=2000, n_freqs=6),
        "radiance_field": dict(steps=2400, batch=32768, finest=1024, log2_table_size=15, baseline_steps=400,
                               baseline_depth=4),
    },
    "quick": {
        "image": dict(steps=30, batch=4096, finest=128, size=128, levels=6, budget_kb=64.0, width=16,
                      baseline_steps=10, baseline_batch=1024),
        "sdf": dict(steps=30, batch=2048, finest=64, budget_kb=64.0, levels=6, width=16, samples=8000,
                    baseline_steps=0, slope_lattice=16, mc_resolution=32, n_freqs=4),
        "radiance_field": dict(steps=12, batch=2048, finest=32, levels=4, log2_table_size=10, width=16, depth=1,
                               train_views=6, heldout_views=2, train_size=24, heldout_size=24, samples_per_side=48,
                               occupancy_resolution=8, occupancy_every=4, baseline_steps=4, baseline_depth=1,
                               n_freqs=4),
    },
}


def check(s: Settings) -> None:
    if s.steps < 0 or s.batch < 1 or s.baseline_steps < 0:
        raise HashGridError("--steps and --baseline-steps must be >= 0, --batch >= 1")
    if s.levels < 1 or s.base_resolution < 2 or s.finest < s.base_resolution:
        raise HashGridError("--levels must be >= 1, --base-resolution >= 2 and --finest >= --base-resolution")
    if s.app == "image" and s.size not in [2048 // k for k in range(1, 2049) if 2048 % k == 0]:
        raise HashGridError(f"--size {s.size}: must divide 2048")
    if s.arch == "mlp" and s.app != "image":
        raise HashGridError("--arch mlp: the image application only (the sdf one measures it with --baseline-steps)")
    if s.app == "radiance_field":
        from .radiance_field_train import check as check_radiance_field

        check_radiance_field(s)


def extra_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--mesh", default=None, help="sdf: a watertight OBJ/PLY/GLB (default: the procedural rabbit)")
    parser.add_argument("--preview", action="store_true", help="sdf: also render preview.png through the GLSL path; "
                        "radiance_field: also draw the held-out views with the shader and record their PSNR")
    parser.add_argument("--threads", type=int, default=1,
                        help="torch threads while training (default: %(default)s; a shared 2-core machine)")


def train(run: Run) -> int:
    with torch_threads(run.args.threads):
        return importlib.import_module(APPS[run.settings.app].module).train(run)


TRAINER = Trainer("hash_grid", __doc__, Settings, PRESETS, train, folder=lambda s: APPS[s.app].folder,
                  folder_hint="hash_grid_<app>", preset_by="app",
                  ship_assets={app.folder: {"app": name} for name, app in APPS.items()},
                  extra_arguments=extra_arguments, check=check, errors=(HashGridError,))
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
