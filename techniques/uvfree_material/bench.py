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
  (astc-encoder-py) round trips (inshade/codecs.py), written into a temporary copy of the asset
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

import argparse
import hashlib
import io
import json
import math
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from inshade import command
from inshade.bench.entry import Claim, Sizing, SuiteEntry, claim_row
from inshade.bench.harness import (BenchError, add_clock_argument, clock_for, clock_record, interleave, machine,
                                   machine_markdown, markdown_table, matplotlib_pyplot, paired_ratio, write_report)
from inshade.files import atomic_write

from . import CHANNEL_VIEWS, KIND

STEM = KIND
DEFAULT_OUT = f"bench-out/{KIND}"
ASSET_GLOB = f"{KIND}_*"
VIEWS = ("default", "close-up")
GROUPS = CHANNEL_VIEWS                         # the "channel" setting's choices: shaded + 5 groups
TEXTURES = ("albedo", "normal", "rma")         # objects.TEXTURES: <name>.png in the asset folder
ASTC_SIZES = (4, 5, 6, 8, 10, 12)
CODECS = ("BC1", "BC7", *(f"ASTC {b}x{b}" for b in ASTC_SIZES))
TARGET_RATE, TARGET_ALBEDO_DB = 1 / 3, 32.0
TARGET_ASSETS = f"{KIND}_stump_high_"


def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    p.add_argument("--assets", default=None,
                   help=f"comma-separated asset folders (default: every trained/{ASSET_GLOB} folder)")
    p.add_argument("--out", default=DEFAULT_OUT, help=f"output folder (default {DEFAULT_OUT})")
    p.add_argument("--quality-size", type=int, default=256, help="quality renders' height (default %(default)s)")
    p.add_argument("--width", type=int, default=1024, help="frame-time width (default %(default)s)")
    p.add_argument("--height", type=int, default=768, help="frame-time height (default %(default)s)")
    p.add_argument("--rounds", type=int, default=7, help="timed rounds (default %(default)s)")
    p.add_argument("--warmup", type=int, default=2, help="untimed draws per variant (default %(default)s)")
    p.add_argument("--codecs", default=",".join(CODECS),
                   help="comma-separated baselines (default all: %(default)s)")
    add_clock_argument(p)
    return p


def main(argv=None) -> int:
    return command.main(f"inshade bench {KIND}", __doc__, add_arguments, run, argv, errors=(BenchError,))


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


def load_asset(folder: Path):
    """(scene, bundle) of a uvfree_material asset folder; BenchError naming the folder otherwise."""
    from inshade.bundle import BundleError
    from inshade.runtime.scene import SceneError, load_scene

    if not (folder / "scene.json").is_file():
        raise BenchError(f"{folder}: not a {KIND} asset (no scene.json)")
    try:
        scene = load_scene(folder)
    except (SceneError, BundleError, ValueError) as exc:
        raise BenchError(f"{folder}: {exc}") from None
    nets = [n for n in scene.networks if n.prefix == "mat"]
    if len(nets) != 1 or "channel" not in scene.settings or "view" not in scene.settings:
        raise BenchError(f"{folder}: not a {KIND} asset (scene.json needs the material network and the "
                         f"'view' and 'channel' settings)")
    from inshade.bundle import load

    bundle = load(nets[0].bundle)
    if bundle.kind != KIND:
        raise BenchError(f"{folder}: bundle kind is {bundle.kind!r}, expected {KIND!r}")
    return scene, bundle


# ---------------------------------------------------------------------------------------------
# rendering

class Renders:
    """Renderers of this run on one program cache: a scene's program compiles (and llvmpipe JITs
    it) once, then every renderer of that asset, codec copies included, reuses it."""

    def __init__(self):
        from inshade.runtime.context import shared_context
        from inshade.runtime.programs import ProgramCache

        self.cache = ProgramCache(shared_context())

    def renderer(self, scene, bundle, **settings):
        from inshade.runtime.renderer import SceneRenderer

        return SceneRenderer(scene, cache=self.cache, settings=settings, bundles=[bundle])

    def channels(self, scene, bundle, view: str, views, height: int) -> tuple[dict, float | None]:
        """{(camera view, group): RGBA float32 image} for ``view`` (decoded | reference) at the
        camera ``views``, and this renderer's first draw's wall time (llvmpipe JIT-compiles a new
        program there)."""
        w = max(1, int(round(height * scene.size[0] / scene.size[1])))
        r = self.renderer(scene, bundle, view=view)
        try:
            out = {}
            for cam in views:
                camera = scene.make_camera(None if cam == "default" else cam)
                for g in GROUPS:
                    r.set_setting("channel", g)
                    r.render_network(camera, w, height)
                    out[cam, g] = r.read("network").copy()
            return out, r.first_draw_seconds
        finally:
            r.release()


def cameras(scene) -> tuple[str, ...]:
    return tuple(v for v in VIEWS if v == "default" or v in scene.bookmarks)


# ---------------------------------------------------------------------------------------------
# metrics

def _stored(img: np.ndarray) -> np.ndarray:
    """A channel view's texel values as stored (it shows srgb_eotf(stored)); for the shaded view,
    its display values (sRGB encoding of the radiance clipped to [0, 1])."""
    from inshade.metrics import srgb_oetf

    return srgb_oetf(img[..., :3])


def _db(v: float):
    """PSNR for the JSON: rounded, "inf" for identical values (JSON has no infinity)."""
    return round(v, 3) if math.isfinite(v) else "inf"


def normal_angles(test: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Degrees between the normals stored as n * 0.5 + 0.5 in ``test`` and ``ref`` ([N, 3])."""
    a, b = test * 2.0 - 1.0, ref * 2.0 - 1.0
    cos = (a * b).sum(-1) / np.maximum(np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1), 1e-12)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def _flip_covered(test: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> float:
    from inshade.metrics import flip

    m = mask[..., None]
    return flip(ref * m, test * m) / max(float(mask.mean()), 1e-12)


def group_metrics(test: dict, ref: dict, views) -> dict:
    """The quality row of ``test`` against ``ref`` ({(view, group): RGBA}) over the covered pixels
    of ``views`` pooled."""
    from inshade.metrics import flip_unavailable, psnr

    masks = {v: ref[v, "shaded"][..., 3] > 0 for v in views}
    stored = {k: _stored(img) for k, img in test.items() if k[0] in views}
    stored_ref = {k: _stored(img) for k, img in ref.items() if k[0] in views}

    def pixels(images, g):
        return np.concatenate([images[v, g][masks[v]] for v in views])

    row = {"pixels": int(sum(m.sum() for m in masks.values()))}
    if not row["pixels"]:
        raise BenchError(f"views {', '.join(views)}: the mesh covers no pixel")
    no_flip = flip_unavailable()
    for g in ("albedo", "shaded"):
        row[f"{g}_psnr"] = _db(psnr(pixels(stored, g), pixels(stored_ref, g)))
        row[f"{g}_flip"] = None if no_flip else round(float(np.mean(
            [_flip_covered(stored[v, g], stored_ref[v, g], masks[v]) for v in views])), 5)
    angles = normal_angles(pixels(stored, "normal"), pixels(stored_ref, "normal"))
    row["normal_mean_deg"] = round(float(angles.mean()), 3)
    row["normal_p95_deg"] = round(float(np.percentile(angles, 95)), 3)
    for g in ("roughness", "metallic", "ao"):   # grey: the value in every channel
        row[f"{g}_psnr"] = _db(psnr(pixels(stored, g)[:, 0], pixels(stored_ref, g)[:, 0]))
    return row


def quality_rows(test: dict, ref: dict, views) -> list[dict]:
    """One row per camera view, then the views pooled ("all")."""
    rows = [{"view": v, **group_metrics(test, ref, (v,))} for v in views]
    if len(views) > 1:
        rows.append({"view": "all", **group_metrics(test, ref, tuple(views))})
    return rows


def pooled(rows: list[dict]) -> dict:
    """The row every summary uses: the views pooled (the only view when the scene has one)."""
    return rows[-1]


# ---------------------------------------------------------------------------------------------
# memory

def texture_size(folder: Path) -> tuple[int, int]:
    """(width, height) of the reference textures (all the same size)."""
    from PIL import Image

    sizes = {k: Image.open(folder / f"{k}.png").size for k in TEXTURES}
    if len(set(sizes.values())) != 1:
        raise BenchError(f"{folder}: the reference textures differ in size: {sizes}")
    return sizes["albedo"]


def memory(bundle, folder: Path) -> dict:
    """GPU bytes of the material against the three uncompressed RGB8 textures of the asset's PNG size."""
    from .memory import memory_report

    return memory_report(bundle, *texture_size(folder))


# ---------------------------------------------------------------------------------------------
# block-compressed baselines

def roundtrip(codec: str, img8: np.ndarray):
    """inshade.codecs round trip of one uint8 RGB texture; CodecError when it cannot run."""
    from inshade import codecs

    if codec.startswith("ASTC "):
        return codecs.astc_roundtrip(img8, int(codec.split("x")[-1]))
    return codecs.bc_roundtrip(img8, codec)


def compressed_asset(folder: Path, into: Path, codec: str, memo: dict) -> int:
    """A copy of the asset in ``into`` with the three textures replaced by their ``codec`` round
    trips (same scene, mesh, bundle); returns the codec bytes of the three maps. ``memo`` keeps
    round trips by texture content: the configurations of one object share their textures."""
    from PIL import Image

    shutil.copytree(folder, into, ignore=shutil.ignore_patterns(*(f"{k}.png" for k in TEXTURES), "preview.png*"))
    total = 0
    for k in TEXTURES:
        data = (folder / f"{k}.png").read_bytes()
        key = (hashlib.sha256(data).hexdigest(), codec)
        if key not in memo:
            img8 = np.asarray(Image.open(io.BytesIO(data)).convert("RGB"), np.uint8)
            decoded, nbytes = roundtrip(codec, img8)
            memo[key] = (np.ascontiguousarray(decoded[..., :3]), int(nbytes))
        decoded, nbytes = memo[key]
        Image.fromarray(decoded).save(into / f"{k}.png")
        total += nbytes
    return total


def baselines(folder: Path, codecs_: list[str], reference: dict, renders: Renders, views, height: int,
              ref_bytes: int, memo: dict, log) -> list[dict]:
    from inshade.codecs import CodecError

    rows = []
    for codec in codecs_:
        with tempfile.TemporaryDirectory(prefix="uvf_bench_") as tmp:
            copy = Path(tmp) / folder.name
            try:
                nbytes = compressed_asset(folder, copy, codec, memo)
            except CodecError as exc:
                rows.append({"codec": codec, "available": False, "reason": str(exc)})
                log(f"  {codec}: unavailable ({exc})")
                continue
            scene, bundle = load_asset(copy)
            images, _ = renders.channels(scene, bundle, "reference", views, height)
        q = quality_rows(images, reference, views)
        rows.append({"codec": codec, "available": True, "reason": None, "bytes": nbytes,
                     "rate": round(nbytes / ref_bytes, 4), "quality": q})
        log(f"  {codec}: {nbytes} B, albedo {pooled(q)['albedo_psnr']} dB, shaded {pooled(q)['shaded_psnr']} dB")
    return rows


def _num(v) -> float:
    return math.inf if v == "inf" else float(v)


def equal_bytes(neural_bytes: int, neural_albedo, rows: list[dict], astc_only: bool = False) -> dict | None:
    """The available codec row(s) whose bytes are closest to ``neural_bytes`` and whether the neural
    material's pooled albedo PSNR is higher than each; None without a candidate."""
    cands = [r for r in rows if r["available"] and (not astc_only or r["codec"].startswith("ASTC"))]
    if not cands:
        return None
    best = min(abs(r["bytes"] - neural_bytes) for r in cands)
    picked = [r for r in cands if abs(r["bytes"] - neural_bytes) == best]
    return {"neural_bytes": neural_bytes, "neural_albedo_psnr": neural_albedo,
            "above_every_codec": neural_bytes > max(r["bytes"] for r in cands),
            "codecs": [{"codec": r["codec"], "bytes": r["bytes"], "albedo_psnr": pooled(r["quality"])["albedo_psnr"],
                        "neural_beats": _num(neural_albedo) > _num(pooled(r["quality"])["albedo_psnr"])}
                       for r in picked]}


# ---------------------------------------------------------------------------------------------
# decode cost

def decode_cost(scene, bundle, renders: Renders, width: int, height: int, rounds: int, warmup: int,
                clock_name: str, log) -> dict:
    """Plan totals, and the shaded frame decoded vs reference (interleaved, same clock). The
    reference frame is drawn by the shader with the decoder compiled out (setting "decoder": off),
    since a software rasteriser may pay for both sides of a branch on a uniform."""
    dec = renders.renderer(scene, bundle, view="decoded", channel="shaded")
    ref = renders.renderer(scene, bundle, view="reference", channel="shaded", decoder=False)
    try:
        plan = dec.generated[0].plan.totals()
        camera = scene.make_camera()
        for r in (dec, ref):   # the first draw at this size, untimed (llvmpipe JIT-compiles here)
            r.render_network(camera, width, height, force=True)
            r.ctx.finish()
        coverage = float((dec.read("network")[..., 3] > 0).mean())
        clock = clock_for(dec.ctx, clock_name, software=dec.gl["software"])
        # the G-buffer pass alone too: both frames draw it, the rest is the material pass
        t = interleave({"decoded": lambda: dec.render_network(camera, width, height, force=True),
                        "reference": lambda: ref.render_network(camera, width, height, force=True),
                        "gbuffer": lambda: dec.gbuffer.draw_camera(camera, width, height)},
                       rounds=rounds, warmup=warmup, clock=clock)
    finally:
        dec.release()
        ref.release()
    ratio = paired_ratio(t["decoded"].samples, t["reference"].samples)
    out = {"plan": {k: int(v) for k, v in plan.items()}, "width": width, "height": height,
           "coverage": round(coverage, 4), "clock": clock_record(clock),
           "ms": {k: v.to_dict() for k, v in t.items()},
           "decoded_over_reference": ratio.to_dict()}
    log(f"  decode: {plan['fetches']} fetches, {plan['flops']} FLOPs/px; {1e3 * t['decoded'].median:.2f} ms decoded "
        f"vs {1e3 * t['reference'].median:.2f} ms reference ({ratio.median:.2f}x)")
    return out


# ---------------------------------------------------------------------------------------------

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
    return {"folder": str(folder), "object": prov.get("object"), "config": prov.get("config"),
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


def targets(assets: dict) -> list[dict]:
    """The rate and quality goal on the high-poly asset, per configuration."""
    out = []
    for name, a in assets.items():
        if not name.startswith(TARGET_ASSETS):
            continue
        albedo = pooled(a["quality"])["albedo_psnr"]
        m = a["memory"]
        ok_db = _num(albedo) >= TARGET_ALBEDO_DB
        out.append({"asset": name, "config": a["config"], "albedo_psnr": albedo,
                    "rate_features_mlp": m["rate_features_mlp"], "rate_all": m["rate_all"],
                    "met": ok_db and m["rate_features_mlp"] <= TARGET_RATE,
                    "met_with_owner_tables": ok_db and m["rate_all"] <= TARGET_RATE})
    return out


def beats_astc(assets: dict) -> dict:
    """Beat ASTC at equal bytes on at least one configuration (features + MLP bytes, and + owner tables)."""
    out = {}
    for key in ("astc_features_mlp", "astc_with_owner_tables"):
        wins = [name for name, a in assets.items() if a["equal_bytes"][key]
                and any(c["neural_beats"] for c in a["equal_bytes"][key]["codecs"])]
        out[key] = {"met": bool(wins), "assets": wins}
    return out


def run(args: argparse.Namespace) -> int:
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
# report

QUALITY_HEADERS = ["albedo PSNR (dB)", "albedo FLIP", "normal mean (deg)", "normal p95 (deg)", "roughness PSNR",
                   "metallic PSNR", "AO PSNR", "shaded PSNR", "shaded FLIP"]
QUALITY_KEYS = ["albedo_psnr", "albedo_flip", "normal_mean_deg", "normal_p95_deg", "roughness_psnr",
                "metallic_psnr", "ao_psnr", "shaded_psnr", "shaded_flip"]


def _cell(v) -> str:
    if v is None:
        return "—"
    if v == "inf":
        return "∞"
    return str(v)


def _quality_cells(row: dict) -> list[str]:
    return [_cell(row[k]) for k in QUALITY_KEYS]


def _verdict(m: dict) -> str:
    return ("met (" + ", ".join(m["assets"]) + ")") if m["met"] else "missed"


def _x(v) -> str:
    """A ratio bound: None is unbounded (a round lost in noise)."""
    return "—" if v is None else f"{v:.2f}"


def _equal_bytes_line(label: str, e: dict | None) -> str:
    if e is None:
        return f"- {label}: no codec available"
    parts = [f"{c['codec']} ({c['bytes']} B, {_cell(c['albedo_psnr'])} dB): neural "
             f"{'beats it' if c['neural_beats'] else 'does not beat it'}" for c in e["codecs"]]
    above = " (the neural bytes exceed every codec's: no equal-bytes match)" if e["above_every_codec"] else ""
    return (f"- {label} ({e['neural_bytes']} B, albedo {_cell(e['neural_albedo_psnr'])} dB): closest "
            + "; ".join(parts) + above)


def markdown(r: dict) -> str:
    lines = [f"# {KIND}: UV-free neural materials vs their uv textures and BC1/BC7/ASTC", "",
             machine_markdown(r["machine"]), "",
             "Quality against the uncompressed uv-textured reference render, covered pixels; channel groups "
             "on the stored values (albedo sRGB, normal as the angle between the decoded vectors, "
             "roughness/metallic/AO); shaded on the display values (sRGB of the clipped radiance). "
             "'all': both views pooled. Bytes: the three maps (codecs), features + MLP (neural; "
             "+ owner tables in brackets).", ""]
    if r.get("skipped"):
        lines += [f"- skipped (no scene.json): {', '.join(r['skipped'])}", ""]
    lines += ["## Targets", ""]
    if r["targets"]:
        lines += markdown_table(["asset", "albedo PSNR (dB)", "rate (features + MLP)", "rate (+ owner tables)",
                                 f"<= {TARGET_RATE:.0%} at >= {TARGET_ALBEDO_DB:.0f} dB", "with owner tables"],
                                [[t["asset"], _cell(t["albedo_psnr"]), f"{t['rate_features_mlp']:.1%}",
                                  f"{t['rate_all']:.1%}", "met" if t["met"] else "missed",
                                  "met" if t["met_with_owner_tables"] else "missed"] for t in r["targets"]])
    else:
        lines.append(f"- no high-poly asset ({TARGET_ASSETS}*) in this run: the target is not measured")
    ms = r["beats_astc"]
    lines += ["", "- Beat ASTC at equal bytes on at least one configuration, pooled albedo PSNR): "
              f"features + MLP: {_verdict(ms['astc_features_mlp'])}; "
              f"with owner tables: {_verdict(ms['astc_with_owner_tables'])}", ""]
    lines += ["## Summary (views pooled)", ""]
    lines += markdown_table(["asset", "bytes (+ owner tables)", "rate", *QUALITY_HEADERS],
                            [[name, f"{a['memory']['neural_bytes']} ({a['memory']['neural_bytes_all']})",
                              f"{a['memory']['rate_features_mlp']:.1%} ({a['memory']['rate_all']:.1%})",
                              *_quality_cells(pooled(a["quality"]))] for name, a in r["assets"].items()])
    for name, a in r["assets"].items():
        m = a["memory"]
        lines += ["", f"## {name}", "",
                  f"- object {a['object']}, config {a['config']}, {a['faces']} faces, L = {a['levels']}, "
                  f"T = {a['table_size']}; textures {m['texture_size'][0]}x{m['texture_size'][1]}", ""]
        lines += ["### Quality (decoded vs reference)", ""]
        lines += markdown_table(["view", *QUALITY_HEADERS], [[q["view"], *_quality_cells(q)] for q in a["quality"]])
        lines += ["", "### Memory", ""]
        share = {k: f"{m[k] / m['reference_bytes']:.1%}" for k in ("features_bytes", "mlp_bytes", "topology_bytes")}
        lines += markdown_table(["part", "bytes", "rate"], [
            ["feature tables (fp16 textures)", m["features_bytes"], share["features_bytes"]],
            ["MLP (fp32)", m["mlp_bytes"], share["mlp_bytes"]],
            ["owner tables (uint texture)", m["topology_bytes"], share["topology_bytes"]],
            ["neural: features + MLP", m["neural_bytes"], f"{m['rate_features_mlp']:.1%}"],
            ["neural: + owner tables", m["neural_bytes_all"], f"{m['rate_all']:.1%}"],
            ["uncompressed textures (3 x RGB8)", m["reference_bytes"], "100%"]])
        lines += ["", "### Baselines (reference view of the compressed textures vs the uncompressed, views pooled)", ""]
        rows = [["neural (decoded)", m["neural_bytes"], f"{m['rate_features_mlp']:.1%}",
                 *_quality_cells(pooled(a["quality"]))]]
        for b in a["baselines"]:
            rows.append([b["codec"], b["bytes"], f"{b['rate']:.1%}", *_quality_cells(pooled(b["quality"]))]
                        if b["available"] else [b["codec"], "unavailable", "—", b["reason"]] + [""] * 8)
        lines += markdown_table(["textures", "bytes", "rate", *QUALITY_HEADERS], rows)
        e = a["equal_bytes"]
        lines += ["", "At equal bytes (closest codec total):", "",
                  _equal_bytes_line("features + MLP", e["features_mlp"]),
                  _equal_bytes_line("+ owner tables", e["with_owner_tables"]),
                  _equal_bytes_line("features + MLP, ASTC only", e["astc_features_mlp"]),
                  _equal_bytes_line("+ owner tables, ASTC only", e["astc_with_owner_tables"])]
        d = a["decode"]
        ratio = d["decoded_over_reference"]
        verdict = {"faster": "decoded slower", "slower": "decoded faster"}.get(ratio["verdict"], ratio["verdict"])
        lines += ["", f"### Decode cost ({d['width']}x{d['height']}, shaded, coverage {d['coverage']:.0%}; "
                  f"clock: {d['clock']['clock']}, {d['clock']['clock_note']})", ""]
        lines += markdown_table(["", "value"], [
            ["fetches / pixel (plan)", d["plan"]["fetches"]], ["FLOPs / pixel (plan)", d["plan"]["flops"]],
            ["frame, decoded (median ms)", f"{1e3 * d['ms']['decoded']['median_s']:.2f}"],
            ["frame, reference textures, decoder compiled out (median ms)",
             f"{1e3 * d['ms']['reference']['median_s']:.2f}"],
            ["G-buffer pass alone, in both frames (median ms)", f"{1e3 * d['ms']['gbuffer']['median_s']:.2f}"],
            ["decoded / reference (min..max)",
             f"{_x(ratio['median'])} ({_x(ratio['low'])}..{_x(ratio['high'])}): {verdict}"],
            ["first draw, s (llvmpipe JIT-compiles here unless its shader cache holds the program)",
             _cell(a["first_draw_s"])]])
    lines.append("")
    return "\n".join(lines)


def plot(r: dict, path: Path) -> None:
    """Pooled albedo PSNR against bytes, one panel per object: neural configurations (filled:
    features + MLP; hollow: + owner tables) and the codecs of that object's textures."""
    plt = matplotlib_pyplot()
    objects = {}
    for name, a in r["assets"].items():
        objects.setdefault(a["object"] or name, []).append((name, a))
    fig, axes = plt.subplots(1, len(objects), figsize=(5 * len(objects), 4), squeeze=False)
    for ax, (obj, assets) in zip(axes[0], objects.items()):
        codec_rows = [b for b in assets[0][1]["baselines"] if b["available"]
                      and pooled(b["quality"])["albedo_psnr"] != "inf"]
        for family, marker in (("BC", "s"), ("ASTC", "^")):
            pts = [b for b in codec_rows if b["codec"].startswith(family)]
            ax.plot([b["bytes"] for b in pts], [pooled(b["quality"])["albedo_psnr"] for b in pts], marker,
                    linestyle="-" if family == "ASTC" else "none", label=family)
            for b in pts:
                ax.annotate(b["codec"].replace("ASTC ", ""), (b["bytes"], pooled(b["quality"])["albedo_psnr"]),
                            fontsize=6)
        for name, a in assets:
            db = pooled(a["quality"])["albedo_psnr"]
            if db == "inf":
                continue
            line, = ax.plot([a["memory"]["neural_bytes"]], [db], "o", label=f"neural {a['config'] or name}")
            ax.plot([a["memory"]["neural_bytes_all"]], [db], "o", mfc="none", color=line.get_color())
        ax.set_xscale("log")
        ax.set_xlabel("bytes")
        ax.set_ylabel("albedo PSNR (dB)")
        ax.set_title(f"{obj} (hollow: neural + owner tables)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, format="png")
    plt.close(fig)


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


SUITE = SuiteEntry(sizes={
    "cpu": Sizing(("--assets", "trained/uvfree_material_fruit_balanced", "--quality-size", "128",
                   "--width", "512", "--height", "384", "--rounds", "5", "--warmup", "1",
                   "--codecs", "BC1,BC7,ASTC 6x6,ASTC 8x8"), 90),
    # the thesis times a 1280x720 query
    "device": Sizing(("--width", "1280", "--height", "720", "--rounds", "15"), 80),
}, claims=CLAIMS, headlines=headlines)
