"""Texture-space PRT (the paper's baseline) beside learnt transfer on the same mesh, in one run.

    python -m inshade.techniques.prt.texture_bench --out docs/bench

For the shipped mesh asset (``--learnt``, trained/prt_mesh: the procedural bunny, k=64 transfer MLP)
and texture-PRT variants of the same mesh (one xatlas atlas per ``--resolutions`` entry, baked with
``--bake-dirs`` rays per texel by techniques/prt/texture_prt.py, stored at each ``--bits``):

- **quality**: every variant's GL image vs the ray-cast truth over the same ``--views`` orbit
  (twin.py ``quality_orbit``'s protocol: ``--size``^2 renders, truth = ``mesh_transfer`` with
  ``--truth-dirs`` rays at the G-buffer's points, PSNR over surface pixels, SSIM, MAE; diffuse and
  glossy). The truth is cast once per view and shared by all variants: their G-buffers are the
  same surface (the atlas keeps every position); the largest G-buffer difference from the learnt
  asset's is recorded (``gbuffer_max_diff``);
- **memory**: texture bytes, learnt network bytes (float32 parameters), per-vertex storage of this
  mesh and per million vertices;
- **frame time** of each pass at ``--frame-size``^2 (median of ``--repeats`` forced redraws after a
  timed first draw, inshade.bench.harness clock; GL_RENDERER recorded).

Writes ``prt_texture.json``, ``prt_texture.md`` and ``prt_texture.png`` into ``--out``. ``--quick``:
two views, 32^2, one 128^2 texture (tests / smoke runs).
"""
from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bench.contract import Bench, clock_option, option
from inshade.bench.harness import (BenchError, WallClock, clock_for, clock_record, machine,
                                   machine_markdown, markdown_table, matplotlib_pyplot, measure, portable_path,
                                   write_report)

PAPER_VERTEX_MB_PER_MILLION = 70.0       # §5.4 of the paper
PAPER_NETWORK_BYTES = (64 << 10, 5 << 20)


@dataclass
class Settings:
    out: str = option("bench-out/prt_texture", "output folder")
    learnt: str = option("trained/prt_mesh", "the learnt-transfer mesh asset (its mesh is used)")
    resolutions: str = option("256,512,1024", "texture sides, comma-separated")
    bits: str = option("8,16", "bits per lane of each texture, comma-separated (8, 16, 32)")
    bake_dirs: int = option(256, "rays per texel of the bake")
    views: int = option(30)
    size: int = option(96, "square size of the quality renders")
    truth_dirs: int = option(512, "rays per pixel of the ground truth")
    frame_size: int = option(512, "square size of the timed frames")
    repeats: int = option(5)
    work: str | None = option(None, "folder for the variants' assets (default: a temporary one)")
    cache: str | None = option(None, "bake cache (default ~/.cache/inshade/prt_texture)")
    quick: bool = option(False, "2 views, 32^2, one 128^2 16-bit texture, 16 rays")
    clock: str = clock_option()


def build_variant(mesh, learnt_scene: Path, resolution: int, bits_list, bake_dirs: int, work: Path, cache: Path):
    """Atlas + bake (cached) + one scene folder per bit depth; returns [(label, folder, info)]."""
    from inshade.files import atomic_write
    from inshade.geometry.mesh import load_mesh, obj_text
    from inshade.techniques.prt import texture_prt as tp

    folder = work / f"tex{resolution}"
    folder.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    mapped = tp.atlas(mesh, resolution, 2)
    atomic_write(folder / tp.MESH_NAME, obj_text(mapped))
    atlas_info = mapped.metadata["atlas"]
    rendered = load_mesh(folder / tp.MESH_NAME)
    table, stats = tp.bake(rendered, resolution, bake_dirs, 0, 1.5, progress=None, cache_dir=cache)
    bleed = tp.bleed_check(rendered, resolution, tp.texel_samples(rendered, resolution, 1.5))
    seconds = time.perf_counter() - start
    base = json.loads((learnt_scene / "scene.json").read_text())
    out = []
    for bits in bits_list:
        sub = work / f"tex{resolution}_{bits}bit"
        sub.mkdir(parents=True, exist_ok=True)
        (sub / tp.MESH_NAME).write_bytes((folder / tp.MESH_NAME).read_bytes())
        tp.texture_bundle(table, bits, sub.name, {"atlas": atlas_info, "bake": stats, "bleed": bleed}).save(sub / "transfer")
        scene = tp.scene_dict(sub.name, sub.name, base["camera"], {})
        atomic_write(sub / "scene.json", json.dumps(scene, indent=1) + "\n")
        out.append((f"texture {resolution}² {bits}-bit", sub,
                    {"kind": "texture", "resolution": resolution, "bits": bits, "bytes": tp.texture_bytes(resolution, bits),
                     "atlas": atlas_info, "bake": {k: v for k, v in stats.items()}, "bleed": bleed,
                     "build_seconds": round(seconds, 1)}))
    return out


def run(args: Settings) -> int:
    import torch

    from inshade.bundle import load
    from inshade.geometry.mesh import load_mesh
    from inshade.scene.camera import camera_from_dict
    from inshade.runtime.context import gl_info, shared_context
    from inshade.runtime.programs import ProgramCache
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene
    from inshade.techniques.prt import texture_prt as tp
    from inshade.techniques.prt.twin import (PrtShading, compose, gbuffer_view, ground_truth_transfer, image_metrics,
                                             light_matrix_t, orbit_cameras)

    torch.set_num_threads(int(torch.get_num_threads()))
    try:
        resolutions = [int(v) for v in args.resolutions.split(",") if v.strip()]
        bits_list = [int(v) for v in args.bits.split(",") if v.strip()]
    except ValueError:
        raise BenchError(f"--resolutions / --bits: comma-separated ints, got {args.resolutions!r} / {args.bits!r}") from None
    bad = [b for b in bits_list if b not in tp.BITS]
    if bad:
        raise BenchError(f"--bits: each must be one of {list(tp.BITS)}, got {bad[0]}")
    learnt = Path(args.learnt)
    if not (learnt / "scene.json").is_file():
        raise BenchError(f"--learnt: no scene.json in {learnt}")
    work = Path(args.work) if args.work else Path("/tmp") / "inshade_prt_texture_bench"
    cache = Path(args.cache) if args.cache else Path.home() / ".cache" / "inshade" / "prt_texture"
    learnt_scene = load_scene(learnt)
    mesh = learnt_scene.mesh.data
    bundle = load(learnt / "transfer")
    net_params = int(sum(np.asarray(t).size for t in bundle.tensors.values()))
    variants = [("learnt k=64 MLP", learnt, {"kind": "learnt", "params": net_params, "bytes": net_params * 4})]
    for res in resolutions:
        print(f"texture {res}^2: atlas + bake", file=sys.stderr)
        variants += build_variant(load_mesh(Path(learnt_scene.mesh.path)), learnt, res, bits_list, args.bake_dirs,
                                  work, cache)
    ctx = shared_context()
    info = gl_info(ctx)
    clock = clock_for(ctx, args.clock, software=info["software"])
    pcache = ProgramCache(ctx)
    cams = [camera_from_dict(c) for c in orbit_cameras(learnt_scene, args.views)]
    rows = {label: {"diffuse": [], "glossy": []} for label, _, _ in variants}
    gdiff = {label: 0.0 for label, _, _ in variants}
    truth = []          # per view: (view, gt transfer, position, normal)
    frames = {}
    for vi, (label, folder, meta) in enumerate(variants):
        scene = load_scene(folder)
        r = SceneRenderer(scene, ctx, cache=pcache)
        try:
            sh = r.environment_sh()
            m = light_matrix_t(sh)
            for ci, cam in enumerate(cams):
                for mode in ("diffuse", "glossy"):
                    r.set_setting("shading", mode)
                    image = read_rgba(r.render_network(cam, args.size, args.size))
                    pos, nrm = [a.copy() for a in r.gbuffer.read()[:2]]
                    if vi == 0 and mode == "diffuse":
                        view = gbuffer_view(pos, nrm, cam.uniforms(args.size, args.size), args.size, args.size)
                        truth.append((view, ground_truth_transfer(mesh, view, args.truth_dirs, 0), pos, nrm))
                    view, gt_t, pos0, nrm0 = truth[ci]
                    gdiff[label] = max(gdiff[label], float(np.abs(pos - pos0).max()), float(np.abs(nrm - nrm0).max()))
                    gt = compose(view, gt_t, sh, PrtShading.from_settings(r.values, scene), m)
                    rows[label][mode].append(image_metrics(image, gt["rgba"], gt["hit"]))
            r.set_setting("shading", "glossy")
            cam = scene.make_camera()

            def redraw():
                r.weights_version += 1
                r.render_network(cam, args.frame_size, args.frame_size)

            first = WallClock(ctx.finish).time(redraw)
            t = measure(redraw, repeats=args.repeats, warmup=0, clock=clock)
            frames[label] = {"size": args.frame_size, "shading": "glossy", "first_draw_s": first, "seconds": t.median,
                             "min_s": t.min, "max_s": t.max, "fps": 1.0 / t.median}
        finally:
            r.release()
        print(f"{label}: done", file=sys.stderr)
    table = []
    for label, folder, meta in variants:
        q = {mode: {k: float(np.mean([row[k] for row in rows[label][mode]])) for k in ("psnr", "ssim", "mae")}
             for mode in ("diffuse", "glossy")}
        table.append({"variant": label, **meta, "quality": q, "frame": frames[label], "gbuffer_max_diff": gdiff[label]})
    vertices = int(len(mesh.vertices))
    result = {"benchmark": "prt_texture", "quick": bool(args.quick), "machine": machine(info), **clock_record(clock),
              "mesh": portable_path(learnt_scene.mesh.path), "vertices": vertices, "faces": int(len(mesh.faces)),
              "protocol": {"views": args.views, "size": args.size, "truth_dirs": args.truth_dirs,
                           "bake_dirs": args.bake_dirs, "truth": "mesh_transfer at the G-buffer points, one per view"},
              "memory": {"vertex_f32_bytes": tp.vertex_bytes(vertices), "vertex_f16_bytes": tp.vertex_bytes(vertices, 2),
                         "vertex_f32_mb_per_million": tp.vertex_bytes(10 ** 6) / 1e6,
                         "paper_vertex_mb_per_million": PAPER_VERTEX_MB_PER_MILLION,
                         "paper_network_bytes": list(PAPER_NETWORK_BYTES)},
              "variants": table}
    write_report(args.out, "prt_texture", result, _markdown, _plot)
    return 0


def _markdown(r: dict) -> str:
    m = r["memory"]
    lines = ["# Texture-space PRT (the paper's baseline) vs learnt transfer, same mesh", "",
             machine_markdown(r["machine"]), "",
             f"Mesh: `{r['mesh']}` ({r['vertices']} vertices, {r['faces']} faces). Quality: GL image vs ray-cast "
             f"truth over a {r['protocol']['views']}-view orbit at {r['protocol']['size']}², truth "
             f"{r['protocol']['truth_dirs']} rays/pixel, PSNR over surface pixels (the learnt assets' protocol); "
             f"textures baked with {r['protocol']['bake_dirs']} rays/texel. Frame: glossy, "
             f"{r['variants'][0]['frame']['size']}², median of forced redraws.", ""]
    rows = []
    for v in r["variants"]:
        q, f = v["quality"], v["frame"]
        rows.append([v["variant"], f"{v['bytes'] / 1024:.0f} KB" if v["bytes"] < 1 << 20 else f"{v['bytes'] / 2 ** 20:.2f} MB",
                     f"{q['diffuse']['psnr']:.2f}", f"{q['diffuse']['ssim']:.4f}", f"{q['glossy']['psnr']:.2f}",
                     f"{q['glossy']['ssim']:.4f}", f"{f['seconds'] * 1e3:.1f}", f"{f['fps']:.2f}"])
    lines += markdown_table(["transfer", "memory", "diffuse PSNR", "SSIM", "glossy PSNR", "SSIM", "frame ms", "FPS"], rows)
    lines += ["", "Memory of other storage on this mesh: per-vertex transfer "
              f"{m['vertex_f32_bytes'] / 2 ** 20:.2f} MB (float32; {m['vertex_f16_bytes'] / 2 ** 20:.2f} MB half), i.e. "
              f"{m['vertex_f32_mb_per_million']:.0f} MB per million vertices (the paper: ~{m['paper_vertex_mb_per_million']:.0f} MB); "
              "the paper's networks: 64 KB - 5 MB.", ""]
    return "\n".join(lines)


def _plot(r: dict, path: Path) -> None:
    plt = matplotlib_pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    for mode, marker in (("diffuse", "o"), ("glossy", "s")):
        xs = [v["bytes"] for v in r["variants"]]
        ys = [v["quality"][mode]["psnr"] for v in r["variants"]]
        ax.scatter(xs, ys, marker=marker, label=mode)
        for x, y, v in zip(xs, ys, r["variants"]):
            ax.annotate(v["variant"].replace("texture ", ""), (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_xlabel("transfer storage (bytes)")
    ax.set_ylabel("PSNR vs ray-cast truth (dB)")
    ax.set_title(f"texture PRT vs learnt transfer ({r['machine'].get('gl_renderer', '')})", fontsize=9)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _errors() -> tuple:
    from inshade.techniques.prt.texture_prt import TextureBakeError

    return BenchError, TextureBakeError


BENCH = Bench("prt_texture", __doc__, Settings, run, errors=_errors, prog="python -m inshade.techniques.prt.texture_bench",
              quick={"resolutions": "128", "bits": "16", "bake_dirs": 16, "views": 2, "size": 32, "truth_dirs": 32,
                     "frame_size": 64, "repeats": 1})
add_arguments, main = BENCH.add_arguments, BENCH.main

if __name__ == "__main__":
    raise SystemExit(main())
