"""The hash_grid bench's report: markdown tables (the bars, one section per application, bytes, what
is not compared) and the plot (quality per network against each bar, ms per frame)."""
from __future__ import annotations

from pathlib import Path

from inshade.bench.harness import machine_markdown, markdown_table, matplotlib_pyplot

from .bench_claims import CLAIMS, PRIMARY, headlines

TITLES = {"image": "Image", "sdf": "SDF", "radiance_field": "Radiance field"}
MB = 1e6


def _f(v, spec: str = ".2f") -> str:
    return "—" if v is None else format(v, spec)


def _ms(v: float) -> str:
    return f"{v:.0f}" if v >= 100 else f"{v:.1f}" if v >= 1 else f"{v:.2f}"


def frame_cell(f: dict | None) -> str:
    if f is None:
        return "—"
    if "ms_median" in f:
        return _ms(f["ms_median"])
    if "ms_projected" in f:
        return f"~{_ms(f['ms_projected'])} (projected)"
    return f"skipped (~{f['predicted_ms'] / 1e3:.0f} s predicted)"


def met(row: dict, app: dict | None) -> str:
    """Whether a headline row meets its bar (the image's also needs <= 1 MB and a 2K picture)."""
    c, v = CLAIMS[row["claim"]], row["ours_value"]
    ok = v >= c.value if c.higher_better else v <= c.value
    if row["claim"] in ("image_mlp", "radiance_field_mlp"):
        ok = v > 0
    elif row["claim"] == "sdf_mlp":
        ok = v > 1
    elif row["claim"] == "image":
        ours = next(r for r in app["rows"] if r["key"] == "hash_grid")
        ok = ok and ours["bytes"] <= MB and app["size"] >= 2048
    return "yes" if ok else "**no**"


def _bars(result: dict) -> list[str]:
    rows = [(h["subject"], h["measure"], h["paper_says"], h["ours"], met(h, result["apps"].get(h["subject"])))
            for h in headlines(result)]
    return markdown_table(("application", "measure", "bar", "measured", "met"), rows) + [""]


def _sizes(result: dict) -> list[str]:
    return [str(s) for s in result["timing"]["sizes"]]


def _speed_cells(row: dict, sizes) -> list[str]:
    return [_f(row.get("first_draw_s")), *(frame_cell(row.get("frames", {}).get(s)) for s in sizes)]


def _image(app: dict, sizes) -> list[str]:
    head = ("network", "bytes", "PSNR sRGB dB", "PSNR linear dB", "FLIP", "FLOPs/px", "fetches/px", "first draw s",
            *(f"ms @{s}²" for s in sizes))
    rows, notes = [], []
    for r in app["rows"]:
        if "not_compared" in r:
            notes.append(f"- {r['name']}: not compared: {r['not_compared']}")
            continue
        q = r.get("quality") or {}
        rows.append((r["name"], r["bytes"], _f(q.get("psnr_srgb")), _f(q.get("psnr_linear")), _f(q.get("flip"), ".4f"),
                     r["flops_per_pixel"], r["fetches_per_pixel"], *_speed_cells(r, sizes)))
        notes.append(f"- {r['name']} ({r['architecture']}): quality: {r['quality_source']}")
    ours = app["rows"][0]
    notes.append(f"- the trainer's own PSNR of the hash grid (torch twin, fp16 tables as exported): "
                 f"{ours['trainer_quality']['psnr_srgb']:.2f} dB sRGB, {ours['trainer_quality']['psnr_linear']:.2f} dB linear")
    return markdown_table(head, rows, "lrrrrrrr" + "r" * len(sizes)) + [""] + notes


def _sdf(app: dict, sizes) -> list[str]:
    head = ("network", "bytes", "surface err / diag", "zero set→mesh / diag (p95)", "IoU", "evals/px", "FLOPs/px",
            "fetches/px", "ns/eval", "first draw s", *(f"ms @{s}²" for s in sizes))
    rows, notes = [], []
    for r in app["rows"]:
        q = r.get("quality") or {}
        zero = (f"{q['zero_set_to_mesh_mean_per_diagonal']:.2e} ({q['zero_set_to_mesh_p95_per_diagonal']:.2e})"
                if "zero_set_to_mesh_mean_per_diagonal" in q else "—")
        rows.append((r["name"], r["bytes"], _f(q.get("surface_abs_mean_per_diagonal"), ".2e"), zero,
                     _f(q.get("iou_uniform"), ".4f"), _f(r["evaluations_per_pixel"], ".1f"), r["flops_per_pixel"],
                     r["fetches_per_pixel"], _f(r["evaluation"]["ns_per_evaluation"], ".0f"), *_speed_cells(r, sizes)))
        notes.append(f"- {r['name']} ({r['architecture']}): quality: {r['quality_source']}")
    ours, mlp = app["rows"][0], app["rows"][1]
    notes += [f"- evaluations per pixel: the trace's twin (models/sdf.py) from the scene's camera at "
              f"{ours['evaluations']['counted_at']}² ({ours['evaluations']['trace_per_pixel']:.1f} trace steps, "
              f"{ours['evaluations']['hit_fraction']:.0%} of pixels hit, 6 normal evaluations each); the MLP-only "
              "row's per-pixel work is at the hash grid's evaluations",
              f"- ns/eval: passes/evaluate.frag over a {round(ours['evaluation']['points'] ** (1 / 3))}³ lattice of the "
              f"traced cube; MLP-only / hash grid: {mlp['cost_ratio']:.2f}x; {mlp['frames_note']}",
              f"- step: 1 / (safety x measured slope {app['lipschitz']['lipschitz_measured']:.3g}) = "
              f"{app['lipschitz']['step_scale']:.3g} (sound bound {app['lipschitz']['lipschitz_sound']:.3g})"]
    for name, a in app.get("also", {}).items():
        notes.append(f"- {name} (`{a.get('folder')}`, {a.get('bytes')} bytes, not equal bytes): surface err / diag "
                     f"{_f(a.get('surface_abs_mean_per_diagonal'), '.2e')}, IoU {_f(a.get('iou_uniform'), '.4f')}")
    return markdown_table(head, rows, "lrrrrrrrrr" + "r" * len(sizes)) + [""] + notes


def _radiance_field(app: dict, sizes) -> list[str]:
    head = ("network", "bytes", "held-out PSNR dB (GL)", "torch march dB", "evals/px", "FLOPs/px", "fetches/px",
            "ns/eval", "first draw s", *(f"ms @{s}²" for s in sizes))
    rows, notes = [], []
    for r in app["rows"]:
        q = r.get("quality") or {}
        gl = q.get("heldout_psnr") if r["key"] == "hash_grid" else None
        torch_march = q.get("heldout_psnr_torch") if r["key"] == "hash_grid" else q.get("heldout_psnr")
        rows.append((r["name"], r["bytes"], _f(gl), _f(torch_march), _f(r["evaluations_per_pixel"], ".1f"),
                     r["flops_per_pixel"], r["fetches_per_pixel"], _f(r["evaluation"]["ns_per_evaluation"], ".0f"),
                     *_speed_cells(r, sizes)))
        notes.append(f"- {r['name']} ({r['architecture']}): quality: {r['quality_source']}")
    ours, mlp = app["rows"][0], app["rows"][1]
    march = app["march"]
    notes += [f"- evaluations per pixel: the march's twin (radiance_field_march.py) from the scene's camera at "
              f"{ours['evaluations']['counted_at']}² with the occupancy grid ({march['occupancy_resolution']}³ cells, "
              f"{_f(march['occupied_fraction'], '.1%')} occupied; dt {march['step']:.4g}, at most {march['max_steps']} "
              "steps); the occupancy lookups of every step are in the frame times, not in FLOPs/px",
              f"- ns/eval: passes/evaluate.frag over a {round(ours['evaluation']['points'] ** (1 / 3))}³ lattice of the "
              f"box; MLP-only / hash grid: {mlp['cost_ratio']:.2f}x; {mlp['frames_note']}",
              "- held-out PSNR per view (GL): " + ", ".join(f"{v:.2f}" for v in ours["quality"]["heldout_psnr_per_view"])]
    return markdown_table(head, rows, "lrrrrrrrr" + "r" * len(sizes)) + [""] + notes


SECTIONS = {"image": _image, "sdf": _sdf, "radiance_field": _radiance_field}


def _bytes(result: dict) -> list[str]:
    rows = []
    for name, app in result["apps"].items():
        ours = app["rows"][0]
        plan = ours["plan"]
        gpu = plan["texture_bytes"] + plan["uniform_bytes"]
        inline = "inline" in plan["storage"]
        extra = (f"occupancy grid {app['occupancy_bytes']} B (8-bit cells)" if "occupancy_bytes" in app else
                 f"uncompressed RGB8 {app['uncompressed_bytes']} B" if "uncompressed_bytes" in app else "")
        rows.append((TITLES[name], app["table_bytes"], ours["bytes"] - app["table_bytes"], ours["bytes"],
                     f"{gpu}" + (" + MLP as literals in the program" if inline else ""), app["bytes_file"], extra))
    return markdown_table(("application", "grid tables (fp16) B", "MLP (fp32) B", "network B",
                           "GPU resources B (plan)", "bundle files B", "besides"), rows, "lrrrrrl") + [""]


def markdown(result: dict) -> str:
    m, t = result["machine"], result["timing"]
    sizes = _sizes(result)
    cache = "off" if (m.get("MESA_SHADER_CACHE_DISABLE") or "").lower() in ("true", "1") else "on"
    lines = ["# Hash grid + MLP (instant-NGP): image, SDF, radiance field", "",
             machine_markdown(m),
             f"- ms per frame: median of {t['frames']} draw{'s' * (t['frames'] != 1)} at each side after the first "
             f"draw, made at {t['probe']}² and reported apart (first draw s: llvmpipe JIT-compiles there; Mesa's shader "
             f"cache {cache}); {result.get('clock_note') or 'wall clock'}; a side predicted past {t['max_frame_s']:g} s "
             "a frame is skipped",
             "- FLOPs and fetches per pixel: the codegen plan per network evaluation x the evaluations a pixel makes "
             f"(the image: 1; the SDF and the radiance field: counted by the march's torch twin at {t['count_size']}²)",
             f"- FLIP: {result['flip']}" + ("; **quick run** (tiny sizes: a smoke test, not figures)" if result["quick"]
                                             else ""), "",
             "## Against the bars", ""] + _bars(result)
    for name, app in result["apps"].items():
        trained = app["trained"]
        lines += [f"## {TITLES[name]} (`{app['asset']}`)", "",
                  f"`{trained['command']}` (preset {trained['preset']}, {trained['date_utc']}, "
                  f"{_f(trained['train_seconds'], '.0f')} s of training)", ""] + SECTIONS[name](app, sizes) + [""]
    lines += ["## Bytes", ""] + _bytes(result)
    skipped = [f"- {k}: {v}" for app in result["apps"].values() for k, v in app.get("not_compared", {}).items()]
    if skipped:
        lines += ["## Not compared", ""] + skipped
    return "\n".join(lines) + "\n"


def plot(result: dict, path: Path) -> None:
    plt = matplotlib_pyplot()
    apps = list(result["apps"].items())
    fig, axes = plt.subplots(1, len(apps) + 1, figsize=(3.6 * (len(apps) + 1), 3.6))
    colours = {"hash_grid": "tab:blue", "mlp": "tab:orange", "di": "tab:green"}
    for ax, (name, app) in zip(axes, apps):
        rows = [r for r in app["rows"] if r.get("quality") and PRIMARY[name] in r["quality"]]
        ax.bar([r["name"] for r in rows], [r["quality"][PRIMARY[name]] for r in rows],
               color=[colours[r["key"]] for r in rows])
        c = CLAIMS[name]
        ax.axhline(c.value, color="k", ls="--", lw=1, label=f"bar {c.value:g}")
        if name == "sdf":
            ax.set_yscale("log")
        ax.set_ylabel("surface error / diagonal" if name == "sdf" else "PSNR dB")
        ax.set_title(f"{TITLES[name]}, {rows[0]['bytes'] / MB:.2f} MB each" if rows else TITLES[name], fontsize=9)
        ax.tick_params(axis="x", labelsize=7)
        ax.legend(fontsize=7)
    ax = axes[-1]
    size = _sizes(result)[0]
    labels, values, hatches, cols = [], [], [], []
    for name, app in apps:
        for r in app["rows"]:
            f = r.get("frames", {}).get(size, {})
            v = f.get("ms_median", f.get("ms_projected"))
            if v is not None:
                labels.append(f"{TITLES[name]}\n{r['name']}")
                values.append(v)
                hatches.append("//" if "ms_projected" in f else "")
                cols.append(colours[r["key"]])
    bars = ax.bar(range(len(values)), values, color=cols)
    for b, h in zip(bars, hatches):
        b.set_hatch(h)
    ax.set_xticks(range(len(values)), labels, fontsize=5, rotation=60, ha="right")
    ax.set_yscale("log")
    ax.set_ylabel(f"ms / frame at {size}² (hatched: projected)")
    fig.suptitle(f"hash grid + MLP vs equal-bytes alternatives — {result['machine']['gl_renderer']}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
