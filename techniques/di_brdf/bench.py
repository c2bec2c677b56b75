"""`inshade bench di_brdf`: learned (Differentiable Indirection) vs analytic BRDF shaders, same run.

The material-ball pass (shaders/passes/material_balls.frag.glsl) of the di_brdf_disney and di_brdf_ggx
assets, full screen at ``--size``, with 1-4 point lights, in three variants compiled from the same
scene: ``analytic`` (BRDF_VIEW 0), ``learned`` (1) and the ``diffuse`` baseline (3: albedo n.l / pi,
the pass's fixed cost -- ray-sphere, frame, material fetch, light loop). As in the paper's Table 1
the BRDF cost is the variant's time minus the baseline's; the ratio analytic / learned of those is
the speedup. Both LUT paths are timed: ``fast`` (hardware bilinear filtering, the paper's
recommendation) and ``exact`` (texelFetch + fp32 mix).

Timing (``inshade.bench.harness``): every variant is compiled and drawn ``--warmup`` times first
(llvmpipe JIT-compiles at the first draw), then all variants (LUT path x view x lights) are drawn
once per round for ``--rounds`` rounds, the order reversed every other round (ABBA), so load
drifts hit all alike. Each draw is timed by ``--clock`` (GL timer query on a hardware driver,
``draw(); glFinish()`` wall time on llvmpipe). Reported: medians and min..max per variant, the
BRDF cost per round (variant minus the diffuse baseline of the same round) and the speed-ups as the
median of the per-round ratios with their min..max; a speed-up whose rounds do not all agree
(min..max contains 1) is reported as "no difference". GL_RENDERER is logged.
Writes ``di_brdf.json``, ``di_brdf.md`` and ``di_brdf.png`` into ``--out``.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

from inshade.bench.contract import Bench, clock_option, option, sized
from inshade.bench.entry import Claim, claim_row, ratio_verdict
from inshade.bench.harness import (BenchError, Ratio, clock_for, clock_record, interleave,
                                   machine, machine_markdown, markdown_table, matplotlib_pyplot,
                                   paired_difference, paired_ratio, write_report)
from inshade.techniques.di_brdf import VIEWS as PASS_VIEWS

DEFAULT_OUT = "bench-out/brdf"
VIEWS = {v: PASS_VIEWS[v] for v in ("analytic", "learned", "diffuse")}   # the timed views (no split)
LIGHTS = (1, 2, 3, 4)


@dataclass
class Settings:
    out: str = option(DEFAULT_OUT, f"output folder (default {DEFAULT_OUT})")
    assets: str = option("trained", "folder holding di_brdf_disney/ and di_brdf_ggx/ (default %(default)s)")
    size: int = option(512, "square target size in pixels (default %(default)s)")
    rounds: int = option(7, "timed rounds per variant (default %(default)s)")
    warmup: int = option(2, "untimed draws per variant first (default %(default)s)")
    filters: str = option("fast,exact", "LUT paths to time (default %(default)s)")
    models: str = option("disney,ggx", "assets to time (default %(default)s)")
    clock: str = clock_option()


def _time_model(folder: Path, size: int, filters, rounds: int, warmup: int, clock_name: str, log) -> dict:
    from inshade.scene.camera import camera_from_dict
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(folder)
    camera = camera_from_dict({"type": "plane2d", "aspect": 1.0})
    renderers, info = {}, {}
    try:
        for f in filters:
            for view, code in VIEWS.items():
                t0 = time.perf_counter()
                r = SceneRenderer(scene, settings={"view": code, "lut_filter": f, "lights": 1})
                r.render_network(camera, size, size)
                r.ctx.finish()
                info[f"{f}/{view}"] = {"compile_and_first_draw_s": round(time.perf_counter() - t0, 3)}
                renderers[(f, view)] = r
        first = next(iter(renderers.values()))
        clock = clock_for(first.ctx, clock_name, software=first.gl["software"])

        def draw(r, n):
            def fn():
                r.set_setting("lights", n)
                r._net_key = None              # force the network pass to redraw
                r.render_network(camera, size, size)
            return fn

        variants = {(f, v, n): draw(r, n) for n in LIGHTS for (f, v), r in renderers.items()}
        timings = interleave(variants, rounds=rounds, warmup=warmup, clock=clock,
                             progress=lambda i, total: log(f"  {folder.name}: round {i}/{total}"))
        gl = first.gl
    finally:
        for r in renderers.values():
            r.release()
    rows = []
    for f in filters:
        for n in LIGHTS:
            t = {v: timings[(f, v, n)] for v in VIEWS}
            ms = {v: [x * 1e3 for x in t[v].samples] for v in VIEWS}
            a = paired_difference(ms["analytic"], ms["diffuse"])
            lrn = paired_difference(ms["learned"], ms["diffuse"])
            rows.append({"filter": f, "lights": n,
                         "analytic_ms": t["analytic"].median * 1e3, "learned_ms": t["learned"].median * 1e3,
                         "diffuse_ms": t["diffuse"].median * 1e3,
                         "analytic_minus_base_ms": a.median, "learned_minus_base_ms": lrn.median,
                         "analytic_minus_base_range_ms": [a.min, a.max],
                         "learned_minus_base_range_ms": [lrn.min, lrn.max],
                         # > 1: learned faster; per-round ratios, the verdict from their min..max
                         "speedup": paired_ratio(a.samples, lrn.samples).to_dict(),
                         "speedup_total": paired_ratio(ms["analytic"], ms["learned"]).to_dict(),
                         "timings": {v: t[v].to_dict() for v in VIEWS}})
    return {"gl": {k: gl[k] for k in ("vendor", "renderer", "version")}, "machine": machine(gl),
            **clock_record(clock), "variants": info, "rows": rows}


def run(args) -> int:
    if args.size < 1 or args.rounds < 1 or args.warmup < 0:
        raise BenchError("--size and --rounds must be >= 1, --warmup >= 0")
    filters = [f for f in args.filters.split(",") if f]
    result = {"benchmark": "brdf", "size": args.size, "rounds": args.rounds, "warmup": args.warmup, "models": {}}
    log = lambda s: print(s, file=sys.stderr)  # noqa: E731
    for m in [m for m in args.models.split(",") if m]:
        folder = Path(args.assets) / f"di_brdf_{m}"
        if not (folder / "scene.json").is_file():
            result["models"][m] = {"unavailable": f"no asset at {folder} (build it: inshade train di_brdf {m})"}
            continue
        result["models"][m] = _time_model(folder, args.size, filters, args.rounds, args.warmup, args.clock, log)
        log(f"inshade: {m}: GL_RENDERER={result['models'][m]['gl']['renderer']}")
    timed = [r for r in result["models"].values() if "machine" in r]
    result["machine"] = timed[0].pop("machine") if timed else machine()
    for r in timed[1:]:
        r.pop("machine")
    result["clock"] = timed[0]["clock"] if timed else None
    write_report(args.out, "di_brdf", result, markdown, plot)
    return 0


def _ratio_text(r: dict) -> str:
    return Ratio.from_dict(r).describe("learned faster", "learned slower")


def markdown(result: dict) -> str:
    size = result["size"]
    lines = [f"# inshade bench di_brdf ({size}x{size}, median of {result['rounds']} interleaved rounds)",
             "", machine_markdown(result["machine"])]
    for m, r in result["models"].items():
        if "unavailable" in r:
            continue
        lines.append(f"- {m}: clock {r['clock']}: {r['clock_note']}")
        break
    lines += ["- BRDF cost = variant minus the diffuse baseline drawn in the same round; speed-up = analytic / "
              "learned per round, median (min–max over rounds); 'no difference' when the rounds disagree "
              "(min–max contains 1)", ""]
    for m, r in result["models"].items():
        if "unavailable" in r:
            lines += [f"## {m}: unavailable ({r['unavailable']})", ""]
            continue
        lines += [f"## {m} on `{r['gl']['renderer']}`", ""]
        lines += markdown_table(
            ["LUT path", "lights", "analytic ms", "learned ms", "diffuse base ms", "analytic - base",
             "learned - base", "speedup (minus base)", "speedup (total)"],
            [[row["filter"], row["lights"], f"{row['analytic_ms']:.2f}", f"{row['learned_ms']:.2f}",
              f"{row['diffuse_ms']:.2f}", _cost(row, "analytic"), _cost(row, "learned"),
              _ratio_text(row["speedup"]), _ratio_text(row["speedup_total"])] for row in r["rows"]],
            "lrrrrrrrr")
        lines.append("")
    return "\n".join(lines) + "\n"


def _cost(row: dict, view: str) -> str:
    lo, hi = row[f"{view}_minus_base_range_ms"]
    return f"{row[f'{view}_minus_base_ms']:.2f} ({lo:.2f}–{hi:.2f})"


def plot(result: dict, path: Path) -> None:
    plt = matplotlib_pyplot()

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for m, r in result["models"].items():
        for row_filter in sorted({row["filter"] for row in r.get("rows", [])}):
            rows = [row for row in r["rows"] if row["filter"] == row_filter]
            n = [row["lights"] for row in rows]
            for view, style in (("analytic", "o-"), ("learned", "s--")):
                med = [row[f"{view}_minus_base_ms"] for row in rows]
                lo = [mm - row[f"{view}_minus_base_range_ms"][0] for mm, row in zip(med, rows)]
                hi = [row[f"{view}_minus_base_range_ms"][1] - mm for mm, row in zip(med, rows)]
                ax.errorbar(n, med, yerr=[lo, hi], fmt=style, capsize=3, label=f"{m} {view} ({row_filter})")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_xlabel("point lights")
    ax.set_ylabel("ms above the diffuse baseline (median, min–max of rounds)")
    ax.set_xticks(list(LIGHTS))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    renderers = {r["gl"]["renderer"] for r in result["models"].values() if "gl" in r}
    ax.set_title(f"BRDF cost, {result['size']}^2 ({', '.join(sorted(renderers))})", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper

CLAIMS = {"disney4": Claim("Differentiable Indirection (Datta et al. 2023), Table 1",
                           "Disney BRDF cost (minus the diffuse base), analytic / learned, 4 lights, hardware "
                           "filtering", "0.742 / 0.255 ms: 2.9x on a mobile RTX 3070 Ti at 4K", 0.742 / 0.255)}


def headlines(r: dict) -> list[dict]:
    rows = []
    for model in ("disney",):
        for row in r["models"].get(model, {}).get("rows", []):
            if row["filter"] == "fast" and row["lights"] == 4:
                rows.append(claim_row(CLAIMS, "di_brdf", "disney4", f"{ratio_verdict(row['speedup'])}; analytic "
                                      f"{row['analytic_minus_base_ms']:.3f} ms, learned "
                                      f"{row['learned_minus_base_ms']:.3f} ms at {r['size']}²",
                                      row["speedup"]["median"], model))
    return rows


BENCH = Bench("di_brdf", __doc__, Settings, run, claims=CLAIMS, headlines=headlines,
              sizes={"cpu": sized(30),
                     "device": sized(25, size=2880, rounds=15)})   # 2880^2 ~ the paper's 4K pixel count (Table 1)
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite
