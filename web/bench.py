"""``inshade bench web``: every shipped asset as a page in headless Chromium.

Per asset: the page's bytes (native size), load time to the first frame, the frame time of the
full redraw (median of 5, network pass forced) under the browser's WebGL2 (SwiftShader without a
GPU), and the PSNR of the first frame against ``inshade render`` at a quarter of the scene's size
(8-bit sRGB), plus the evaluation page's max error against torch under the parity rule's scale.
Writes docs/bench/web.json, .md and .png (frame time per asset).
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

from inshade.files import atomic_write

ROOT = Path(__file__).resolve().parents[1]


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
             f"Exported on `{report['gl_renderer']}`; `inshade render` is the reference. Page bytes and timings "
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
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in report["assets"] if "frame_ms" in r]
    fig, ax = plt.subplots(figsize=(8, 0.28 * len(rows) + 1.2))
    ax.barh([r["asset"] for r in rows], [r["frame_ms"] for r in rows])
    ax.set_xscale("log")
    ax.set_xlabel(f"frame time (ms), {report['browser_renderer'][:60]}")
    ax.invert_yaxis()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="inshade bench web", description=__doc__.split("\n\n")[0])
    ap.add_argument("assets", nargs="*", help="asset folders (default: every shipped asset)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "bench" / "web"), help="output path stem")
    args = ap.parse_args(argv)
    from inshade.runtime.context import shared_context

    from .browser import Browser

    assets = [Path(a) for a in args.assets] or sorted(p for p in (ROOT / "trained").iterdir() if p.is_dir())
    report = {"gl_renderer": shared_context().info["GL_RENDERER"], "assets": []}
    with Browser() as browser, tempfile.TemporaryDirectory() as tmp:
        report["browser_renderer"] = browser.renderer()
        for asset in assets:
            row = measure(asset, browser, Path(tmp))
            print(json.dumps(row), file=sys.stderr, flush=True)
            report["assets"].append(row)
    out = Path(args.out)
    atomic_write(out.with_suffix(".json"), json.dumps(report, indent=1) + "\n")
    atomic_write(out.with_suffix(".md"), markdown(report))
    plot(report, out.with_suffix(".png"))
    print(markdown(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
