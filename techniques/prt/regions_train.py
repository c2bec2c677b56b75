"""Build the sub-scene PRT asset (Learnt Transfer, Dhawal et al. 2022 §4.4): the procedural atrium, its transfer
split into region networks, and the two one-network baselines, in one run.

    python -m inshade.techniques.prt.regions_train --force --out trained/prt_atrium [--preset ship|quick]

Steps (times in ``OUT/metrics.json``):

1. ``OUT/sdf.json``: the atrium (techniques/prt/atrium.py);
2. ground truth: ``regions_data.scene_dataset`` -- surface samples of the whole scene, transfer cast
   against the whole scene, held-out samples with many rays (cached in ``--cache``);
3. the split: a ``grid`` over atrium.FLOOR_PLAN, cells merged by transfer variance down to
   ``networks`` (regions.merge_regions);
4. one network of ``region_width`` per region, trained on its cells plus ``delta`` (world units)
   around them (region_twin.train_regions) -> ``OUT/region_<i>/``; the shader blends neighbours
   within ``band`` (world units) of a cell side;
5. baselines: one network of k = 64 (``OUT/baselines/k64``) and, per region set, one of the width
   whose parameter count is closest to the whole set's (``OUT/baselines/k<w>``), same data, same
   steps; region sets
   of the ``other_set_widths`` (``OUT/baselines/set_k<w>/region_<i>``, the same split) are
   reported beside them (k = 24: better quality, ~3.5x the JIT of the k = 16 set);
6. ``OUT/scene.json``, previews (train.py ``write_previews``), and the report (regions_bench.run: quality vs ray-cast truth,
   frame times, seam PSNR for all three) -> ``OUT/metrics.json`` and ``--report`` (JSON + md + png).

``--preset quick`` is seconds of work (tests); ``ship`` built trained/prt_atrium.
"""
from __future__ import annotations

import argparse
import json
import shlex
import time
from pathlib import Path

from inshade import asset_folder, command
from inshade.devices import DeviceError
from inshade.files import atomic_write
from inshade.techniques.prt.train import prt_scene, write_previews
from inshade.provenance import recorded_at

SHIP = dict(points=60000, dirs=128, holdout=3000, holdout_dirs=512, resolution=256, grid=(4, 3), networks=9,
            delta=0.75, band=0.4, region_width=16, other_set_widths=(24,), layers=4, steps=10000, batch=512,
            lr=1e-2, seed=0, quality_views=7, quality_size=96, quality_dirs=256, fps_size=512, fps_repeats=3)
QUICK = dict(SHIP, points=3000, dirs=16, holdout=200, holdout_dirs=32, resolution=128, networks=4, region_width=8,
             other_set_widths=(), steps=60, quality_views=1, quality_size=24, quality_dirs=16, fps_size=32,
             fps_repeats=1)
PRESETS = {"quick": QUICK, "ship": SHIP}
CAMERA = {"type": "orbit", "fov_y": 50.0, "target": [0.0, 0.5, 0.0], "distance": 15.0, "yaw": -20.0, "pitch": -58.0}
BOOKMARKS = {"colonnade": {"type": "orbit", "fov_y": 50.0, "target": [0.0, 1.5, 2.0], "distance": 6.0, "yaw": 15.0,
                           "pitch": -15.0},
             "top": {"type": "orbit", "fov_y": 50.0, "target": [0.0, 0.0, 0.0], "distance": 16.0, "yaw": 0.0,
                     "pitch": -89.0}}


def preset_settings(preset: str, asset: str = "prt_atrium") -> dict:
    """The settings ``--preset`` resolves to (one recipe: the atrium)."""
    if preset not in PRESETS:
        raise ValueError(f"--preset: expected one of {', '.join(PRESETS)}, got {preset!r}")
    return dict(PRESETS[preset])


def width_for_params(target: int, layers: int, pos_freqs: int = 6, normal_freqs: int = 4) -> int:
    """The multiple-of-4 width of a one-network transfer_graph whose parameter count is nearest ``target``."""
    n_in = 3 + 3 * 2 * pos_freqs + 3 + 3 * 2 * normal_freqs

    def params(k):
        return n_in * k + k + (layers - 1) * (k * k + k) + k * 16 + 16

    return min(range(4, 1025, 4), key=lambda k: (abs(params(k) - target), k))


def scene_dict(networks: list[dict], title: str) -> dict:
    return prt_scene("prt_atrium", title, "passes/sdf_prt.frag", 256, networks, {"sdf": "sdf.json"}, CAMERA,
                     BOOKMARKS)


def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    asset_folder.add_arguments(p, "prt_atrium")
    p.add_argument("--preset", choices=tuple(PRESETS), default="ship", help="settings (default %(default)s)")
    p.add_argument("--cache", default=None, help="dataset cache (default ~/.cache/inshade/prt_atrium)")
    p.add_argument("--report", default="docs/bench", help="folder of prt_regions.{json,md,png} (default %(default)s)")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads (default %(default)s)")
    return p


def run(args) -> int:
    import numpy as np
    import torch

    from inshade.models.sdf import SdfModule
    from inshade.geometry.sdf import load_sdf
    from inshade.techniques.prt import regions, regions_bench
    from inshade.techniques.prt.atrium import FLOOR_PLAN, atrium
    from inshade.techniques.prt.region_twin import export_regions, train_regions
    from inshade.techniques.prt.regions_data import scene_dataset
    from inshade.techniques.prt.transfer_model import export_transfer
    from inshade.techniques.prt.transfer_training import train_transfer

    if args.threads > 0:
        torch.set_num_threads(args.threads)
    s = preset_settings(args.preset)
    out = asset_folder.claim(args.out, "prt_atrium", force=args.force)
    out.mkdir(parents=True, exist_ok=True)
    cache = Path(args.cache) if args.cache else Path.home() / ".cache" / "inshade" / "prt_atrium"
    times = {}
    atomic_write(out / "sdf.json", json.dumps(atrium(), indent=1) + "\n")
    sdf = SdfModule(load_sdf(out / "sdf.json"))
    start = time.perf_counter()
    data = scene_dataset(sdf, s["points"], s["dirs"], holdout=s["holdout"], holdout_dirs=s["holdout_dirs"],
                         seed=s["seed"], resolution=s["resolution"], cache=cache, progress=None)
    times["data_seconds"] = time.perf_counter() - start
    print(f"data: {s['points']} x {s['dirs']} rays, {data['seconds']:.1f} s{' (cached)' if data['cached'] else ''}",
          flush=True)
    grid = regions.RegionGrid(*FLOOR_PLAN, *s["grid"])
    p = data["position"].numpy()
    cell_ids = grid.cell_of(p)
    table = regions.merge_regions(grid, cell_ids, data["transfer"].numpy(), max_networks=s["networks"])
    cw, cd = grid.cell_size
    band = (s["band"] / cw, s["band"] / cd)
    print(f"regions: {grid.cells} cells -> {int(table.max()) + 1} networks, table {table.tolist()}", flush=True)
    ckpt_dir = cache / f"ckpt-{data['key']}"       # checkpoints of this dataset (resumable runs)
    common = dict(steps=s["steps"], batch=s["batch"], lr=s["lr"], seed=s["seed"], progress=None)
    start = time.perf_counter()
    trained = train_regions(data, grid, table, s["delta"], band, width=s["region_width"], layers=s["layers"],
                            checkpoint_dir=ckpt_dir / f"regions-k{s['region_width']}", **common)
    times["regions_train_seconds"] = time.perf_counter() - start
    cmd = shlex.join(["python", "-m", "inshade.techniques.prt.regions_train", f"--out={out}",
                      f"--preset={args.preset}"])
    provenance = {"command": cmd, "dataset_key": data["key"], "torch": torch.__version__,
                  **recorded_at()}
    export_regions(trained, out, provenance)
    widths = [64, width_for_params(sum(m["params"] for _, _, m, _ in trained), s["layers"])]
    for width in s["other_set_widths"]:             # the same split with wider networks, for the report
        start = time.perf_counter()
        other = train_regions(data, grid, table, s["delta"], band, width=width, layers=s["layers"],
                              checkpoint_dir=ckpt_dir / f"regions-k{width}", **common)
        times[f"set_k{width}_train_seconds"] = time.perf_counter() - start
        export_regions(other, out / "baselines" / f"set_k{width}", provenance)
        widths.append(width_for_params(sum(m["params"] for _, _, m, _ in other), s["layers"]))
    set_params = sum(m["params"] for _, _, m, _ in trained)
    baselines = {}
    for width in widths:
        if f"k{width}" in baselines:
            continue
        start = time.perf_counter()
        net, frame, metrics = train_transfer(data, width=width, layers=s["layers"],
                                             checkpoint=ckpt_dir / f"k{width}.safetensors",
                                             **common)
        times[f"k{width}_train_seconds"] = time.perf_counter() - start
        export_transfer(net, frame, out / "baselines" / f"k{width}", metrics, provenance, name=f"atrium_k{width}")
        baselines[f"k{width}"] = metrics
        print(f"baseline k={width}: {metrics['params']} params, held-out diffuse "
              f"{metrics['heldout_diffuse_psnr']:.2f} dB", flush=True)
    count = int(table.max()) + 1
    networks = [{"bundle": f"region_{r}", "prefix": f"region_{r}"} for r in range(count)]
    atomic_write(out / "scene.json", json.dumps(scene_dict(
        networks, f"PRT: a procedural atrium, {count} sub-scene transfer networks (k={s['region_width']}) selected "
                  f"by region"), indent=1) + "\n")
    times["preview_seconds"] = write_previews(out)
    start = time.perf_counter()
    report = regions_bench.run_report(out, s, report_dir=Path(args.report) if args.report else None,
                                      baselines=regions_bench.find_baselines(out))
    times["report_seconds"] = time.perf_counter() - start
    metrics = {"asset": out.name, "geometry": "sdf", "command": cmd, "preset": args.preset, "settings": s,
               "regions": {"grid": list(s["grid"]), "table": table.tolist(), "networks": count,
                           "band_cells": list(band), "delta": s["delta"],
                           "variances": regions.region_variances(grid, table, cell_ids, data["transfer"].numpy()),
                           "cell_variances": regions.region_variances(grid, np.arange(grid.cells), cell_ids,
                                                                      data["transfer"].numpy()),
                           "params": set_params,
                           "networks_metrics": [m for _, _, m, _ in trained]},
               "baselines": baselines, "data": {k: data[k] for k in ("key", "seconds", "rays", "rays_per_second")},
               "quality": report["quality"]["regions"], "report": report["summary"], **times}
    atomic_write(out / "metrics.json", json.dumps(metrics, indent=1, sort_keys=True) + "\n")
    print(json.dumps(report["summary"], indent=1))
    return 0


def main(argv=None) -> int:
    return command.main("python -m inshade.techniques.prt.regions_train", __doc__, add_arguments, run, argv,
                        errors=(DeviceError,))


if __name__ == "__main__":
    import sys

    sys.exit(main())
