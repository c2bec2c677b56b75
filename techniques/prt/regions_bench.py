"""Sub-scene PRT report (Learnt Transfer, Dhawal et al. 2022 §4.4): quality, frame time and seam error of a
region set against the one-network baselines on the same scene, in one run.

    python -m inshade.techniques.prt.regions_bench [--asset trained/prt_atrium] [--out docs/bench]

Variants: ``regions`` (the asset's scene: N networks selected by region, blended across the
band), ``regions_hard`` (the same networks, band 0: the margin training alone against seams),
each ``OUT/baselines/k<w>`` bundle as the scene's only network (one network of k = 64, one
with the set's parameter count), and each ``OUT/baselines/set_k<w>`` region set (same table).

- quality: the GL image vs the ray-cast ground truth over ``quality_views`` orbit views (the
  protocol of the PRT assets' metrics.json "quality": twin.quality_orbit's, with the ground truth
  cast once per view and shared by every variant), PSNR / SSIM / MAE over surface pixels, diffuse
  and glossy;
- seam: PSNR over the surface pixels within ``band`` (world units) of a side between cells of
  different networks (the same pixels for every variant);
- frames: median of ``fps_repeats`` forced redraws at ``fps_size``² (wall clock with glFinish on
  software renderers, bench/harness.py); ``first_draw_s``: the variant's first draw of
  all (the program's JIT; cold when MESA_SHADER_CACHE_DISABLE=true).

Writes ``prt_regions.json``, ``prt_regions.md`` and ``prt_regions.png``.
"""
from __future__ import annotations

import copy
import json
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bench.contract import Bench, option
from inshade.bench.harness import (BenchError, WallClock, clock_for, clock_record, machine, machine_markdown,
                                   matplotlib_pyplot, measure, portable_path, write_report)

PAPER = "Sponza: 12 even parts merged to 9 MLPs, 200+ FPS at 1024² (RTX 3090, GLSL)"


def seam_mask(grid, table, width_world: float, p: np.ndarray) -> np.ndarray:
    """[N] bool: points within ``width_world`` (xz) of a cell side whose neighbour has another network."""
    from inshade.techniques.prt import regions

    cw, cd = grid.cell_size
    band = (min(0.5, width_world / cw), min(0.5, width_world / cd))
    nets, w = regions.blend_weights(grid, np.asarray(table), band, p)
    return (nets[:, 1:] >= 0).any(1)


def _scene_with(scene_dict: dict, folder: Path, bundle: Path, sdf: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    d = dict(scene_dict, name=f"prt_atrium_{bundle.name}", networks=[{"bundle": str(bundle.resolve()),
                                                                     "prefix": "transfer"}],
             sdf=str(sdf.resolve()))
    (folder / "scene.json").write_text(json.dumps(d))
    return folder


def find_baselines(asset) -> list[str]:
    """The comparison variants stored in ``asset/baselines``: ``k<w>`` (one network) and ``set_k<w>``
    (another region set of the same table), sorted."""
    folder = Path(asset) / "baselines"
    return sorted(p.name for p in folder.iterdir() if p.is_dir()) if folder.is_dir() else []


def _set_bundles(folder: Path, count: int) -> list:
    from inshade.bundle import load

    return [load(folder / f"region_{r}") for r in range(count)]


def run_report(asset, settings: dict, report_dir=None, baselines=("k64",), ctx=None, progress=None) -> dict:
    """The report dict ({"quality", "frames", "summary", ...}); written as prt_regions.* into
    ``report_dir`` when given."""
    import torch

    from inshade.bundle import load
    from inshade.runtime.context import gl_info, shared_context
    from inshade.runtime.programs import ProgramCache
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene
    from inshade.techniques.prt import regions, twin

    asset = Path(asset)
    scene = load_scene(asset)
    ctx = ctx or shared_context()
    info = gl_info(ctx)
    clock = clock_for(ctx, "auto", software=info["software"])
    cache = ProgramCache(ctx)
    region_bundles = [load(n.bundle) for n in scene.networks]
    rs = regions.read_region_set(region_bundles)
    geometry = twin.scene_geometry(scene)
    variants, params, tmp = _variants(asset, scene, region_bundles, rs, baselines)
    band_world = float(settings.get("band", 0.4))
    cams = twin.orbit_cameras(scene, int(settings["quality_views"]))
    size, n_dirs = int(settings["quality_size"]), int(settings["quality_dirs"])
    renderers = {}
    try:
        for name, (sc, bundles) in variants.items():
            renderers[name] = SceneRenderer(sc, ctx, cache=cache, bundles=bundles)
        results, first_draw = _measure_quality(ctx, renderers, geometry, rs, cams, size, n_dirs, band_world)
        frames = _measure_frames(ctx, renderers, scene.make_camera(), settings, clock, first_draw)
    finally:
        for r in renderers.values():
            r.release()
        cache.release()
        shutil.rmtree(tmp, ignore_errors=True)     # the baselines' scene files
    quality = _mean_quality(results)
    summary = _summary(quality, frames, params)
    for name in quality:
        quality[name].update({"n_views": len(cams), "size": size, "n_dirs": n_dirs, "gl_renderer": info["renderer"]})
    result = {"benchmark": "prt_regions", "machine": machine(info), **clock_record(clock), "paper": PAPER,
              "asset": portable_path(asset),
              "settings": {k: (list(v) if isinstance(v, tuple) else v) for k, v in settings.items()},
              "regions": {"grid": rs.grid.to_dict(), "table": list(rs.table), "networks": rs.count,
                          "band_cells": list(rs.band), "seam_band_world": band_world},
              "method": f"quality: {len(cams)} orbit views {size}² vs {n_dirs}-ray ground truth "
                        f"(shared by all variants); "
                        f"frames: median of {settings['fps_repeats']} redraws ({clock.note})",
              "quality": quality, "frames": frames, "summary": summary, "torch": torch.__version__}
    if report_dir is not None:
        write_report(Path(report_dir), "prt_regions", result, markdown, plot)
    return result


def _variants(asset: Path, scene, region_bundles: list, rs, baselines) -> tuple[dict, dict, Path]:
    """name -> (scene, bundles or None: the scene's own) of every variant, name -> its parameter count,
    and the temporary folder holding the one-network baselines' scene files (the caller removes it)."""
    from inshade.bundle import load
    from inshade.scene.description import load_scene
    from inshade.techniques.prt import regions

    hard = copy.deepcopy(region_bundles)
    for b in hard:
        b.meta["render"]["region"]["band"] = [0.0, 0.0]
    scene_json = json.loads((asset / "scene.json").read_text())
    tmp = Path(tempfile.mkdtemp(prefix="prt_regions_"))
    variants = {"regions": (scene, None), "regions_hard": (scene, hard)}
    params = {"regions": sum(b.meta.get("metrics", {}).get("params", 0) for b in region_bundles)}
    params["regions_hard"] = params["regions"]
    for name in baselines:
        if name.startswith("set_"):
            other = _set_bundles(asset / "baselines" / name, rs.count)
            if regions.read_region_set(other).table != rs.table:
                raise BenchError(f"{asset / 'baselines' / name}: render.region.table: differs from the scene's set")
            variants[name] = (scene, other)
            params[name] = sum(b.meta.get("metrics", {}).get("params", 0) for b in other)
        else:
            folder = _scene_with(scene_json, tmp / name, asset / "baselines" / name, asset / "sdf.json")
            variants[name] = (load_scene(folder), None)
            params[name] = load(asset / "baselines" / name).meta.get("metrics", {}).get("params")
    return variants, params, tmp


_SHADING_SETTING = "shading"     # the PRT pass's diffuse / glossy switch


def _measure_quality(ctx, renderers: dict, geometry, rs, cams: list, size: int, n_dirs: int,
                     band_world: float) -> tuple[dict, dict]:
    """Each variant's image metrics per view and mode against the ray-cast truth (cast once per view),
    over all surface pixels and over the seam band; and each variant's first draw of all (seconds)."""
    from inshade.scene.camera import camera_from_dict
    from inshade.runtime.render import read_rgba
    from inshade.techniques.prt import twin

    results = {name: {"diffuse": [], "glossy": [], "seam_diffuse": [], "seam_glossy": []} for name in renderers}
    first_draw = {}
    sh = renderers["regions"].environment_sh()
    m = twin.light_matrix_t(sh)
    for i, cam_dict in enumerate(cams):
        cam = camera_from_dict(cam_dict)
        u = cam.uniforms(size, size)
        view = twin.trace_view(geometry, u, size, size)
        gt_t = twin.ground_truth_transfer(geometry, view, n_dirs, seed=i)
        seam = np.zeros(size * size, bool)
        seam[view.idx.numpy()] = seam_mask(rs.grid, rs.table, band_world, view.p.numpy())
        seam = seam.reshape(size, size)
        for mode in ("diffuse", "glossy"):
            for name, r in renderers.items():
                r.set_setting(_SHADING_SETTING, mode)
                if name not in first_draw:      # llvmpipe JIT-compiles the program here
                    first_draw[name] = WallClock(ctx.finish).time(lambda: r.render_network(cam, size, size))
                image = read_rgba(r.render_network(cam, size, size))
                shading = twin.PrtShading.from_settings(r.values, r.scene)
                gt = twin.compose(view, gt_t, sh, shading, m)
                results[name][mode].append(twin.image_metrics(image, gt["rgba"], gt["hit"]))
                if (seam & gt["hit"]).any():
                    results[name][f"seam_{mode}"].append(twin.image_metrics(image, gt["rgba"], seam & gt["hit"]))
        print(f"view {i + 1}/{len(cams)}: {int(view.idx.numel())} hits, {int(seam.sum())} seam pixels",
              file=sys.stderr, flush=True)
    return results, first_draw


def _measure_frames(ctx, renderers: dict, camera, settings: dict, clock, first_draw: dict) -> dict:
    """Each variant's frame time per mode (median of forced redraws at ``fps_size``²), its programs'
    compile + link seconds and its first draw of all."""
    frames = {}
    fsize = int(settings["fps_size"])
    for name, r in renderers.items():
        frames[name] = {}
        for mode in ("diffuse", "glossy"):
            r.set_setting(_SHADING_SETTING, mode)

            def redraw(r=r):
                r.weights_version += 1
                r.render_network(camera, fsize, fsize)

            first = WallClock(ctx.finish).time(redraw)
            t = measure(redraw, repeats=int(settings["fps_repeats"]), warmup=0, clock=clock)
            frames[name][mode] = {"first_draw_s": first, "seconds": t.median, "min_s": t.min, "max_s": t.max,
                                  "fps": 1.0 / t.median, "size": fsize}
            print(f"{name} {mode} {fsize}²: {t.median * 1e3:.1f} ms (first draw {first:.1f} s)",
                  file=sys.stderr, flush=True)
        frames[name]["compile_link_s"] = r.compile_seconds
        frames[name]["first_draw_s"] = first_draw.get(name)
    return frames


def _mean_quality(results: dict) -> dict:
    """name -> metric rows -> the mean PSNR / SSIM / MAE over the views (rows with no pixels left out)."""
    quality = {}
    for name, rows in results.items():
        quality[name] = {}
        for key, vals in rows.items():
            if vals:
                quality[name][key] = {k: float(np.mean([v[k] for v in vals])) for k in ("psnr", "ssim", "mae")}
    return quality


def _summary(quality: dict, frames: dict, params: dict) -> dict:
    """One row per variant: parameters, PSNR (all and seam), FPS and first draw."""
    return {name: {"params": params[name], "diffuse_psnr": quality[name]["diffuse"]["psnr"],
                   "glossy_psnr": quality[name]["glossy"]["psnr"],
                   "seam_diffuse_psnr": quality[name].get("seam_diffuse", {}).get("psnr"),
                   "seam_glossy_psnr": quality[name].get("seam_glossy", {}).get("psnr"),
                   "diffuse_fps": frames[name]["diffuse"]["fps"], "glossy_fps": frames[name]["glossy"]["fps"],
                   "first_draw_s": frames[name]["first_draw_s"]} for name in params}


LABELS = {"regions": "sub-scene set (blended)", "regions_hard": "sub-scene set (hard switch)"}


def _label(name: str) -> str:
    if name.startswith("set_k"):
        return f"sub-scene set k={name[5:]} (blended)"
    return LABELS.get(name, f"one network k={name[1:]}")


def markdown(result: dict) -> str:
    r = result["regions"]
    lines = ["# Sub-scene PRT on a large scene (the atrium): quality, frame time, seams", "",
             machine_markdown(result["machine"]),
             f"- {result['method']}",
             f"- regions: {r['grid']['cells'][0]}x{r['grid']['cells'][1]} grid -> {r['networks']} networks "
             f"(variance merge), table {r['table']}, blend band {r['seam_band_world']} world units; "
             f"seam PSNR over pixels within that band of a side between different networks",
             f"- paper: {result['paper']}", "",
             "| variant | params | diffuse PSNR | glossy PSNR | seam diffuse | seam glossy | diffuse FPS | "
             "glossy FPS | first draw s |", "|---|---|---|---|---|---|---|---|---|"]
    f = lambda v, d=2: "–" if v is None else f"{v:.{d}f}"  # noqa: E731
    for name, s in result["summary"].items():
        lines.append(f"| {_label(name)} | {s['params']} | {f(s['diffuse_psnr'])} | {f(s['glossy_psnr'])} | "
                     f"{f(s['seam_diffuse_psnr'])} | {f(s['seam_glossy_psnr'])} | {f(s['diffuse_fps'], 3)} | "
                     f"{f(s['glossy_fps'], 3)} | {f(s['first_draw_s'], 1)} |")
    size = next(iter(result["frames"].values()))["diffuse"]["size"]
    lines += ["", f"FPS at {size}² on `{result['machine']['gl_renderer']}` (CPU rasteriser: not GPU numbers)."]
    return "\n".join(lines) + "\n"


def plot(result: dict, path: Path) -> None:
    plt = matplotlib_pyplot()
    names = list(result["summary"])
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    x = np.arange(len(names))
    for j, key in enumerate(("diffuse_psnr", "glossy_psnr", "seam_diffuse_psnr", "seam_glossy_psnr")):
        vals = [result["summary"][n][key] or 0.0 for n in names]
        axes[0].bar(x + (j - 1.5) * 0.2, vals, 0.2, label=key.replace("_psnr", ""))
    axes[0].set_xticks(x, [_label(n) for n in names], fontsize=6, rotation=15)
    axes[0].set_ylabel("PSNR dB vs ray-cast truth")
    axes[0].set_ylim(30, 50)
    axes[0].legend(fontsize=7)
    for j, key in enumerate(("diffuse_fps", "glossy_fps")):
        axes[1].bar(x + (j - 0.5) * 0.35, [result["summary"][n][key] for n in names], 0.35, label=key)
    axes[1].set_xticks(x, [_label(n) for n in names], fontsize=6, rotation=15)
    axes[1].set_ylabel("frames / s")
    axes[1].legend(fontsize=7)
    fig.suptitle(f"sub-scene PRT — {result['machine']['gl_renderer']}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


@dataclass
class Settings:
    asset: str = option("trained/prt_atrium", "the region-set asset (default %(default)s)")
    out: str = option("docs/bench", "report folder (default %(default)s)")


def run(args) -> int:
    asset = Path(args.asset)
    mpath = asset / "metrics.json"
    if not mpath.is_file():
        raise BenchError(f"{mpath}: missing (build the asset with python -m inshade.techniques.prt.regions_train)")
    m = json.loads(mpath.read_text())
    run_report(asset, m["settings"], Path(args.out), baselines=find_baselines(asset))
    return 0


BENCH = Bench("prt_regions", __doc__, Settings, run, prog="python -m inshade.techniques.prt.regions_bench")
add_arguments, main = BENCH.add_arguments, BENCH.main

if __name__ == "__main__":
    sys.exit(main())
