"""`inshade bench mlp` beyond OpenGL: the same networks on the same batch as WGSL, Vulkan GLSL, HLSL and
Slang (wgpu on this machine's Vulkan device), and onnxruntime on the CPU beside torch
(the stronger CPU peer). Every result is checked against torch like the GLSL ones."""
from __future__ import annotations

import argparse
import io
import time
import warnings

import numpy as np

from inshade.bench.harness import measure

# the targets a run times unless told otherwise (inshade.runtime.compute.TARGETS)
DEFAULT_TARGETS = ("wgsl", "vulkan", "hlsl", "slang")


def target_list(text: str) -> list[str]:
    from inshade.codegen.targets import TARGETS

    names = [v.strip() for v in text.split(",") if v.strip()]
    bad = [n for n in names if n not in TARGETS or TARGETS[n].opengl]
    if bad:
        beyond = ", ".join(n for n, t in TARGETS.items() if not t.opengl)
        raise argparse.ArgumentTypeError(f"unknown target {', '.join(bad)} (choose from {beyond})")
    return names


def _max_error(y: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.abs(y.astype(np.float64) - ref))) if y.size else 0.0


def bench_target(bundle, target: str, storage: str, x: np.ndarray, ref: np.ndarray, repeats: int) -> dict:
    """One network in one storage for one target: compile, first dispatch, median dispatch (computing and
    waiting for the batch; read-back apart), its error against torch."""
    from inshade.codegen import generate
    from inshade.runtime.compute import compute_device, device_name, prepare

    limits = compute_device().planning_limits()
    try:
        gen = generate(bundle, target=target, storage=storage, limits=limits)
        run = prepare(gen, x, target)
    except ValueError as exc:   # a storage past the limits, or a driver that cannot bind it here, says why
        return {"target": target, "storage": storage, "skipped": str(exc)}
    start = time.perf_counter()
    run.run()
    first = time.perf_counter() - start
    timing = measure(run.run, repeats=repeats, warmup=0)
    y = run.read()
    return {"target": target, "storage": storage, "device": device_name(target),
            "resolved": "+".join(sorted({r.storage for r in gen.plan.rows if r.type == "dense"})),
            "seconds": timing.median, "compile_s": run.compile_s, "first_s": first,
            "max_error": _max_error(y, ref), "finite": bool(np.all(np.isfinite(y))), "timing": timing.to_dict()}


def onnx_model(net, x: np.ndarray) -> bytes:
    """The torch network as an ONNX model of input ``x`` and output ``y``, any batch size."""
    import torch

    buffer = io.BytesIO()
    with warnings.catch_warnings():   # torch's own notice that its TorchScript exporter is legacy
        warnings.simplefilter("ignore")
        torch.onnx.export(net, (torch.from_numpy(x[:2]),), buffer, dynamo=False, input_names=["x"],
                          output_names=["y"], dynamic_axes={"x": {0: "n"}, "y": {0: "n"}})
    return buffer.getvalue()


def bench_onnxruntime(net, x: np.ndarray, ref: np.ndarray, repeats: int) -> dict:
    """The torch network exported to ONNX and run by onnxruntime's CPU provider on the same batch."""
    try:
        import onnxruntime as ort
    except ImportError:
        return {"skipped": "onnxruntime is not installed (pip install 'inshade[onnx]')"}
    session = ort.InferenceSession(onnx_model(net, x), providers=["CPUExecutionProvider"])

    def infer():
        return session.run(None, {"x": x})[0]
    y = infer()   # warm-up
    timing = measure(infer, repeats=repeats, warmup=0)
    return {"version": ort.__version__, "seconds": timing.median, "max_error": _max_error(y, ref),
            "finite": bool(np.all(np.isfinite(y))), "timing": timing.to_dict()}


def markdown_rows(result: dict) -> list[str]:
    """The report's section beyond OpenGL: each target's time beside torch's and onnxruntime's."""
    lines = ["", "## Beyond OpenGL, and onnxruntime", "",
             "| network | code | storage | device | ms | vs torch | vs onnxruntime | compile s | max err |",
             "|---|---|---|---|---:|---:|---:|---:|---:|"]
    for n in result["networks"]:
        ort = n.get("onnxruntime", {})
        ort_s = ort.get("seconds")
        if ort_s:
            lines.append(f"| {n['name']} | onnxruntime {ort['version']} CPU | – | CPU | {ort_s * 1e3:.1f} "
                         f"| {n['torch_s'] / ort_s:.2f}x | 1.00x | – | {ort['max_error']:.1e} |")
        elif ort:
            lines.append(f"| {n['name']} | onnxruntime | – | – | – | – | – | – | {ort['skipped']} |")
        for r in n.get("targets", []):
            if "skipped" in r:
                lines.append(f"| {n['name']} | {r['target']} | {r['storage']} | – | – | – | – | – "
                             f"| {r['skipped']} |")
                continue
            vs_ort = f"{ort_s / r['seconds']:.2f}x" if ort_s else "–"
            lines.append(f"| {n['name']} | {r['target']} | {r['storage']} | {r['device']} | {r['seconds'] * 1e3:.1f} "
                         f"| {n['torch_s'] / r['seconds']:.2f}x | {vs_ort} | {r['compile_s']:.3f} "
                         f"| {r['max_error']:.1e}{'' if r['parity_ok'] else ' ❌'} |")
    return lines


def plot_series(networks: list[dict]) -> list[tuple[str, list[float]]]:
    """Throughput (Mpixel/s) of onnxruntime and of each target at its fastest storage, per network."""
    series = [("onnxruntime CPU", [n["pixels"] / n["onnxruntime"]["seconds"] / 1e6
                                   if n.get("onnxruntime", {}).get("seconds") else 0 for n in networks])]
    targets = list(dict.fromkeys(r["target"] for n in networks for r in n.get("targets", []) if "seconds" in r))
    for t in targets:
        series.append((f"{t} (fastest storage)", [max((n["pixels"] / r["seconds"] / 1e6 for r in n.get("targets", [])
                                if r["target"] == t and "seconds" in r), default=0) for n in networks]))
    return series
