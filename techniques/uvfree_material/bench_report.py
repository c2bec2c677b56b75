"""The report of `inshade bench uvfree_material`: ``uvfree_material.md`` (targets, the summary, and
per asset its quality, memory, baselines, equal-bytes codecs and decode cost) and ``.png`` (pooled
albedo PSNR against bytes, per object), from the result bench.py writes."""
from __future__ import annotations

from pathlib import Path

from inshade.bench.harness import machine_markdown, markdown_table, matplotlib_pyplot

from . import KIND
from .bench_measure import TARGET_ALBEDO_DB, TARGET_ASSETS, TARGET_RATE, pooled

QUALITY_HEADERS = ["albedo PSNR (dB)", "albedo FLIP", "normal mean (deg)", "normal p95 (deg)", "roughness PSNR",
                   "metallic PSNR", "AO PSNR", "shaded PSNR", "shaded FLIP"]
QUALITY_KEYS = ["albedo_psnr", "albedo_flip", "normal_mean_deg", "normal_p95_deg", "roughness_psnr",
                "metallic_psnr", "ao_psnr", "shaded_psnr", "shaded_flip"]

FEATURE_STORAGE = {"f16": "fp16 textures", "f32": "fp32 textures", "u8": "unorm8 textures + per-lane scale/offset"}


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
            [f"feature tables ({FEATURE_STORAGE.get(m.get('features_precision', 'f16'), 'fp16 textures')})",
             m["features_bytes"], share["features_bytes"]],
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
