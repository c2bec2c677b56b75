"""``inshade bench web``: every shipped asset as a page in headless Chromium.

Per asset: the page's bytes (native size, both APIs' programs), then on each API the page has (WebGL2
and WebGPU, SwiftShader without a GPU): load time to the first frame (drawn at a quarter of the size)
and to the full one, the frame time of the full redraw (median of 5, network pass forced), and the
PSNR of the page against ``inshade render`` at a quarter of the scene's size (8-bit sRGB); plus the
evaluation page's max error against torch under the parity rule's scale.
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
from inshade.bench.mlp import int_list

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = "bench-out/web"


def _quarter(size) -> tuple[int, int]:
    return max(16, size[0] // 4), max(16, size[1] // 4)


APIS = ("webgl2", "webgpu")


def measure(asset: Path, browser, tmp: Path) -> dict:
    """The asset's row: the WebGL2 page's numbers at its top level (as before WebGPU), WebGPU's under "webgpu"."""
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene

    from .browser import page_bytes
    from .export import export_web

    scene = load_scene(asset)
    row = {"asset": asset.name, "program": scene.program, "size": list(scene.size)}
    native, small = tmp / f"{asset.name}_native", tmp / f"{asset.name}_small"
    row["requires"] = export_web(asset, native, api="auto").manifest["requires"]
    row["page_bytes"] = page_bytes(native)
    row["wgsl_bytes"] = sum(f.stat().st_size for f in (native / "programs").glob("*.wgsl"))
    w, h = _quarter(scene.size)
    export_web(asset, small, width=w, height=h, api="auto")
    image, _ = render_scene(scene, width=w, height=h, settings={"labels": False})
    for api in APIS:
        numbers = _page(browser, native, small, api, image, scene)
        if api == "webgl2":
            row.update(numbers)
        else:
            row[api] = numbers
    row["psnr_size"] = [w, h]
    return row


def _page(browser, native: Path, small: Path, api: str, render, scene) -> dict:
    from .browser import psnr8, serve, srgb8

    out = {}
    with serve(native) as url:
        state = browser.open(url + f"index.html?api={api}")
        if state["error"]:
            return {"error": state["error"]}
        out["load_to_first_frame_ms"] = round(float(state["first_frame_ms"]), 1)   # at a quarter of the size
        out["load_to_full_frame_ms"] = round(float(state["full_frame_ms"]), 1)
        out["frame_ms"] = round(statistics.median(browser.frame_ms(5)), 2)
        if api == "webgpu":
            out["adapter"] = browser.driver.execute_script("return window.inshade.viewer.gpu.adapter;")
    with serve(small) as url:
        browser.open(url + f"index.html?api={api}")
        out["psnr_db_vs_render"] = round(psnr8(browser.canvas(), srgb8(render)), 2)
        page = "evaluate.html" if api == "webgl2" else "evaluate_webgpu.html"
        state = browser.open(url + page)
        if state["ready"]:
            key = "evaluate" if api == "webgl2" else "evaluate_webgpu"
            out["evaluate_max_scaled_error"] = _evaluation_error(small, scene, browser.evaluation(), key)
    return out


def _evaluation_error(folder: Path, scene, out: np.ndarray, key: str = "evaluate") -> float | None:
    """max |browser - torch| / max(1, |torch|) over the evaluation batch (None without torch)."""
    try:
        import torch

        from inshade.bundle import load
        from inshade.models import GraphModule
        from inshade.scene.description import NetworkSdfRef
    except ImportError:
        return None
    e = json.loads((folder / "manifest.json").read_text())[key]
    refs = [load(n.bundle) for n in scene.networks]
    if isinstance(scene.sdf, NetworkSdfRef):
        refs.append(load(scene.sdf.bundle))
    bundle = next(b for b in refs if b.name == e["bundle"])
    x = np.fromfile(folder / "data.bin", np.float32, e["count"] * e["in_dim"], offset=e["inputs"][0])
    with torch.no_grad():
        ref = GraphModule.from_bundle(bundle)(torch.from_numpy(x.reshape(e["count"], e["in_dim"]))).numpy()
    return float((np.abs(out.astype(np.float64) - ref) / np.maximum(1.0, np.abs(ref))).max())


def _peer_network(width: int, depth: int, encoding: str):
    """The MLP bench's network of that size and encoding (its seed; 4 octaves)."""
    from inshade.bench.mlp import mlp_network

    if encoding not in ("frequency", "raw"):
        raise BenchError(f"--peer-encodings: {encoding!r} is not frequency or raw")
    return mlp_network(width, depth, encoding, 4, 0)


def markdown(report: dict) -> str:
    lines = [f"# Exported pages in headless Chromium ({report['browser_renderer']})", "",
             machine_markdown(report["machine"])]
    adapters = sorted({r["webgpu"]["adapter"] for r in report["assets"] if "adapter" in r.get("webgpu", {})})
    if adapters:
        lines.append(f"- WebGPU adapter: `{', '.join(adapters)}`")
    if report["assets"]:
        lines += _asset_rows(report)
    if report.get("peers"):
        from .bench_peers import markdown as peers_markdown

        lines += peers_markdown(report["peers"], report["peers_count"])
    return "\n".join(lines) + "\n"


def _asset_rows(report: dict) -> list[str]:
    lines = ["", "Exported on this renderer; `inshade render` on it is the reference. Page bytes (both APIs' "
             "programs; the WGSL's share in brackets) and timings at the scene's own size; PSNR (8-bit sRGB) at a "
             "quarter of it; the evaluation error is max |browser - torch| / max(1, |torch|) on the exported batch "
             "(the parity rule is 1e-5). Each cell: WebGL2 / WebGPU.", "",
             "| asset | page bytes | load → first frame, 1/4 size (ms) | load → full frame (ms) | frame (ms) | "
             "PSNR vs render (dB) | eval error |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for r in report["assets"]:
        apis = [r, r.get("webgpu", {})]
        if "error" in r and "webgpu" not in r:
            lines.append(f"| {r['asset']} | {r.get('page_bytes', '-')} | error: {r['error']} | | | | |")
            continue
        wgsl = f" ({r['wgsl_bytes']:,})" if "wgsl_bytes" in r else ""
        cells = [" / ".join(_cell(a, key, fmt) for a in apis if a)
                 for key, fmt in (("load_to_first_frame_ms", ".0f"), ("load_to_full_frame_ms", ".0f"),
                                  ("frame_ms", ".1f"), ("psnr_db_vs_render", ".2f"), ("evaluate_max_scaled_error", ".2g"))]
        lines.append(f"| {r['asset']} | {r.get('page_bytes', 0):,}{wgsl} | " + " | ".join(cells) + " |")
    return lines


def _cell(numbers: dict, key: str, fmt: str) -> str:
    if "error" in numbers:
        return "error: " + numbers["error"][:80]
    value = numbers.get(key)   # reports before the quarter-size first frame have no full-frame time
    return "-" if value is None else format(value, fmt)


def plot(report: dict, path: Path) -> None:
    plt = matplotlib_pyplot()
    rows = [r for r in report["assets"] if "frame_ms" in r]
    peers = {n: rs for n, rs in (report.get("peers") or {}).items() if "error" not in rs}
    panels = [p for p in ("assets", "peers") if (rows if p == "assets" else peers)] or ["assets"]
    fig, axes = plt.subplots(len(panels), 1, figsize=(8, 0.28 * max(len(rows), 8) * len(panels) + 1.2), squeeze=False)
    for ax, panel in zip(axes[:, 0], panels):
        if panel == "assets":
            ax.barh([r["asset"] for r in rows], [r["frame_ms"] for r in rows])
            ax.set_xlabel(f"frame time (ms), {report['browser_renderer'][:60]}")
        else:
            runtimes = list(dict.fromkeys(k for rs in peers.values() for k in rs))
            height = 0.8 / max(1, len(peers))
            for i, (name, rs) in enumerate(peers.items()):
                ax.barh([k + height * i for k in range(len(runtimes))],
                        [rs.get(k, {}).get("ms", 0) for k in runtimes], height, label=name)
            ax.set_yticks(range(len(runtimes)), runtimes)
            ax.set_xlabel(f"ms per batch of {report['peers_count']} samples, headless Chromium")
            ax.legend(fontsize=7)
        ax.set_xscale("log")
        ax.invert_yaxis()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


@dataclass
class Settings:
    assets: list[str] = option((), "asset folders (default: every shipped asset)", positional="assets", nargs="*")
    out: str = option(DEFAULT_OUT, "output folder")
    no_assets: bool = option(False, "skip the shipped assets' pages (the peers only)")
    peer_widths: list[int] = option((16, 64), "hidden widths of the networks the browser runtimes run side by "
                                    "side ('' for none)", parse=int_list)
    peer_depths: list[int] = option((4,), "their hidden layer counts", parse=int_list)
    peer_encodings: list[str] = option(("frequency", "raw"), "their uv encodings: frequency (4 octaves, as the MLP "
                                       "bench), raw", parse=lambda t: [v for v in t.split(",") if v])
    peer_size: int = option(256, "their batch is size x size samples", parse=int)
    repeats: int = option(5, "timed repeats per runtime (median, after a warm-up)", parse=int)


def run(settings: Settings) -> int:
    from .browser import Browser, BrowserError

    from .bench_peers import PeersMissing
    from .bench_peers import measure as measure_peers

    assets = [] if settings.no_assets else (
        [Path(a) for a in settings.assets] or sorted(p for p in (ROOT / "trained").iterdir() if p.is_dir()))
    report = {"benchmark": "web", "machine": machine(), "assets": []}
    try:
        with Browser() as browser, tempfile.TemporaryDirectory() as tmp:
            report["browser_renderer"] = browser.renderer()
            for asset in assets:
                row = measure(asset, browser, Path(tmp))
                print(json.dumps(row), file=sys.stderr, flush=True)
                report["assets"].append(row)
            nets = {f"{w}x{d} {e}": _peer_network(w, d, e) for e in settings.peer_encodings
                    for w in settings.peer_widths for d in settings.peer_depths}
            if nets:
                report["peers"] = measure_peers(browser, nets, Path(tmp) / "peers", settings.peer_size ** 2,
                                                settings.repeats)
                report["peers_count"] = settings.peer_size ** 2
    except (BrowserError, PeersMissing) as exc:
        raise BenchError(str(exc)) from None
    write_report(settings.out, "web", report, markdown, plot)
    return 0


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows

CLAIMS = {"page_psnr": Claim("none (inshade's own bar)", "exported page's first frame vs inshade render, "
                             "8-bit sRGB", "at least 40 dB (different rasterisers)", 40.0)}


def headlines(r: dict) -> list[dict]:
    pages = [(a["asset"], api, n["psnr_db_vs_render"]) for a in r["assets"]
             for api, n in (("WebGL2", a), ("WebGPU", a.get("webgpu", {}))) if "psnr_db_vs_render" in n]
    if not pages:
        return []
    asset, api, worst = min(pages, key=lambda p: p[2])
    return [claim_row(CLAIMS, "web", "page_psnr", f"worst {worst:.1f} dB ({asset}, {api}) over {len(pages)} pages "
                      f"in {r['browser_renderer'][:40]}", worst)]


BENCH = Bench("web", __doc__, Settings, run, claims=CLAIMS, headlines=headlines,
              formatter=argparse.ArgumentDefaultsHelpFormatter, sizes={
    # the suite times the pages; the browser runtimes side by side run on their own (web/peers' npm packages)
    "cpu": sized(60, assets=("trained/neural_image", "trained/di_texture_astronaut", "trained/sdf_creature"),
                 peer_widths=()),
    # the GPU machine needs Debian's chromium + chromium-driver for this one
    "device": sized(10, assets=("trained/neural_image",), peer_widths=()),
})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite


if __name__ == "__main__":
    sys.exit(main())
