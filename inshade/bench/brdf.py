"""`inshade bench brdf`: learned (Differentiable Indirection) vs analytic BRDF shaders, same run.

The material-ball pass (shaders/passes/material_balls.frag.glsl) of the di_disney and di_ggx
assets, full screen at ``--size``, with 1-4 point lights, in three variants compiled from the same
scene: ``analytic`` (BRDF_VIEW 0), ``learned`` (1) and the ``diffuse`` baseline (3: albedo n.l / pi,
the pass's fixed cost -- ray-sphere, frame, material fetch, light loop). As in the paper's Table 1
the BRDF cost is the variant's time minus the baseline's; the ratio analytic / learned of those is
the speedup. Both LUT paths are timed: ``fast`` (hardware bilinear filtering, the paper's
recommendation) and ``exact`` (texelFetch + fp32 mix).

Timing: every variant is compiled and drawn ``--warmup`` times first (llvmpipe JIT-compiles at the
first draw), then the variants are drawn in interleaved rounds (side by side, so load drifts hit
all alike) and the median of ``draw(); glFinish()`` wall time is reported. GL_RENDERER is logged.
Writes ``brdf.json``, ``brdf.md`` and ``brdf.png`` into ``--out``.
"""
from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from pathlib import Path

DEFAULT_OUT = "bench-out/brdf"
VIEWS = {"analytic": 0, "learned": 1, "diffuse": 3}


def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    p.add_argument("--out", default=DEFAULT_OUT, help=f"output folder (default {DEFAULT_OUT})")
    p.add_argument("--assets", default="trained", help="folder holding di_disney/ and di_ggx/ (default %(default)s)")
    p.add_argument("--size", type=int, default=512, help="square target size in pixels (default %(default)s)")
    p.add_argument("--rounds", type=int, default=7, help="timed rounds per variant (default %(default)s)")
    p.add_argument("--warmup", type=int, default=2, help="untimed draws per variant first (default %(default)s)")
    p.add_argument("--filters", default="fast,exact", help="LUT paths to time (default %(default)s)")
    p.add_argument("--models", default="disney,ggx", help="assets to time (default %(default)s)")
    return p


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="inshade bench brdf", description=__doc__.splitlines()[0])
    add_arguments(p)
    return run(p.parse_args(argv))


def _time_model(folder: Path, size: int, filters, rounds: int, warmup: int, log) -> dict:
    from inshade.viewer.camera import camera_from_dict
    from inshade.viewer.renderer import SceneRenderer
    from inshade.viewer.scene import load_scene

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
        ctx = next(iter(renderers.values())).ctx
        gl = next(iter(renderers.values())).gl
        times = {k: {n: [] for n in range(1, 5)} for k in renderers}

        def draw(r, n):
            r.set_setting("lights", n)
            r._net_key = None              # force the network pass to redraw
            t = time.perf_counter()
            r.render_network(camera, size, size)
            ctx.finish()
            return time.perf_counter() - t

        for k, r in renderers.items():
            for n in range(1, 5):
                for _ in range(warmup):
                    draw(r, n)
        for i in range(rounds):
            for n in range(1, 5):
                for k, r in renderers.items():
                    times[k][n].append(draw(r, n))
            log(f"  {folder.name}: round {i + 1}/{rounds}")
    finally:
        for r in renderers.values():
            r.release()
    rows = []
    for f in filters:
        for n in range(1, 5):
            med = {v: statistics.median(times[(f, v)][n]) * 1e3 for v in VIEWS}
            a, lrn = med["analytic"] - med["diffuse"], med["learned"] - med["diffuse"]
            rows.append({"filter": f, "lights": n, "analytic_ms": med["analytic"], "learned_ms": med["learned"],
                         "diffuse_ms": med["diffuse"], "analytic_minus_base_ms": a, "learned_minus_base_ms": lrn,
                         "speedup": (a / lrn) if lrn > 0 else float("inf"),
                         "speedup_total": med["analytic"] / med["learned"]})
    return {"gl": {k: gl[k] for k in ("vendor", "renderer", "version")}, "variants": info, "rows": rows}


def run(args) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    filters = [f for f in args.filters.split(",") if f]
    result = {"size": args.size, "rounds": args.rounds, "warmup": args.warmup, "platform": platform.platform(),
              "python": sys.version.split()[0], "models": {}}
    log = lambda s: print(s, file=sys.stderr)  # noqa: E731
    for m in [m for m in args.models.split(",") if m]:
        folder = Path(args.assets) / f"di_{m}"
        if not (folder / "scene.json").is_file():
            result["models"][m] = {"unavailable": f"no asset at {folder} (build it: inshade train di_{m})"}
            continue
        result["models"][m] = _time_model(folder, args.size, filters, args.rounds, args.warmup, log)
        log(f"inshade: {m}: GL_RENDERER={result['models'][m]['gl']['renderer']}")
    (out / "brdf.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / "brdf.md").write_text(markdown(result))
    plot(result, out / "brdf.png")
    print((out / "brdf.md").read_text())
    return 0


def markdown(result: dict) -> str:
    lines = [f"# inshade bench brdf ({result['size']}x{result['size']}, median of {result['rounds']} rounds)", ""]
    for m, r in result["models"].items():
        if "unavailable" in r:
            lines += [f"## {m}: unavailable ({r['unavailable']})", ""]
            continue
        lines += [f"## {m} on `{r['gl']['renderer']}`", "",
                  "| LUT path | lights | analytic ms | learned ms | diffuse base ms | analytic - base | "
                  "learned - base | speedup (minus base) | speedup (total) |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for row in r["rows"]:
            lines.append(f"| {row['filter']} | {row['lights']} | {row['analytic_ms']:.2f} | {row['learned_ms']:.2f} | "
                         f"{row['diffuse_ms']:.2f} | {row['analytic_minus_base_ms']:.2f} | "
                         f"{row['learned_minus_base_ms']:.2f} | {row['speedup']:.2f}x | {row['speedup_total']:.2f}x |")
        lines.append("")
    return "\n".join(lines) + "\n"


def plot(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for m, r in result["models"].items():
        for row_filter in sorted({row["filter"] for row in r.get("rows", [])}):
            rows = [row for row in r["rows"] if row["filter"] == row_filter]
            n = [row["lights"] for row in rows]
            ax.plot(n, [row["analytic_minus_base_ms"] for row in rows], "o-", label=f"{m} analytic ({row_filter})")
            ax.plot(n, [row["learned_minus_base_ms"] for row in rows], "s--", label=f"{m} learned ({row_filter})")
    ax.set_xlabel("point lights")
    ax.set_ylabel("ms above the diffuse baseline")
    ax.set_xticks([1, 2, 3, 4])
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    renderers = {r["gl"]["renderer"] for r in result["models"].values() if "gl" in r}
    ax.set_title(f"BRDF cost, {result['size']}^2 ({', '.join(sorted(renderers))})", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
