"""`inshade bench hash_grid`: instant-NGP's hash grid + MLP (techniques/hash_grid) in its three
applications, each against the project's own alternatives at equal bytes, through the GL driver.

- image (``--image``, default trained/hash_grid_image; passes/field2d.frag): PSNR (sRGB and linear)
  and FLIP of the GL render at the collage's native size against the target; beside it the
  MLP-only network of its bytes (the trainer's measured quality; frames timed here) and a DI
  texture cascade of its bytes trained here (``--di-steps``) and drawn the same way (bench_image.py);
- sdf (``--sdf``, default trained/hash_grid_sdf; passes/sdf_diffuse.frag): the trainer's mean
  surface error per bounding-box diagonal, the MLP-only network's beside it (bench_fields.py);
- radiance_field (``--radiance-field``, default trained/hash_grid_radiance_field;
  passes/radiance_field_hash_grid.frag): PSNR of the shader's march of the held-out views against
  their ground truth, the MLP-only network's (the trainer's) beside it (bench_fields.py).

For every network: bytes (grid tables at their precision + fp32 MLP weights; the GPU resources the
codegen plan lays out; the bundle's files), FLOPs and texture fetches per pixel (the codegen plan
per evaluation, times the evaluations a pixel makes: 1 for the image, counted by the torch twin of
the march for the others), and ms per frame at each ``--sizes`` side: the median of ``--frames``
draws after the first, which is made at ``--probe``² and reported apart (llvmpipe JIT-compiles
there; Mesa's on-disk shader cache is off for this run unless the caller set it), on the harness
clock (GL timer query on a hardware driver, draw + glFinish wall time on llvmpipe). A side whose
frame the probe predicts past ``--max-frame-s`` is skipped with the prediction recorded.

Writes hash_grid.{json,md,png} into ``--out`` (GL_RENDERER in all three). ``--quick``: one tiny
side, one frame, a few DI steps (tests and smoke runs; options given explicitly win).
"""
from __future__ import annotations

import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

from inshade.bench.contract import Bench, clock_option, option, sized
from inshade.bench.harness import BenchError, clock_for, clock_record, machine, write_report

from .bench_claims import CLAIMS, STEM, headlines
from .bench_report import markdown, plot

APPS = ("image", "sdf", "radiance_field")
QUICK = dict(sizes="64", frames=1, probe=16, di_steps=20, di_batch=2048, count_size=16, eval_side=8, heldout_views=1)


@dataclass
class Settings:
    out: str = option("bench-out/hash_grid", "report folder (default %(default)s)")
    apps: str = option(",".join(APPS), "applications to measure (default %(default)s)")
    image: str = option("trained/hash_grid_image", "image asset folder (default %(default)s)")
    sdf: str = option("trained/hash_grid_sdf", "SDF asset folder (default %(default)s)")
    radiance_field: str = option("trained/hash_grid_radiance_field", "radiance-field asset folder (default %(default)s)")
    sizes: str = option("512,1024", "timed frame sides, comma-separated (default %(default)s)")
    frames: int = option(5, "timed draws per side (default %(default)s)")
    probe: int = option(64, "side of each program's first draw (default %(default)s)")
    max_frame_s: float = option(120.0, "skip a side whose frame the probe predicts longer than this (default "
                                       "%(default)s)")
    di_steps: int = option(1500, "steps of the image's DI cascade (default %(default)s)")
    di_batch: int = option(16384, "samples per DI step (default %(default)s)")
    count_size: int = option(128, "side at which the marches' evaluations per pixel are counted (default %(default)s)")
    eval_side: int = option(48, "lattice side of the per-evaluation timing (side^3 points; default %(default)s)")
    heldout_views: int = option(8, "radiance field: held-out views drawn by the shader (default %(default)s)")
    quick: bool = option(False, "tiny run: " + ", ".join(f"{k} {v}" for k, v in QUICK.items()))
    clock: str = clock_option()


def _sizes(text: str) -> tuple[int, ...]:
    try:
        sizes = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise BenchError(f"--sizes: expected comma-separated integers, got {text!r}") from None
    if not sizes or min(sizes) < 8:
        raise BenchError(f"--sizes: sides of at least 8 pixels, got {text!r}")
    return sizes


def _checked(args) -> tuple[tuple[str, ...], tuple[int, ...]]:
    BENCH.apply_quick(args)   # (a no-op once applied: options given explicitly win)
    apps = tuple(a.strip() for a in args.apps.split(",") if a.strip())
    unknown = [a for a in apps if a not in APPS]
    if not apps or unknown:
        raise BenchError(f"--apps: unknown application {unknown[0] if unknown else '(none)'} (known: {', '.join(APPS)})")
    for name in ("frames", "probe", "di_batch", "count_size", "eval_side", "heldout_views"):
        if getattr(args, name) < 1:
            raise BenchError(f"--{name.replace('_', '-')}: must be >= 1, got {getattr(args, name)}")
    if args.di_steps < 0 or not args.max_frame_s > 0:
        raise BenchError("--di-steps must be >= 0 and --max-frame-s > 0")
    return apps, _sizes(args.sizes)


def run(args) -> int:
    import torch

    from inshade.metrics import flip_unavailable
    from inshade.runtime.context import gl_info, shared_context

    from . import bench_fields, bench_image
    from .bench_measure import Timing, load_asset
    from .train import APPS as TRAINED

    apps, sizes = _checked(args)
    folders = {app: Path(getattr(args, app)) for app in apps}   # --image, --sdf, --radiance-field
    for app, folder in folders.items():     # every asset checked before any work
        load_asset(folder, TRAINED[app].folder)
    measures = {"image": bench_image.measure, "sdf": bench_fields.measure_sdf,
                "radiance_field": bench_fields.measure_radiance_field}
    ctx = shared_context()
    info = gl_info(ctx)
    clock = clock_for(ctx, args.clock, software=info["software"])
    print(f"GL_RENDERER: {info['renderer']}", file=sys.stderr)
    flip_reason = flip_unavailable()
    opts = SimpleNamespace(timing=Timing(sizes, args.frames, args.probe, args.max_frame_s, clock),
                           flip=flip_reason is None, di_steps=args.di_steps, di_batch=args.di_batch,
                           count_size=args.count_size, eval_side=args.eval_side, heldout_views=args.heldout_views)

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    result = {"benchmark": STEM, "quick": bool(args.quick), "machine": machine(info, torch=torch.__version__),
              **clock_record(clock),
              "timing": {"sizes": list(sizes), "frames": args.frames, "probe": args.probe,
                         "max_frame_s": args.max_frame_s, "count_size": args.count_size,
                         "eval_points": args.eval_side ** 3},
              "flip": "available" if flip_reason is None else f"unavailable: {flip_reason}", "apps": {}}
    with tempfile.TemporaryDirectory(prefix="hash_grid_bench-") as tmp:
        for app in apps:
            work = Path(tmp) / app
            work.mkdir()
            result["apps"][app] = measures[app](folders[app], opts, ctx, work, log)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_report(out, STEM, result, markdown, plot)
    log(f"wrote {out / (STEM + '.json')}, {out / (STEM + '.md')}, {out / (STEM + '.png')}")
    return 0


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows

BENCH = Bench(STEM, __doc__, Settings, run, cold_cache=True, quick=QUICK, quick_keeps_given=True, claims=CLAIMS,
              headlines=headlines, sizes={
    # llvmpipe: 256² and 512² (a 512² radiance-field frame took 29 s, the SDF's first draw 150 s of JIT)
    "cpu": sized(600, sizes="256,512", frames=2, max_frame_s=40, di_steps=1000, heldout_views=4, count_size=96,
                 eval_side=32),
    # the DI cascade trains on the machine's CPUs (~75 s of the budget)
    "device": sized(90, sizes="512,1024", frames=8, di_steps=1000)})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite
