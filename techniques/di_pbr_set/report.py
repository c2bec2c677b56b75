"""How good a compressed PBR set is, and the asset's report: per-lane-group quality of a decoded
set, ASTC on the same two RGBA8 textures, the rendered mesh's PSNR, and the markdown table; the
``gltf_*`` twins score the glTF mode's lanes (gltf_lanes.py: a two-lane normal, metallic)."""
from __future__ import annotations

import numpy as np

from inshade.metrics import psnr, srgb_oetf
from inshade.models.pbr_lanes import CHANNELS, LANES

ASTC_BLOCKS = (4, 5, 6, 8)


def lane_metrics(test: np.ndarray, ref: np.ndarray) -> dict:
    """Per lane group: PSNR of the 8-bit values (albedo in sRGB-encoded bytes, as texture codecs
    are scored) and, for the normal, the mean / 99th-percentile angle between decoded normals."""
    t8 = np.round(np.clip(test, 0.0, 1.0) * 255.0)
    r8 = np.round(np.clip(ref, 0.0, 1.0) * 255.0)
    out = {}
    for name, (first, width) in LANES.items():
        out[f"psnr_{name}"] = round(psnr(t8[..., first:first + width], r8[..., first:first + width], 255.0), 3)
    nt, nr = test[..., 3:6] * 2.0 - 1.0, ref[..., 3:6] * 2.0 - 1.0
    cos = np.sum(nt * nr, -1) / np.maximum(np.linalg.norm(nt, axis=-1) * np.linalg.norm(nr, axis=-1), 1e-12)
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    out["normal_mean_deg"] = round(float(angle.mean()), 3)
    out["normal_p99_deg"] = round(float(np.percentile(angle, 99)), 3)
    out["psnr_all_lanes"] = round(psnr(t8, r8, 255.0), 3)
    return out


def gltf_lane_metrics(test: np.ndarray, ref: np.ndarray) -> dict:
    """``lane_metrics`` for the glTF mode's lanes: PSNR of the 8-bit values per group (albedo
    sRGB-encoded; the normal's two lanes) and the angle between the normals the pass rebuilds."""
    from inshade.techniques.di_pbr_set.gltf_lanes import LANES as GLTF_LANES, unit_normals

    def db(a, b):   # a lane the decode reproduces exactly (e.g. a constant metallic) is null, not Infinity
        value = psnr(a, b, 255.0)
        return round(value, 3) if np.isfinite(value) else None

    t8 = np.round(np.clip(test, 0.0, 1.0) * 255.0)
    r8 = np.round(np.clip(ref, 0.0, 1.0) * 255.0)
    out = {f"psnr_{name}": db(t8[..., a:a + w], r8[..., a:a + w]) for name, (a, w) in GLTF_LANES.items()}
    cos = np.clip(np.sum(unit_normals(np.clip(test, 0.0, 1.0)) * unit_normals(ref), -1), -1.0, 1.0)
    angle = np.degrees(np.arccos(cos))
    out["normal_mean_deg"] = round(float(angle.mean()), 3)
    out["normal_p99_deg"] = round(float(np.percentile(angle, 99)), 3)
    out["psnr_all_lanes"] = db(t8, r8)
    return out


def astc_rows(set8: tuple[np.ndarray, np.ndarray], ref: np.ndarray, measure=lane_metrics) -> list[dict]:
    """ASTC (LDR, the benchmark's quality) on the same two RGBA8 textures, per block size, scored by
    ``measure`` (the lanes' metrics)."""
    from inshade.bench.codecs import ASTC_QUALITY, CodecError, astc_roundtrip

    rows = []
    raw = ref.shape[0] * ref.shape[1] * CHANNELS
    for block in ASTC_BLOCKS:
        try:
            decoded, nbytes = zip(*(astc_roundtrip(img, block) for img in set8))
        except CodecError as exc:
            rows.append({"codec": f"ASTC {block}x{block}", "available": False, "reason": str(exc)})
            continue
        test = np.concatenate(decoded, -1).astype(np.float32) / 255.0
        rows.append({"codec": f"ASTC {block}x{block}", "available": True, "bytes": int(sum(nbytes)),
                     "ratio": round(raw / sum(nbytes), 3), "settings": f"2 RGBA textures, quality {ASTC_QUALITY:g}",
                     **measure(test, ref)})
    return rows


def render_psnr(test: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> float:
    """PSNR over mesh pixels of display values (linear clamped to [0, 1], sRGB-encoded, 8-bit)."""
    a = np.round(srgb_oetf(np.clip(test[..., :3], 0, 1)) * 255.0)
    b = np.round(srgb_oetf(np.clip(ref[..., :3], 0, 1)) * 255.0)
    return psnr(a, b, 255.0, mask=mask)


DECODERS = (("di_glsl_exact", "DI (GLSL exact)"), ("di_glsl_fast", "DI (GLSL fast)"), ("di_torch", "DI (torch)"))
TITLES = {"ao": "AO", "all_lanes": "all lanes"}      # a lane group's column title where not its name


def _db(value) -> str:
    return f"{value:.2f}"


def _db_or_exact(value) -> str:     # a lane the decode reproduces exactly has no PSNR (null)
    return "exact" if value is None else f"{value:.2f}"


def lane_columns(lanes, db) -> list[tuple]:
    """(title, cell(sizes, quality)) of each of ``lanes``' PSNR columns, then the one of all lanes, as
    ``db`` shows a PSNR; the normal's mean / p99 angle beside the normal's PSNR."""
    columns = []
    for lane in (*lanes, "all_lanes"):
        columns.append((f"{TITLES.get(lane, lane)} dB", lambda sizes, q, key=f"psnr_{lane}": db(q[key])))
        if lane == "normal":
            columns.append(("normal mean / p99 deg",
                            lambda sizes, q: f"{q['normal_mean_deg']:.2f} / {q['normal_p99_deg']:.2f}"))
    return columns


def quality_table(metrics: dict, columns, rendered) -> str:
    """What both reports end with: the table of DI's decoders and ASTC's block sizes (codec, bytes,
    then ``columns``: (title, cell(sizes, quality)), ``sizes`` holding bytes and ratio), a blank line,
    DI's training line and, where the asset was rendered, ``rendered(metrics["render"])``."""
    t = metrics["texture"]

    def row(name, sizes, q):
        return "| " + " | ".join([name, str(sizes["bytes"]), *(cell(sizes, q) for _, cell in columns)]) + " |"

    lines = ["| " + " | ".join(["codec", "bytes", *(title for title, _ in columns)]) + " |",
             "|---" * (len(columns) + 2) + "|"]
    lines += [row(label, t, metrics[key]) for key, label in DECODERS if key in metrics]
    lines += [row(a["codec"], a, a) if a["available"] else f"| {a['codec']} | unavailable: {a['reason']} |||||||"
              for a in metrics.get("astc", [])]
    device = metrics.get("device", "cpu")
    lines += ["", f"DI: N_p {t['n_primary']}, N_c {t['n_cascaded']}, {t['steps']} steps, "
                  f"{t['train_seconds']:.0f} s training on {'1 CPU thread' if device == 'cpu' else device}."]
    if "render" in metrics:
        lines.append(rendered(metrics["render"]))
    return "\n".join(lines) + "\n"


def markdown(metrics: dict) -> str:
    """The asset's quality table: DI (GLSL-decoded, both LUT paths) against ASTC on the same lanes."""
    t = metrics["texture"]
    lines = [f"# PBR set (8 lanes) compressed with DI: {t['width']}x{t['height']}", "",
             f"- GL_RENDERER: `{metrics.get('gl_renderer', 'n/a')}`",
             "- PSNR of 8-bit lane values (albedo sRGB-encoded) against the uncompressed set; normal: "
             "angle between decoded and original normals", ""]
    columns = [("ratio", lambda sizes, q: f"{sizes['ratio']:.2f}"), *lane_columns(LANES, _db)]

    def rendered(r):
        return (f"Rendered torus ({r['size']}^2, {r['lights']} lights + environment): DI vs uncompressed "
                f"{r['psnr_di_vs_uncompressed']:.2f} dB over {r['covered_pixels']} mesh pixels (display sRGB 8-bit).")

    return "\n".join(lines) + "\n" + quality_table(metrics, columns, rendered)


def gltf_markdown(metrics: dict) -> str:
    """The glTF mode's report: the decoded lanes against the bake (DI and ASTC), the sizes against
    the file's textures, and the render against the file's own material."""
    from inshade.techniques.di_pbr_set.gltf_lanes import LANES as GLTF_LANES

    t, src, bake = metrics["texture"], metrics["source"], metrics["bake"]
    lines = [f"# {src['file']}, material {src['material']} ({src['material_name'] or 'unnamed'}): "
             f"PBR set (8 lanes) compressed with DI", "",
             f"- GL_RENDERER: `{metrics.get('gl_renderer', 'n/a')}`",
             f"- lanes: albedo (sRGB-encoded), normal x, y (z rebuilt), roughness, occlusion, metallic, baked at "
             f"{bake['size']}x{bake['size']} over mesh uv origin {bake['origin']}, extent {bake['extent']}, "
             f"repeat {bake['repeat']} (size from {bake['size_from']})",
             f"- DI: {t['bytes']} bytes, {t['ratio']:.2f}x the 8-lane bake, {src['ratio_vs_lane_textures']:.2f}x "
             f"the file's lane textures as RGBA8 ({src['lane_texture_bytes_rgba8']} bytes)",
             "- PSNR of 8-bit lane values against the bake; normal: angle between rebuilt normals", ""]

    def rendered(r):
        return (f"Rendered at the scene camera ({r['size']}^2, {r['lights']} lights + environment): DI vs the "
                f"file's material {r['psnr_di_vs_reference']:.2f} dB over its {r['material_pixels']} pixels "
                "(display sRGB 8-bit; DI at the base level, the reference mip-mapped).")

    return "\n".join(lines) + "\n" + quality_table(metrics, lane_columns(GLTF_LANES, _db_or_exact), rendered)
