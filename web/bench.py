"""``inshade bench web``: every shipped asset as a page in headless Chromium.

Per asset: the page's bytes (native size), load time to the first frame, the frame time of the
full redraw (median of 5, network pass forced) under the browser's WebGL2 (SwiftShader without a
GPU), and the PSNR of the first frame against ``inshade render`` at a quarter of the scene's size
(8-bit sRGB), plus the evaluation page's max error against torch under the parity rule's scale.
Writes ``web.json``, ``web.md`` and ``web.png`` (frame time per asset) into ``--out``.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bench.contract import Bench, option, sized
from inshade.bench.entry import Claim, claim_row
from inshade.bench.harness import BenchError, machine, machine_markdown, matplotlib_pyplot, write_report

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = "bench-out/web"


def _quarter(size) -> tuple[int, int]:
    return max(16, size[0] // 4), max(16, size[1] // 4)


def measure(asset: Path, browser, tmp: Path) -> dict:
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene

    from .browser import page_bytes, psnr8, serve, srgb8
    from .export import export_web

    scene = load_scene(asset)
    row = {"asset": asset.name, "program": scene.program, "size": list(scene.size)}
    native = export_web(asset, tmp / f"{asset.name}_native")
    row["page_bytes"] = page_bytes(tmp / f"{asset.name}_native")
    row["requires"] = native.manifest["requires"]
    with serve(tmp / f"{asset.name}_native") as url:
        state = browser.open(url + "index.html")
        if state["error"]:
            return {**row, "error": state["error"]}
        row["load_to_first_frame_ms"] = round(float(state["first_frame_ms"]), 1)
        row["frame_ms"] = round(statistics.median(browser.frame_ms(5)), 2)
    w, h = _quarter(scene.size)
    export_web(asset, tmp / f"{asset.name}_small", width=w, height=h)
    with serve(tmp / f"{asset.name}_small") as url:
        browser.open(url + "index.html")
        page = browser.canvas()
        state = browser.open(url + "evaluate.html")
        evaluated = browser.evaluation() if state["ready"] else None
    image, _ = render_scene(scene, width=w, height=h, settings={"labels": False})
    row["psnr_db_vs_render"] = round(psnr8(page, srgb8(image)), 2)
    row["psnr_size"] = [w, h]
    if evaluated is not None:
        row["evaluate_max_scaled_error"] = _evaluation_error(tmp / f"{asset.name}_small", scene, evaluated)
    return row


def _evaluation_error(folder: Path, scene, out: np.ndarray) -> float | None:
    """max |browser - torch| / max(1, |torch|) over the evaluation batch (None without torch)."""
    try:
        import torch

        from inshade.bundle import load
        from inshade.models import GraphModule
        from inshade.scene.description import NetworkSdfRef
    except ImportError:
        return None
    e = json.loads((folder / "manifest.json").read_text())["evaluate"]
    refs = [load(n.bundle) for n in scene.networks]
    if isinstance(scene.sdf, NetworkSdfRef):
        refs.append(load(scene.sdf.bundle))
    bundle = next(b for b in refs if b.name == e["bundle"])
    x = np.fromfile(folder / "data.bin", np.float32, e["count"] * e["in_dim"], offset=e["inputs"][0])
    with torch.no_grad():
        ref = GraphModule.from_bundle(bundle)(torch.from_numpy(x.reshape(e["count"], e["in_dim"]))).numpy()
    return float((np.abs(out.astype(np.float64) - ref) / np.maximum(1.0, np.abs(ref))).max())


def markdown(report: dict) -> str:
    lines = [f"# Exported pages in headless Chromium ({report['browser_renderer']})", "",
             machine_markdown(report["machine"]), "",
             "Exported on this renderer; `inshade render` on it is the reference. Page bytes and timings "
             "at the scene's own size; PSNR (8-bit sRGB) at a quarter of it; the evaluation error is "
             "max |browser - torch| / max(1, |torch|) on the exported batch (the parity rule is 1e-5).", "",
             "| asset | page bytes | load → first frame (ms) | frame (ms) | PSNR vs render (dB) | eval error |",
             "|---|---:|---:|---:|---:|---:|"]
    for r in report["assets"]:
        if "error" in r:
            lines.append(f"| {r['asset']} | {r.get('page_bytes', '-')} | error: {r['error']} | | | |")
            continue
        err = r.get("evaluate_max_scaled_error")
        lines.append(f"| {r['asset']} | {r['page_bytes']:,} | {r['load_to_first_frame_ms']:.0f} | {r['frame_ms']:.1f} | "
                     f"{r['psnr_db_vs_render']:.2f} | {'-' if err is None else f'{err:.2g}'} |")
    return "\n".join(lines) + "\n"


def plot(report: dict, path: Path) -> None:
    plt = matplotlib_pyplot()
    rows = [r for r in report["assets"] if "frame_ms" in r]
    fig, ax = plt.subplots(figsize=(8, 0.28 * len(rows) + 1.2))
    ax.barh([r["asset"] for r in rows], [r["frame_ms"] for r in rows])
    ax.set_xscale("log")
    ax.set_xlabel(f"frame time (ms), {report['browser_renderer'][:60]}")
    ax.invert_yaxis()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


@dataclass
class Settings:
    assets: list[str] = option((), "asset folders (default: every shipped asset)", positional="assets", nargs="*")
    out: str = option(DEFAULT_OUT, "output folder")


def run(settings: Settings) -> int:
    from .browser import Browser, BrowserError

    assets = [Path(a) for a in settings.assets] or sorted(p for p in (ROOT / "trained").iterdir() if p.is_dir())
    report = {"benchmark": "web", "machine": machine(), "assets": []}
    try:
        with Browser() as browser, tempfile.TemporaryDirectory() as tmp:
            report["browser_renderer"] = browser.renderer()
            for asset in assets:
                row = measure(asset, browser, Path(tmp))
                print(json.dumps(row), file=sys.stderr, flush=True)
                report["assets"].append(row)
    except BrowserError as exc:
        raise BenchError(str(exc)) from None
    write_report(settings.out, "web", report, markdown, plot)
    return 0


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows

CLAIMS = {"page_psnr": Claim("none (inshade's own bar)", "exported page's first frame vs inshade render, "
                             "8-bit sRGB", "at least 40 dB (different rasterisers)", 40.0)}


def headlines(r: dict) -> list[dict]:
    rows = [a for a in r["assets"] if "psnr_db_vs_render" in a]
    if not rows:
        return []
    worst = min(rows, key=lambda a: a["psnr_db_vs_render"])
    return [claim_row(CLAIMS, "web", "page_psnr", f"worst {worst['psnr_db_vs_render']:.1f} dB ({worst['asset']}) "
                      f"over {len(rows)} pages in {r['browser_renderer'][:40]}", worst["psnr_db_vs_render"])]


BENCH = Bench("web", __doc__, Settings, run, claims=CLAIMS, headlines=headlines,
              formatter=argparse.ArgumentDefaultsHelpFormatter, sizes={
    "cpu": sized(60, assets=("trained/neural_image", "trained/di_texture_astronaut", "trained/sdf_creature")),
    # the GPU machine needs Debian's chromium + chromium-driver for this one
    "device": sized(10, assets=("trained/neural_image",)),
})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite


if __name__ == "__main__":
    sys.exit(main())
