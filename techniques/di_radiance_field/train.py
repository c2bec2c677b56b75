"""`inshade train di_radiance_field`: bake the procedural radiance field (field.py), compress it with
the paper's multi-head DI network (model.py) and write an asset folder.

    inshade train di_radiance_field --preset ship --force --out trained/di_radiance_field_trinket

The folder holds:
  - bundle.json + weights.safetensors: the DI network (kind di_radiance_field, prefix rfd), 8-bit
    primaries, fp32 cascaded arrays, ``render`` = the march's step, max_steps and background;
  - grid/: the uncompressed grids as a bundle (prefix rfg) at ``--preview-grid`` per side, 8-bit
    (``--preview-bits``): the asset's "uncompressed" view. At 128^3 x 13 lanes the grids are 27 MB
    even at 8 bits, so the shipped asset carries them downsampled (64^3: 3.4 MB); the bench and
    metrics compare against the full-resolution float32 grids, re-baked from the procedural
    definition (deterministic);
  - scene.json (passes/di_radiance_field.frag, orbit camera, settings view | split | error_scale |
    lut_filter), preview.png (the torch twin of the DI march), metrics.json (preset, settings, per
    head sizes and held-out PSNR, the preview view's PSNR of DI vs the float32 grids).

Ratios count cells (field bytes = N^3 x C x float32; DI bytes = 8-bit primaries + fp32 cascaded
arrays, model.py). ``--preset ship`` is what built trained/di_radiance_field_trinket (128^3 grids,
10x colour and 10x density); ``quick`` (the default) is a 32^3 field in seconds.
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from inshade.scene.builder import network, orbit, requires, scene_json
from inshade.scene.labels import split_labels
from inshade.files import atomic_write
from inshade.trainer import Run, Trainer, batch_setting, seed_setting, setting
from inshade.provenance import recorded_at

from . import KIND, PREFIX_DI, PREFIX_GRID, PROGRAM, SETTINGS as SCENE_SETTINGS
from . import field, march, model

# lr (Adam, cosine): measured on the 128^3 field, 800 steps, batch 8192. Density: 1e-2 left the 5x head
# at 36.6 dB held-out (39.2 dB rendered) and 10x at 37.4 dB (44.9 dB rendered, empty-space noise); 3e-3
# gives 43.9 dB held-out at both (about 60 dB rendered with the 10x colour head, 6 views). Colour: 1e-2
# diverges (the 136^3 primary moves a cell per step), 3e-4 learns slower than 1e-3 (150-step probe).
@dataclass(frozen=True)
class Settings:
    """What a di_radiance_field run is built from (metrics.json records it)."""
    scene: str = setting("trinket", "procedural scene", choices=field.SCENES)
    grid: int = setting(32, "grid side N (N^3 voxels)")
    colour_ratio: float = setting(10.0, "colour compression")
    density_ratio: float = setting(10.0, "density compression")
    steps: int = setting(200, "training steps per head")
    batch: int = batch_setting(4096)
    lr_colour: float = setting(1e-3, "Adam lr, colour head")
    lr_density: float = setting(3e-3, "Adam lr, density head")
    shell_fraction: float = setting(0.75, "share of samples in the surface shell")
    step_voxels: float = setting(1.0, "march step in grid cells")
    preview_grid: int = setting(32, "side of the shipped uncompressed grid")
    preview_bits: int = setting(8, "bits of the shipped grid", choices=(8, 16, 32))
    seed: int = seed_setting()


# "quick" is a 32^3 field in seconds; "ship" is what built trained/di_radiance_field_trinket.
PRESETS = {"quick": {}, "ship": dict(grid=128, steps=800, batch=8192, preview_grid=64)}
BACKGROUND = (0.93, 0.93, 0.95)
# Density lanes (sigma / SIGMA_SCALE) below this are empty space in the march (grids and DI alike): the
# DI density's residual noise in empty space would otherwise integrate into a haze over the ~100 empty
# steps of a ray (DVGO likewise skips low-density points). On the 128^3 field, empty-space DI density
# (99th / 99.9th percentile): 0.0023 / 0.0075 at 10x, 0.0034 / 0.0125 at 5x (lr 3e-3); 0.013 / 0.039 and
# 0.025 / 0.088 with lr 1e-2, where the floor took the 10x render from 38.4 to 44.9 dB. The float32
# grids' empty space (sigmoid tail) is below 1e-3, so the floor leaves the reference unchanged there.
DENSITY_FLOOR = 0.02
ASSET = "di_radiance_field_trinket"


def march_render(grid: int, step_voxels: float) -> dict:
    """The DI bundle's ``render``: dt = step_voxels grid cells; enough steps for the box diagonal."""
    step = float(np.float32(step_voxels / (grid - 1)))
    return {"step": step, "max_steps": int(math.ceil(math.sqrt(3.0) / step)) + 1, "background": list(BACKGROUND),
            "sigma_scale": field.SIGMA_SCALE, "density_floor": DENSITY_FLOOR}


def orbit_camera(yaw: float = 35.0, pitch: float = -25.0, distance: float = 1.7) -> dict:
    return orbit((0.5, 0.45, 0.5), distance, yaw, pitch)


def scene_dict(name: str, title: str, grid_folder: str = "grid", lut_filter: str = "exact", size: int = 256,
               view: str = "di") -> dict:
    settings = json.loads(json.dumps(SCENE_SETTINGS))
    settings["view"]["default"] = view
    settings["lut_filter"]["default"] = lut_filter
    return scene_json(
        name, title, PROGRAM, (size, size),
        networks=[network(grid_folder, PREFIX_GRID), network(".", PREFIX_DI)],
        camera=orbit_camera(),
        bookmarks={"front": orbit_camera(0.0, -10.0), "top": orbit_camera(20.0, -70.0)},
        settings=settings,
        labels=split_labels("uncompressed", "DI", divider=False),   # the pass draws its own divider
        requires=requires(),
        notes="view: uncompressed (the grids, shipped downsampled to keep the asset small) | di | split | "
              "error (|di - uncompressed| x error_scale)",
    )


def train_heads(density, colour, settings: dict, device="cpu", progress=None) -> dict:
    """{head: model.Head} at the settings' ratios."""
    out = {}
    for head in ("density", "colour"):
        out[head] = model.train_head(head, float(settings[f"{head}_ratio"]), density, colour,
                                     steps=int(settings["steps"]), batch=int(settings["batch"]),
                                     lr=float(settings[f"lr_{head}"]), shell_fraction=float(settings["shell_fraction"]),
                                     seed=int(settings["seed"]), device=device, progress=progress)
    return out


def downsample_grid(density: np.ndarray, colour: np.ndarray, n: int):
    """The grids resampled (trilinear, corner-aligned) to n^3: the shipped uncompressed view."""
    from inshade.models.lookup_array import multilinear

    pts = torch.from_numpy(field.grid_points(n).reshape(-1, 3).astype(np.float32))
    table = torch.from_numpy(np.concatenate([colour, density[..., None]], -1))
    with torch.no_grad():
        v = multilinear(table, pts).numpy().reshape(n, n, n, 13)
    return np.ascontiguousarray(v[..., 12]), np.ascontiguousarray(v[..., :12])


def fit(settings: dict, device="cpu", progress=None, provenance: dict | None = None):
    """(di bundle, grid bundle (shipped), full grids (density, colour), metrics)."""
    t0 = time.perf_counter()
    density, colour = field.bake(int(settings["grid"]), settings["scene"])
    bake_seconds = time.perf_counter() - t0
    heads = train_heads(density, colour, settings, device, progress)
    graph = model.di_graph({h: (heads[h].primary, heads[h].cascaded) for h in ("colour", "density")})
    n = int(settings["grid"])
    field_bytes = {h: model.uncompressed_bytes(n, h) for h in model.HEADS}
    metrics = {
        "grid": n, "bake_seconds": round(bake_seconds, 2),
        "heads": {h: {**heads[h].metrics(), "field_bytes": field_bytes[h],
                      "achieved_ratio": round(field_bytes[h] / heads[h].sizing.bytes, 3)} for h in heads},
        "di_bytes": int(sum(heads[h].sizing.bytes for h in heads)),
        "field_bytes": int(sum(field_bytes.values())),
    }
    metrics["overall_ratio"] = round(metrics["field_bytes"] / metrics["di_bytes"], 3)
    render = march_render(n, float(settings["step_voxels"]))
    prov = {
        "technique": "Differentiable Indirection radiance-field compression (Datta et al. 2023 §4.4): per head a 3D "
                     "primary (3 ch, ramp, triangle F, 8-bit) -> 3D cascaded (fp32; colour 12 ch SH logits, "
                     "density 1 ch sigma), cascaded init = the target grid box-filtered",
        "field": f"procedural scene {settings['scene']!r} baked at {n}^3 (field.py)",
        "training": f"MAE vs trilinear samples ({settings['shell_fraction']:.0%} in the surface shell, rest uniform), "
                    f"Adam (colour lr {settings['lr_colour']:g}, density lr {settings['lr_density']:g}), cosine, "
                    f"batch {settings['batch']}, {settings['steps']} steps, primary clip auto, seed {settings['seed']}",
        "device": str(device), "torch": torch.__version__,
        **recorded_at(),
        **(provenance or {}),
    }
    di_bundle = graph.export(KIND, "di_radiance_field", provenance=prov, metrics=metrics, render=render)
    pn = min(int(settings["preview_grid"]), n)
    pd, pc = (density, colour) if pn == n else downsample_grid(density, colour, pn)
    grid_bundle = model.grid_graph(pd, pc, int(settings["preview_bits"])).export(
        KIND, "di_radiance_field_grid",
        provenance={"field": f"{settings['scene']!r} at {n}^3, resampled to {pn}^3, {settings['preview_bits']}-bit"})
    return di_bundle, grid_bundle, (density, colour), metrics


def torch_render(graph, render: dict, camera: dict, size: int) -> np.ndarray:
    from inshade.scene.camera import camera_from_dict

    return march.march(march.graph_network(graph), camera_from_dict(camera).uniforms(size, size), size, size,
                       step=render["step"], max_steps=render["max_steps"], background=render["background"],
                       sigma_scale=render["sigma_scale"], density_floor=render.get("density_floor", 0.0))


def write_asset(out, di_bundle, grid_bundle, full_grids, settings: dict, metrics: dict,
                preview_size: int = 128) -> dict:
    """The bundles, scene.json and preview.png; returns the preview's metrics (its PSNR against the
    float32 grids)."""
    from inshade.bundle import Bundle
    from inshade.metrics import psnr
    from inshade.models.graph import GraphModule
    from inshade.scene.image_io import write_png

    out = Path(out)
    di_bundle.save(out)
    grid_bundle.save(out / "grid")
    n = int(settings["grid"])
    title = (f"DI radiance field: {settings['scene']} {n}^3, colour {settings['colour_ratio']:g}x, density "
             f"{settings['density_ratio']:g}x ({metrics['overall_ratio']:.1f}x overall, fp32 grids = 1x)")
    scene = scene_dict(out.name, title)
    atomic_write(out / "scene.json", json.dumps(scene, indent=1) + "\n")
    render = di_bundle.meta["render"]
    di_graph = GraphModule.from_bundle(Bundle(di_bundle.meta, di_bundle.tensors))
    img = torch_render(di_graph, render, scene["camera"], preview_size)
    ref = torch_render(model.grid_graph(*full_grids), render, scene["camera"], preview_size)
    write_png(out / "preview.png", img[..., :3])
    return {"preview_psnr_vs_fp32_grids": round(float(psnr(img[..., :3], ref[..., :3])), 3),
            "preview_size": preview_size}


def check(s: Settings) -> None:
    field.check_resolution(s.grid, "--grid")
    field.check_resolution(s.preview_grid, "--preview-grid")
    if s.steps < 0 or s.batch < 1:
        raise model.RadianceFieldError(f"--steps must be >= 0 and --batch >= 1 (got {s.steps}, {s.batch})")
    if not 0.0 <= s.shell_fraction <= 1.0:
        raise model.RadianceFieldError(f"--shell-fraction must be in [0, 1], got {s.shell_fraction}")
    if not 0.05 <= s.step_voxels <= 8.0:
        raise model.RadianceFieldError(f"--step-voxels must be in [0.05, 8], got {s.step_voxels}")
    for h in model.HEADS:
        model.plan(s.grid, h, getattr(s, f"{h}_ratio"))    # a ratio the grid cannot meet fails before any work


def train(run: Run) -> int:
    settings = asdict(run.settings)
    t0 = time.perf_counter()
    with torch_threads(1):
        di_bundle, grid_bundle, full, metrics = fit(settings, run.device, provenance={"command": run.command})
        preview = write_asset(run.out, di_bundle, grid_bundle, full, settings, metrics)
    m = {**metrics, **preview}
    run.write_metrics(m)
    print(f"wrote {run.out}: {m['di_bytes'] / 1e6:.2f} MB DI vs {m['field_bytes'] / 1e6:.2f} MB fp32 grids "
          f"({m['overall_ratio']:.1f}x), preview PSNR {m['preview_psnr_vs_fp32_grids']:.2f} dB, "
          f"{time.perf_counter() - t0:.0f} s")
    return 0


class torch_threads:
    """torch on ``n`` intra-op threads inside the block (the shared machines here)."""

    def __init__(self, n):
        self.n = n

    def __enter__(self):
        self.old = torch.get_num_threads()
        torch.set_num_threads(self.n)

    def __exit__(self, *exc):
        torch.set_num_threads(self.old)


TRAINER = Trainer(KIND, __doc__, Settings, PRESETS, train, folder=lambda s: ASSET,
                  folder_hint=ASSET, ship_assets={ASSET: {}},
                  check=check, errors=(model.RadianceFieldError, field.FieldError))
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
