"""`inshade bench uvfree_material`: UV-free neural materials vs their textures and BC1/BC7/ASTC.

The neural material against its uv textures, and those textures block-compressed at equal bytes.

For each asset (``--assets``, default every ``trained/uvfree_material_*`` folder), all through the
real GL driver, at the scene's default camera and its ``close-up`` bookmark:

- **quality**: the decoded material (setting ``view=decoded``) against the uv-textured reference
  (``view=reference``), one render per channel group (setting ``channel``), ``--quality-size``
  high, covered pixels only (alpha > 0). A channel view shows srgb_eotf(stored value), so
  srgb_oetf(image) is the texel value as stored: albedo PSNR + FLIP on the stored sRGB values;
  normal: mean and 95th-percentile angle (degrees) between the vectors decoded from n * 0.5 + 0.5;
  roughness, metallic, AO: PSNR each; shaded (scene lights and environment): PSNR + FLIP on the
  display values (sRGB encoding of the linear radiance clipped to [0, 1]). Per view, and pooled
  over both views ("all": PSNR of the pooled squared error, angles over the pooled pixels, FLIP the
  mean of the views'). FLIP is the frame mean of the images with the background zeroed in both,
  divided by the covered fraction (the mean over covered pixels; background error is ~0).
- **memory**: the bundle's bytes as the GPU holds them (fp16 feature textures, fp32 MLP, owner
  tables; memory.py's accounting) against the uncompressed textures (3 RGB8 maps of
  the asset's PNG sizes): rates with and without the owner tables.
- **baselines**: the three textures through BC1, BC7 (etcpak) and ASTC 4x4 .. 12x12
  (astc-encoder-py) round trips (bench/codecs.py), written into a temporary copy of the asset
  (same scene, mesh, bundle) and rendered in the reference view, same groups and metrics, against
  the uncompressed reference renders. A codec that cannot run is an "unavailable" row with the
  reason. At equal bytes: the codec(s) whose three maps' bytes are closest to the neural total
  (features + MLP, and separately + owner tables), overall and among ASTC only, and whether the
  neural material has the higher pooled albedo PSNR (beat ASTC at equal bytes on at
  least one configuration).
- **decode cost**: fetches and FLOPs per pixel from the codegen plan, and the frame (G-buffer +
  material pass) at ``--width`` x ``--height``: shaded decoded vs shaded reference (and the
  G-buffer pass alone), interleaved rounds (ABBA) with the harness clock, medians and the paired
  ratio. The first draw (llvmpipe
  JIT-compiles there) is made, and reported, before timing.
- **targets**: "<= 33% of the uncompressed bytes at >= 32 dB albedo on the high-poly asset"
  (``uvfree_material_stump_high_*``), met / missed per configuration.

Writes ``uvfree_material.json``, ``.md`` and ``.png`` (pooled albedo PSNR against bytes, per
object) into ``--out`` (a ``.partial.json`` after each asset until the end); logs to stderr.
"""
from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

from inshade.bench.contract import Bench, clock_option, option, rounds_option, sized, warmup_option
from inshade.bench.entry import Claim, claim_row
from inshade.bench.harness import BenchError, machine, portable_path, write_report
from inshade.files import atomic_write

from . import KIND
from .bench_measure import (Renders, baselines, beats_astc, cameras, decode_cost, equal_bytes, load_asset, memory,
                            pooled, quality_rows, targets)
from .bench_report import markdown, plot

STEM = KIND
DEFAULT_OUT = f"bench-out/{KIND}"
ASSET_GLOB = f"{KIND}_*"
ASTC_SIZES = (4, 5, 6, 8, 10, 12)
CODECS = ("BC1", "BC7", *(f"ASTC {b}x{b}" for b in ASTC_SIZES))


@dataclass
class Settings:
    assets: str | None = option(None, f"comma-separated asset folders (default: every trained/{ASSET_GLOB} folder)")
    out: str = option(DEFAULT_OUT, f"output folder (default {DEFAULT_OUT})")
    quality_size: int = option(256, "quality renders' height (default %(default)s)")
    width: int = option(1024, "frame-time width (default %(default)s)")
    height: int = option(768, "frame-time height (default %(default)s)")
    rounds: int = rounds_option()
    warmup: int = warmup_option()
    codecs: str = option(",".join(CODECS), "comma-separated baselines (default all: %(default)s)")
    clock: str = clock_option()


# ---------------------------------------------------------------------------------------------
# options and assets

def parse_codecs(text: str) -> list[str]:
    names = [c.strip() for c in text.split(",") if c.strip()]
    bad = [c for c in names if c not in CODECS]
    if bad:
        raise BenchError(f"--codecs: unknown {', '.join(map(repr, bad))} (choose from {', '.join(CODECS)})")
    return names


def asset_folders(text: str | None) -> tuple[list[Path], list[str]]:
    """(folders to bench, folders skipped). Explicit ``--assets`` must all be assets; the default
    discovery skips (and reports) a folder without scene.json: one still being trained."""
    if text is None:
        found = sorted(p for p in Path("trained").glob(ASSET_GLOB) if p.is_dir())
        ready = [p for p in found if (p / "scene.json").is_file()]
        if not ready:
            raise BenchError(f"--assets: no trained/{ASSET_GLOB} folder with a scene.json here; train one "
                             f"(inshade train {KIND}) or name the folders")
        return ready, [str(p) for p in found if p not in ready]
    folders = [Path(a.strip()) for a in text.split(",") if a.strip()]
    if not folders:
        raise BenchError("--assets: no folder given")
    for f in folders:   # all checked before minutes of rendering
        if not (f / "scene.json").is_file():
            raise BenchError(f"--assets: {f}: not a {KIND} asset (no scene.json)")
    return folders, []


def check_options(args) -> None:
    for name in ("quality_size", "width", "height", "rounds"):
        if getattr(args, name) < 1:
            raise BenchError(f"--{name.replace('_', '-')}: must be >= 1, got {getattr(args, name)}")
    if args.warmup < 0:
        raise BenchError(f"--warmup: must be >= 0, got {args.warmup}")


# ---------------------------------------------------------------------------------------------
# one asset, and the run

def bench_asset(folder: Path, args, codecs_: list[str], renders: Renders, memo: dict, log) -> dict:
    scene, bundle = load_asset(folder)
    prov = bundle.meta.get("provenance", {})
    views = cameras(scene)
    mem = memory(bundle, folder)
    log(f"{folder.name}: {len(views)} views, textures {mem['texture_size'][0]}x{mem['texture_size'][1]}")
    reference, first = renders.channels(scene, bundle, "reference", views, args.quality_size)
    decoded, _ = renders.channels(scene, bundle, "decoded", views, args.quality_size)
    quality = quality_rows(decoded, reference, views)
    albedo = pooled(quality)["albedo_psnr"]
    log(f"  neural: albedo {albedo} dB, normal {pooled(quality)['normal_mean_deg']} deg, "
        f"shaded {pooled(quality)['shaded_psnr']} dB")
    rows = baselines(folder, codecs_, reference, renders, views, args.quality_size, mem["reference_bytes"],
                     memo, log)
    return {"folder": portable_path(folder), "object": prov.get("object"), "config": prov.get("config"),
            "levels": prov.get("levels"), "table_size": prov.get("table_size"), "faces": prov.get("faces"),
            "views": list(views), "first_draw_s": None if first is None else round(first, 2),
            "memory": mem, "quality": quality, "baselines": rows,
            "equal_bytes": {
                "features_mlp": equal_bytes(mem["neural_bytes"], albedo, rows),
                "with_owner_tables": equal_bytes(mem["neural_bytes_all"], albedo, rows),
                "astc_features_mlp": equal_bytes(mem["neural_bytes"], albedo, rows, astc_only=True),
                "astc_with_owner_tables": equal_bytes(mem["neural_bytes_all"], albedo, rows, astc_only=True)},
            "decode": decode_cost(scene, bundle, renders, args.width, args.height, args.rounds, args.warmup,
                                  args.clock, log)}


def run(args: Settings) -> int:
    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    check_options(args)
    codecs_ = parse_codecs(args.codecs)
    folders, skipped = asset_folders(args.assets)
    for f in skipped:
        log(f"{f}: skipped (no scene.json: still training?)")
    from inshade.runtime.context import gl_info, shared_context

    gl = gl_info(shared_context())
    log(f"GL_RENDERER: {gl['renderer']}")
    renders = Renders()
    out = Path(args.out)
    partial = out / f"{STEM}.partial.json"
    results, memo = {"assets": {}}, {}
    for folder in folders:
        results["assets"][folder.name] = bench_asset(folder, args, codecs_, renders, memo, log)
        out.mkdir(parents=True, exist_ok=True)
        atomic_write(partial, json.dumps(results, indent=2))
    results["skipped"] = skipped
    results["targets"] = targets(results["assets"])
    results["beats_astc"] = beats_astc(results["assets"])
    results["machine"] = machine(gl)
    results["settings"] = {k: getattr(args, k) for k in ("quality_size", "width", "height", "rounds", "warmup",
                                                         "clock")}
    results["settings"]["codecs"] = codecs_
    from inshade.metrics import flip_unavailable

    results["settings"]["flip_unavailable"] = flip_unavailable()   # None: FLIP columns measured
    write_report(out, STEM, results, markdown, plot)
    partial.unlink(missing_ok=True)
    return 0


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper

CLAIMS = {
    "ms": Claim("Feature hierarchy (Walloner 2024)", "decode cost (decoded minus textured frame), ms per "
                "1280x720 (ours scaled by pixel count)", "5-12 ms per 1280x720 query, RTX 2080 Ti (CUDA)", 12.0,
                higher_better=False),
    "rate": Claim("Feature hierarchy (Walloner 2024)", "memory, % of the uncompressed textures (features + "
                  "MLP)", "66.6% down to 8.3%"),
}


def headlines(r: dict) -> list[dict]:
    rows = []
    for asset, a in r["assets"].items():
        d = a["decode"]
        ms = 1e3 * (d["ms"]["decoded"]["median_s"] - d["ms"]["reference"]["median_s"])
        per_720p = ms * 1280 * 720 / (d["width"] * d["height"])
        name = asset.removeprefix("uvfree_material_")
        rows.append(claim_row(CLAIMS, "uvfree_material", "ms", f"{per_720p:.2f} ms ({ms:.2f} ms at "
                              f"{d['width']}x{d['height']}, {d['coverage']:.0%} covered)", per_720p, name))
        m = a["memory"]
        albedo = next(q["albedo_psnr"] for q in a["quality"] if q["view"] == "all")
        rows.append(claim_row(CLAIMS, "uvfree_material", "rate", f"{m['rate_features_mlp']:.1%} at albedo "
                              f"{albedo:.2f} dB ({m['rate_all']:.1%} with owner tables)", 100 * m["rate_features_mlp"],
                              name))
    return rows


BENCH = Bench(KIND, __doc__, Settings, run, claims=CLAIMS, headlines=headlines, sizes={
    "cpu": sized(90, assets="trained/uvfree_material_fruit_balanced", quality_size=128, width=512, height=384, rounds=5,
                 warmup=1, codecs="BC1,BC7,ASTC 6x6,ASTC 8x8"),
    # the thesis times a 1280x720 query
    "device": sized(80, width=1280, height=720, rounds=15)})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite
