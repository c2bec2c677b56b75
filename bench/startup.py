"""`inshade bench startup`: how long a first picture takes, cold and warm, per weight storage.

Per shipped asset (or the ones named) and storage (``--storages``: the scene's ``auto`` plan and each
fixed one), ``inshade render ASSET --storage S`` at ``--size`` in a fresh process, as a user's first
run: cold (Mesa's shader cache off, an empty draw history: every program JIT-compiles on a software
driver) and, for ``--warm-storages``, warm (a second run with Mesa's shader cache filled by the
first, in a cache folder of the run's own). Each run's wall time (process start to the image
written) and its first draw (what the draw history recorded: the JIT on a software driver, plus the
frame), the storage the plan chose and its totals; per asset the quickest cold storage. Writes
``startup.json``, ``startup.md`` and ``startup.png`` into ``--out``.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from inshade.bench.contract import Bench, option, sized
from inshade.bench.entry import Claim, claim_row
from inshade.bench.harness import asset_folders, machine, machine_markdown, matplotlib_pyplot, write_report
from inshade.viewer.virtual_display import start_xvfb

DEFAULT_OUT = "bench-out/startup"
STORAGES = ("auto", "inline", "ubo", "texture")
FIRST_FRAME_S = 10.0   # the first picture a user should wait for, cold


def _storages(text: str) -> list[str]:
    names = [v.strip() for v in text.split(",") if v.strip()]
    bad = [n for n in names if n not in STORAGES]
    if bad:
        raise argparse.ArgumentTypeError(f"unknown storage {', '.join(bad)} (choose from {', '.join(STORAGES)})")
    return names


@dataclass
class Settings:
    assets: list[str] = option((), "asset folders (default: every shipped asset)", positional="ASSET", nargs="*")
    storages: list[str] = option(STORAGES, "storages timed cold, comma-separated", parse=_storages)
    warm_storages: list[str] = option(("auto",), "storages also timed warm (a second run), comma-separated",
                                      parse=_storages)
    size: int = option(256, "image side in pixels")
    timeout: int = option(900, "seconds a run may take before it is stopped and reported")
    no_viewer: bool = option(False, "leave the window out")
    out: str = option(DEFAULT_OUT, "output folder")
    quick: bool = option(False, "one small asset, two storages (a smoke run)")


def render_once(asset: Path, storage: str, size: int, tmp: Path, timeout: int, mesa_cache: Path | None) -> dict:
    """One ``inshade render`` in a fresh process: its wall time, first draw and plan; Mesa's shader
    cache off, or kept in ``mesa_cache``."""
    history = Path(tempfile.mkdtemp(dir=tmp))
    env = {**os.environ, "INSHADE_CACHE_DIR": str(history)}
    if mesa_cache is None:
        env["MESA_SHADER_CACHE_DISABLE"] = "true"
    else:
        env.update(MESA_SHADER_CACHE_DISABLE="false", MESA_SHADER_CACHE_DIR=str(mesa_cache))
    shot = history / "shot.png"
    cmd = [sys.executable, "-c", "from inshade.cli import entry; entry()", "-q", "render", str(asset),
           "--storage", storage, "--width", str(size), "--height", str(size), "-o", str(shot)]
    start = time.perf_counter()
    try:
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"stopped after {timeout} s"}
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        return {"error": (proc.stderr.strip().splitlines() or ["(no message)"])[-1][:300]}
    sidecar = json.loads((shot.parent / (shot.name + ".json")).read_text())
    try:
        draws = json.loads((history / "draws.json").read_text())
    except (OSError, ValueError):
        draws = {}
    first = [v["first_draw_s"] for v in draws.values() if isinstance(v, dict) and "first_draw_s" in v]
    plan = sidecar.get("plan") or {}
    return {"wall_s": wall, "first_draw_s": max(first) if first else None,
            "resolved": "+".join(sorted(plan.get("storage", {}))) or "-", "totals": plan.get("totals", {}),
            "renderer": sidecar["gl"]["renderer"]}


# The window, opened in a fresh process: seconds to its first drawn frame and to the program as set.
VIEW_CHILD = """
import json, sys, time
start = time.perf_counter()
from inshade.viewer.app import ViewerApp
app = ViewerApp(sys.argv[1], size=(640, 400), visible=False, vsync=False)
quick = app.warm_up is not None
first = full = None
while full is None and time.perf_counter() - start < float(sys.argv[2]):
    app.step(1)
    drawn = not app.compiling and not app.renderer.first_draw_pending
    if drawn and first is None:
        first = time.perf_counter() - start
    if drawn and app.warm_up is None and (not quick or app.renderer.values["storage"] != "texture"):
        full = time.perf_counter() - start
app.close()
print(json.dumps({"first_frame_s": first, "full_frame_s": full, "quick_first": quick}))
"""


def view_once(asset: Path, tmp: Path, timeout: int, display: str) -> dict:
    """``inshade view`` of ``asset`` in a fresh process with an empty Mesa shader cache (on) and draw history."""
    folder = Path(tempfile.mkdtemp(dir=tmp))
    env = {**os.environ, "DISPLAY": display, "INSHADE_CACHE_DIR": str(folder / "history"),
           "MESA_SHADER_CACHE_DISABLE": "false", "MESA_SHADER_CACHE_DIR": str(folder / "mesa")}
    try:
        proc = subprocess.run([sys.executable, "-c", VIEW_CHILD, str(asset), str(timeout)], env=env,
                              capture_output=True, text=True, timeout=timeout + 60)
    except subprocess.TimeoutExpired:
        return {"error": f"stopped after {timeout} s"}
    if proc.returncode != 0:
        return {"error": (proc.stderr.strip().splitlines() or ["(no message)"])[-1][:300]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def measure_asset(asset: Path, settings: Settings, tmp: Path, display: str | None = None) -> dict:
    row = {"asset": asset.name, "cold": {}, "warm": {}}
    for storage in settings.storages:
        row["cold"][storage] = render_once(asset, storage, settings.size, tmp, settings.timeout, None)
    for storage in settings.warm_storages:
        mesa = Path(tempfile.mkdtemp(dir=tmp))
        filled = render_once(asset, storage, settings.size, tmp, settings.timeout, mesa)
        row["warm"][storage] = filled if "error" in filled else \
            render_once(asset, storage, settings.size, tmp, settings.timeout, mesa)
    if display is not None:
        row["view"] = view_once(asset, tmp, settings.timeout, display)
    timed = {s: r["wall_s"] for s, r in row["cold"].items() if "wall_s" in r}
    row["quickest_cold"] = min(timed, key=timed.get) if timed else None
    return row


def run(settings: Settings) -> int:
    assets = asset_folders(settings.assets)
    report = {"benchmark": "startup", "machine": machine(), "size": settings.size,
              "storages": list(settings.storages), "warm_storages": list(settings.warm_storages), "assets": []}
    xvfb, display = (None, None) if settings.no_viewer else start_xvfb()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for asset in assets:
                row = measure_asset(asset, settings, Path(tmp), display)
                print(json.dumps({k: row.get(k) for k in ("asset", "quickest_cold", "view")}), file=sys.stderr,
                      flush=True)
                report["assets"].append(row)
    finally:
        if xvfb is not None:
            xvfb.terminate()
            xvfb.wait(timeout=10)
    renderers = {r["renderer"] for a in report["assets"] for runs in (a["cold"], a["warm"]) for r in runs.values()
                 if "renderer" in r}
    report["renderer"] = ", ".join(sorted(renderers))
    write_report(settings.out, "startup", report, markdown, plot)
    return 0


def _cell(r: dict | None) -> str:
    if not r:
        return "–"
    if "error" in r:
        return f"✗ {r['error'][:60]}"
    first = f" ({r['first_draw_s']:.1f})" if r.get("first_draw_s") is not None else ""
    return f"{r['wall_s']:.1f}{first} {r['resolved']}"


def markdown(r: dict) -> str:
    cold, warm = r["storages"], r["warm_storages"]
    viewed = any("view" in a for a in r["assets"])
    head = ["asset", *(f"cold {s}" for s in cold), *(f"warm {s}" for s in warm), "quickest cold",
            *(["view: first frame, program as set (s)"] if viewed else [])]
    lines = [f"# Startup: `inshade render` at {r['size']}² in a fresh process", "", machine_markdown(r["machine"]), "",
             f"Renderer: `{r['renderer']}`. Each cell: seconds from process start to the image written (the "
             "first draw's own seconds in brackets: the JIT on a software driver, plus the frame), then the "
             f"storage the plan used. Cold: Mesa's shader cache off; warm: a second run with it filled. View: "
             "`inshade view` in a 640 x 400 window, an empty shader cache (on), seconds from process start to "
             "the first drawn frame and to the program as set (later where the window draws a quick program "
             f"first, marked *). Goal: a cold first picture within {FIRST_FRAME_S:.0f} s.", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for a in r["assets"]:
        best = a["cold"].get(a["quickest_cold"] or "", {})
        verdict = f"{a['quickest_cold']} {best['wall_s']:.1f} s" if best else "–"
        lines.append("| " + " | ".join([a["asset"], *(_cell(a["cold"].get(s)) for s in cold),
                                        *(_cell(a["warm"].get(s)) for s in warm), verdict,
                                        *([_view_cell(a.get("view"))] if viewed else [])]) + " |")
    within = [a for a in r["assets"] if "wall_s" in a["cold"].get("auto", {})]
    if within:
        ok = sum(a["cold"]["auto"]["wall_s"] <= FIRST_FRAME_S for a in within)
        quick = sum(a["cold"][a["quickest_cold"]]["wall_s"] <= FIRST_FRAME_S for a in within)
        lines += ["", f"Cold first picture within {FIRST_FRAME_S:.0f} s: {ok} of {len(within)} assets with the "
                      f"auto plan; {quick} of {len(within)} with each asset's quickest storage."]
    views = [a["view"] for a in r["assets"] if a.get("view", {}).get("first_frame_s") is not None]
    if views:
        lines.append(f"`inshade view`'s first frame within {FIRST_FRAME_S:.0f} s: "
                     f"{sum(v['first_frame_s'] <= FIRST_FRAME_S for v in views)} of {len(views)} assets.")
    return "\n".join(lines) + "\n"


def _view_cell(v: dict | None) -> str:
    if not v:
        return "–"
    if "error" in v or v.get("first_frame_s") is None:
        return f"✗ {v.get('error', 'no frame')[:60]}"
    full = "–" if v.get("full_frame_s") is None else f"{v['full_frame_s']:.1f}"
    return f"{v['first_frame_s']:.1f}{'*' if v.get('quick_first') else ''}, {full}"


def plot(r: dict, path: Path) -> None:
    plt = matplotlib_pyplot()
    names = [a["asset"] for a in r["assets"]]
    fig, ax = plt.subplots(figsize=(10, 0.28 * len(names) + 1.5))
    series = [(f"cold {s}", [a["cold"].get(s, {}).get("wall_s", 0) for a in r["assets"]]) for s in r["storages"]]
    series += [(f"warm {s}", [a["warm"].get(s, {}).get("wall_s", 0) for a in r["assets"]]) for s in r["warm_storages"]]
    if any("view" in a for a in r["assets"]):
        series.append(("view: first frame", [(a.get("view") or {}).get("first_frame_s") or 0 for a in r["assets"]]))
    height = 0.8 / len(series)
    for k, (label, values) in enumerate(series):
        ax.barh([i + k * height for i in range(len(names))], values, height=height, label=label)
    ax.axvline(FIRST_FRAME_S, color="k", linestyle="--", linewidth=1)
    ax.set_yticks([i + 0.4 - height / 2 for i in range(len(names))], names, fontsize=7)
    ax.set_xscale("log")
    ax.set_xlabel("seconds to the first picture (log)")
    ax.invert_yaxis()
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows

CLAIMS = {"first_picture": Claim("none (inshade's own bar)", "cold first picture of a shipped asset, fresh process",
                                 f"within {FIRST_FRAME_S:.0f} s", FIRST_FRAME_S, higher_better=False)}


def headlines(r: dict) -> list[dict]:
    rows = [a for a in r["assets"] if "wall_s" in a["cold"].get("auto", {})]
    if not rows:
        return []
    worst = max(rows, key=lambda a: a["cold"]["auto"]["wall_s"])
    s = worst["cold"]["auto"]["wall_s"]
    return [claim_row(CLAIMS, "startup", "first_picture", f"slowest {s:.1f} s ({worst['asset']}, auto) over "
                      f"{len(rows)} assets", s)]


BENCH = Bench("startup", __doc__, Settings, run, claims=CLAIMS, headlines=headlines,
              quick={"assets": ["trained/neural_image"], "storages": ["auto", "texture"], "size": 64},
              formatter=argparse.ArgumentDefaultsHelpFormatter, sizes={
    "cpu": sized(600, assets=("trained/neural_image", "trained/sdf_creature", "trained/prt_mechanical"),
                 size=256),
    # two programs whose literals take seconds to JIT on llvmpipe, cold and warm: what a GPU driver's compile
    # costs them (the window needs a display, which the device machine has not)
    "device": sized(10, assets=("trained/prt_mechanical", "trained/uvfree_material_fruit_balanced"),
                    storages=("auto", "texture"), no_viewer=True, size=512),
})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite


if __name__ == "__main__":
    sys.exit(main())
