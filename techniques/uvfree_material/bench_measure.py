"""What `inshade bench uvfree_material` measures per asset, through the real GL driver (bench.py runs it,
bench_report.py writes it up): the decoded material and its uv textures rendered per channel group,
their quality metrics, the bundle's GPU bytes, the BC1/BC7/ASTC baselines and the codecs at equal
bytes, the decode cost, and the targets the report judges."""
from __future__ import annotations

import hashlib
import io
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np

from inshade.bench.harness import BenchError, clock_for, clock_record, interleave, paired_ratio

from . import CHANNEL_VIEWS, KIND

VIEWS = ("default", "close-up")
GROUPS = CHANNEL_VIEWS                         # the "channel" setting's choices: shaded + 5 groups
TEXTURES = ("albedo", "normal", "rma")         # objects.TEXTURES: <name>.png in the asset folder
TARGET_RATE, TARGET_ALBEDO_DB = 1 / 3, 32.0
TARGET_ASSETS = f"{KIND}_stump_high_"


# ---------------------------------------------------------------------------------------------
# assets

def load_asset(folder: Path):
    """(scene, bundle) of a uvfree_material asset folder; BenchError naming the folder otherwise."""
    from inshade.bundle import BundleError
    from inshade.scene.description import SceneError, load_scene

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
    """inshade.bench.codecs round trip of one uint8 RGB texture; CodecError when it cannot run."""
    from inshade.bench import codecs

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
    from inshade.bench.codecs import CodecError

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
# targets

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
