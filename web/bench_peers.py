"""The browser runtimes side by side, for ``inshade bench web``: the MLP bench's networks (uv, raw or
through a NeRF frequency encoding, ReLU layers, rgb) evaluated on the same batch in the same headless Chromium
by inshade's two evaluation pages (the network's GLSL ES as a WebGL2 fragment pass, its WGSL as a
WebGPU compute pass), ONNX Runtime Web (wasm and WebGPU execution providers, on the torch network
exported to ONNX) and TensorFlow.js (WebGL, wasm and WebGPU backends, the same layers built from the
bundle's weights). Each is timed over the batch (median of ``repeats`` after a warm-up, the output
read back to the page included) and compared with torch.

The peers are npm packages pinned in web/peers/package.json; ``npm ci --prefix web/peers`` installs
them (they are read from there, never fetched by the page).
"""
from __future__ import annotations

import base64
import json
import os
import statistics
from pathlib import Path

import numpy as np

PEERS = Path(__file__).resolve().parent / "peers"
# runtime -> (family, how it runs): the rows of the table, in order
RUNTIMES = {
    "inshade WebGL2": ("inshade", "GLSL ES fragment pass (evaluate.html)"),
    "inshade WebGPU": ("inshade", "WGSL compute pass (evaluate_webgpu.html)"),
    "onnxruntime-web wasm": ("onnxruntime-web", "wasm execution provider"),
    "onnxruntime-web webgpu": ("onnxruntime-web", "WebGPU execution provider"),
    "tfjs webgl": ("tfjs", "WebGL backend"),
    "tfjs wasm": ("tfjs", "wasm backend"),
    "tfjs webgpu": ("tfjs", "WebGPU backend"),
}
RULE = 1e-5
GOAL = 5.0   # inshade's fastest page against the fastest peer: one fused shader function per sample


class PeersMissing(RuntimeError):
    """The npm packages of the peers are not installed."""


def _installed() -> None:
    if not (PEERS / "node_modules" / "onnxruntime-web").is_dir():
        raise PeersMissing(f"the browser runtimes are not installed: npm ci --prefix {PEERS}")


def _tfjs_layers(bundle) -> dict:
    """The bundle's layers as TF.js builds them: the encoding's octaves, then each dense layer's
    weight [out, in] and bias (float32, base64) and the activation after it."""
    enc = next((n for n in bundle.nodes if n.type == "frequency"), None)
    layers = []
    for n in bundle.nodes:
        if n.type == "dense":
            layers.append({"out": n.out_dim, "in": n.in_dim,
                           "w": base64.b64encode(bundle.tensor(n, "weight").astype(np.float32).tobytes()).decode(),
                           "b": base64.b64encode(bundle.tensor(n, "bias").astype(np.float32).tobytes()).decode(),
                           "act": None})
        elif n.type == "relu":
            layers[-1]["act"] = "relu"
        elif n.type != "frequency":
            raise ValueError(f"the TF.js peer builds frequency, dense and relu only, not {n.type}")
    return {"n_freqs": enc.params["n_freqs"] if enc else 0,
            "include_input": enc.params.get("include_input", True) if enc else True, "layers": layers}


def page(net, name: str, folder: Path, count: int) -> tuple[Path, np.ndarray]:
    """The page folder of one network (inshade's export, its ONNX model, its TF.js layers, the peers
    page) and the batch it evaluates [count, 2]."""
    from inshade.bench.mlp_targets import onnx_model
    from inshade.convert.shown_as import apply_shown_as

    from .export import export_web

    bundle, _ = apply_shown_as(net.export("mlp", name), "image", np.zeros((1, 2), np.float32), "linear")
    bundle.save(folder / "bundle")
    export_web(folder / "bundle", folder / "page", width=16, height=16, eval_count=count)
    out = folder / "page"
    manifest = json.loads((out / "manifest.json").read_text())
    e = manifest["evaluate"]
    x = np.fromfile(out / "data.bin", np.float32, e["count"] * e["in_dim"], offset=e["inputs"][0]).reshape(-1, 2)
    (out / "model.onnx").write_bytes(onnx_model(net, x))
    (out / "tfjs.json").write_text(json.dumps(_tfjs_layers(bundle)))
    for f in ("peers.html", "peers.js"):
        (out / f).write_bytes((PEERS / f).read_bytes())
    os.symlink(PEERS / "node_modules", out / "node_modules")
    return out, x


def measure(browser, nets: dict, folder: Path, count: int, repeats: int) -> dict:
    """{network: {runtime: row}} with each runtime's median ms, its times and max scaled error."""
    import torch

    from .browser import serve

    _installed()
    report = {}
    for name, net in nets.items():
        out, x = page(net, name, folder / name, count)
        with torch.no_grad():
            ref = net(torch.from_numpy(x)).numpy().astype(np.float64)
        with serve(out) as url:
            state = browser.open(url + f"peers.html?repeats={repeats}")
            if state.get("error"):
                report[name] = {"error": state["error"]}
                continue
            results = browser.driver.execute_script("return window.inshade.results;")
        rows = {}
        for runtime in sorted(results, key=lambda k: list(RUNTIMES).index(k) if k in RUNTIMES else len(RUNTIMES)):
            r = results[runtime]
            if "error" in r:
                rows[runtime] = {"error": r["error"]}
                continue
            y = np.frombuffer(base64.b64decode(r["base64"]), np.float32).reshape(len(x), -1).astype(np.float64)
            err = float(np.max(np.abs(y - ref) / np.maximum(1.0, np.abs(ref))))
            rows[runtime] = {"ms": statistics.median(r["times"]), "times": r["times"], "max_scaled_error": err,
                             "within_rule": err <= RULE, "device": r.get("device", "")}
        report[name] = rows
    return report


def markdown(peers: dict, count: int) -> list[str]:
    lines = ["", f"## The browser runtimes side by side ({count} samples per batch)", "",
             "Median ms per batch (the output read back included; inshade's and TF.js's inputs stay on the device "
             "between repeats, onnxruntime-web uploads them each run), the ratio to inshade's fastest page, and "
             f"max |runtime - torch| / max(1, |torch|) (the parity rule is {RULE:g}).", "",
             "| network | runtime | device | ms | vs inshade's fastest | max err |", "|---|---|---|---:|---:|---:|"]
    goals = []
    for name, rows in peers.items():
        if "error" in rows:
            lines.append(f"| {name} | error: {rows['error']} | | | | |")
            continue
        ok = {k: r for k, r in rows.items() if "ms" in r}
        ours = min((r["ms"], k) for k, r in ok.items() if RUNTIMES.get(k, ("",))[0] == "inshade")
        theirs = min((r["ms"], k) for k, r in ok.items() if RUNTIMES.get(k, ("",))[0] != "inshade")
        goals.append(f"- {name}: inshade's fastest ({ours[1]}, {ours[0]:.1f} ms) is {theirs[0] / ours[0]:.2f}x "
                     f"the fastest peer ({theirs[1]}, {theirs[0]:.1f} ms): the 5x goal is "
                     f"{'met' if theirs[0] >= GOAL * ours[0] else 'not met'}")
        ours = [r["ms"] for k, r in rows.items() if RUNTIMES.get(k, ("",))[0] == "inshade" and "ms" in r]
        best = min(ours) if ours else None
        for runtime, r in rows.items():
            if "error" in r:
                lines.append(f"| {name} | {runtime} | – | – | – | error: {r['error'][:120]} |")
                continue
            ratio = f"{r['ms'] / best:.2f}x" if best else "–"
            lines.append(f"| {name} | {runtime} | {r['device']} | {r['ms']:.1f} | {ratio} | {r['max_scaled_error']:.2g} |")
    return lines + ["", f"Goal: at least {GOAL:g}x faster than the fastest peer, per network.", "", *goals]
