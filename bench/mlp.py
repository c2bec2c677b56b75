"""`inshade bench mlp`: generated GLSL (and WGSL, Vulkan GLSL, HLSL, Slang) vs torch and onnxruntime on the CPU,
on the same MLPs and the same batch.

For each network (uv -> [frequency encoding] -> (dense -> relu) * depth -> dense -> rgb) and a
size x size batch of pixel-centre uvs, in one run:

- torch CPU time: median of ``with torch.inference_mode(): net(x)`` (torch's default threads);
- per storage mode: GL compile+link time, the first draw (llvmpipe JIT-compiles the fragment
  shader there), the median of ``draw(); ctx.finish()`` wall time after that warm-up (``--clock``;
  read-back excluded, timed separately), achieved GFLOP/s of the dense layers, and the max error against torch
  (a benchmark that measures wrong code is worthless: errors >= 1e-4 fail the run);
- the machine's numpy float32 sgemm GFLOP/s as the practical peak;
- onnxruntime's CPU time on the same batch, and the code of each ``--targets`` language through its
  compute driver (bench/mlp_targets.py), checked against torch the same way.

Writes ``mlp.json``, ``mlp.md`` and ``mlp.png`` into ``--out`` (``inshade.bench.harness``: every
timing keeps its min, max and quartiles and the clock it used). Timings are wall-clock on a
possibly shared machine: compare the ratios measured side by side, and read absolute numbers
with the GL_RENDERER string next to them.
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.provenance import utc_now
from inshade.bench.contract import Bench, clock_option, option, sized
from inshade.bench.entry import Claim, claim_row
from inshade.bench.harness import (BenchError, clock_for, clock_record, machine,
                                   machine_markdown, matplotlib_pyplot, measure, write_report)
from inshade.bench.mlp_targets import (DEFAULT_TARGETS, bench_onnxruntime, bench_target, markdown_rows, plot_series,
                                       target_list)

DEFAULT_OUT = "bench-out/mlp"
MODES = ("inline", "ubo", "texture")
PARITY_TOL = 1e-4
# Targets on the 2-core llvmpipe machine.
TARGET_SPEEDUP = 3.0          # GLSL throughput >= 3x torch CPU ...
TARGET_WIDTHS = (16, 64)      # ... for widths 16-64 ...
TARGET_DEPTHS = (3, 4)        # ... and depth 3-4
TARGET_PEAK_FRACTION = 0.20   # >= 20% of the measured sgemm GFLOP/s
TARGET_COMPILE_S = 0.5        # ubo and texture compile+link of a 64x4 network


def int_list(text: str) -> list[int]:
    try:
        return [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None


def _mode_list(text: str) -> list[str]:
    from inshade.codegen import STORAGE_MODES

    modes = [v.strip() for v in text.split(",") if v.strip()]
    bad = [m for m in modes if m not in STORAGE_MODES]
    if bad or not modes:
        raise argparse.ArgumentTypeError(f"unknown storage {', '.join(bad) or text!r} "
                                         f"(choose from {', '.join(STORAGE_MODES)})")
    return modes


def _opengl_modes(modes: list[str]) -> list[str]:
    """The storages OpenGL's GLSL has, of those asked for (the others are timed on the other targets only)."""
    from inshade.codegen import OPENGL_STORAGE_MODES

    return [m for m in modes if m in OPENGL_STORAGE_MODES]


@dataclass
class Settings:
    out: str = option(DEFAULT_OUT, "output folder")
    size: int = option(512, "batch is size x size pixels")
    repeats: int = option(5, "timed repeats per measurement (median)")
    widths: list[int] = option((16, 32, 64), "hidden widths, e.g. 16,32,64", parse=int_list)
    depths: list[int] = option((3, 4), "hidden layer counts, e.g. 3,4", parse=int_list)
    storage: list[str] = option(MODES, "weight storage modes to time (inline,ubo,texture,auto; ssbo: storage "
                                "buffers, on the targets beyond OpenGL only)", parse=_mode_list)
    targets: list[str] = option(DEFAULT_TARGETS, "shading languages beyond OpenGL to time through their compute "
                                "drivers, in every storage (wgsl,vulkan,hlsl,slang; '' for none)", parse=target_list)
    encoding: str = option("frequency", "uv input encoding (frequency: NeRF encoding with --freqs octaves)",
                           choices=("frequency", "raw"))
    freqs: int = option(4, "octaves of the frequency encoding")
    sgemm_size: int = option(2048, "n of the n x n numpy sgemm peak")
    seed: int = option(0)
    quick: bool = option(False, "tiny run for tests: 64x64 batch, one small network, 2 repeats")
    strict: bool = option(False, "exit 2 when a target is missed")
    # wall by default: the GLSL times are compared with torch's CPU wall time
    clock: str = clock_option("wall")


def build_parser() -> argparse.ArgumentParser:
    return add_arguments(argparse.ArgumentParser(
        prog="inshade bench mlp", description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter))


# ---------------------------------------------------------------------------------------------
def sgemm_gflops(n: int = 2048, repeats: int = 5) -> dict:
    """numpy float32 n x n matmul: the practical peak of this machine's CPU (BLAS, all cores)."""
    rng = np.random.default_rng(0)
    a = rng.standard_normal((n, n), dtype=np.float32)
    b = rng.standard_normal((n, n), dtype=np.float32)
    timing = measure(lambda: a @ b, repeats=repeats, warmup=1)  # warm-up: thread pool, page faults
    seconds = timing.median
    return {"n": n, "seconds": seconds, "gflops": 2.0 * n ** 3 / seconds / 1e9, "timing": timing.to_dict()}


def uv_grid(size: int) -> np.ndarray:
    """Pixel-centre uvs of a size x size image, [size*size, 2] float32, row-major."""
    c = (np.arange(size, dtype=np.float32) + 0.5) / size
    u, v = np.meshgrid(c, c)
    return np.stack([u.ravel(), v.ravel()], 1).astype(np.float32)


def mlp_network(width: int, depth: int, encoding: str, freqs: int, seed: int):
    import torch

    from inshade.components.encodings.torch_twin import Frequency
    from inshade.models.graph import mlp_graph

    torch.manual_seed(seed * 1000 + width * 10 + depth)
    enc = Frequency(freqs) if encoding == "frequency" else None
    return mlp_graph(2, [width] * depth, 3, "relu", enc).eval()


def _dense_flops(plan) -> int:
    return sum(r.flops for r in plan.rows if r.type == "dense")


def _bench_torch(net, x: np.ndarray, repeats: int):
    import torch

    xt = torch.from_numpy(x)
    with torch.inference_mode():
        y = net(xt)  # warm-up
        timing = measure(lambda: net(xt), repeats=repeats, warmup=0)
    return timing, y.numpy().astype(np.float32)


def _bench_glsl(ctx, bundle, mode: str, x: np.ndarray, ref: np.ndarray, size: int, repeats: int,
                limits: dict, clock) -> dict:
    from inshade.codegen import generate
    from inshade.runtime.network import NetworkEvaluator

    gen = generate(bundle, storage=mode, limits=limits)
    ev = NetworkEvaluator(ctx, gen, width=size)
    try:
        draw = ev.prepare(x)
        start = time.perf_counter()
        draw()
        ctx.finish()
        first_draw = time.perf_counter() - start
        timing = measure(draw, repeats=repeats, warmup=0, clock=clock)
        seconds = timing.median
        start = time.perf_counter()
        y = ev.read(draw.n)
        read_s = time.perf_counter() - start
        draw.release()
    finally:
        ev.release()
    err = float(np.max(np.abs(y.astype(np.float64) - ref))) if y.size else 0.0
    storages = sorted({r.storage for r in gen.plan.rows if r.type == "dense"})
    return {"storage": mode, "resolved": "+".join(storages), "seconds": seconds,
            "compile_link_s": float(ev.compile_seconds), "first_draw_s": first_draw,
            "read_s": read_s, "max_error": err, "finite": bool(np.all(np.isfinite(y))),
            "chunk_bytes": len(gen.chunk), "timing": timing.to_dict()}


def run(args) -> int:
    import torch
    from tqdm import tqdm

    from inshade.runtime.context import gl_info, shared_context

    if args.quick:
        args.sgemm_size = min(args.sgemm_size, 512)
    if args.size < 1 or args.repeats < 1 or not args.widths or not args.depths:
        raise BenchError("--size and --repeats must be >= 1, --widths and --depths not empty")
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    ctx = shared_context()
    info = gl_info(ctx)
    x = uv_grid(args.size)
    quiet = not sys.stderr.isatty()

    clock = clock_for(ctx, args.clock, software=info["software"])
    host = machine(info, torch=torch.__version__, torch_threads=torch.get_num_threads(), numpy=np.__version__)
    with tqdm(total=1, desc="sgemm peak", disable=quiet, leave=False) as bar:
        peak = sgemm_gflops(args.sgemm_size, max(3, args.repeats))
        bar.update()

    specs = [(w, d) for d in args.depths for w in args.widths]
    networks = []
    gl_modes = _opengl_modes(args.storage)
    with tqdm(total=len(specs) * (1 + len(gl_modes)), desc="bench mlp", disable=quiet) as bar:   # GL steps
        for width, depth in specs:
            name = f"{width}x{depth}"
            bar.set_postfix_str(f"{name} torch")
            net = mlp_network(width, depth, args.encoding, args.freqs, args.seed)
            torch_timing, ref = _bench_torch(net, x, args.repeats)
            torch_s = torch_timing.median
            bar.update()
            bundle = net.export("mlp", name=f"bench-mlp-{name}")
            from inshade.codegen import generate

            plan = generate(bundle, storage="inline").plan
            flops_px = _dense_flops(plan)
            entry = {"name": name, "width": width, "depth": depth, "encoding": args.encoding,
                     "in_dim": bundle.in_dim, "params": plan.totals()["params"],
                     "dense_flops_per_px": flops_px, "plan_flops_per_px": plan.totals()["flops"],
                     "pixels": int(x.shape[0]), "torch_s": torch_s,
                     "torch_gflops": flops_px * x.shape[0] / torch_s / 1e9, "torch_timing": torch_timing.to_dict(),
                     "modes": {}}
            for mode in gl_modes:
                bar.set_postfix_str(f"{name} {mode}")
                r = _bench_glsl(ctx, bundle, mode, x, ref, args.size, args.repeats, info, clock)
                r["gflops"] = flops_px * x.shape[0] / r["seconds"] / 1e9
                r["speedup_vs_torch"] = torch_s / r["seconds"]
                r["fraction_of_sgemm"] = r["gflops"] / peak["gflops"]
                r["parity_ok"] = r["finite"] and r["max_error"] < PARITY_TOL
                entry["modes"][mode] = r
                bar.update()
            bar.set_postfix_str(f"{name} onnxruntime")
            entry["onnxruntime"] = bench_onnxruntime(net, x, ref, args.repeats)
            entry["targets"] = []
            for target in args.targets:
                for mode in args.storage:
                    bar.set_postfix_str(f"{name} {target} {mode}")
                    r = bench_target(bundle, target, mode, x, ref, args.repeats)
                    if "seconds" in r:
                        r["parity_ok"] = r["finite"] and r["max_error"] < PARITY_TOL
                    entry["targets"].append(r)
            networks.append(entry)

    targets = evaluate_targets(networks, peak)
    result = {"benchmark": "mlp", "created": utc_now(),
              "batch": {"size": args.size, "pixels": int(x.shape[0])}, "repeats": args.repeats,
              "quick": bool(args.quick),
              "machine": host, **clock_record(clock), "sgemm": peak, "parity_tolerance": PARITY_TOL,
              "networks": networks, "targets": targets,
              "max_error": max((m["max_error"] for n in networks for m in n["modes"].values()), default=0.0)}
    write_report(out_dir, "mlp", result, markdown, plot)
    print(f"wrote {out_dir / 'mlp.json'}, {out_dir / 'mlp.md'}, {out_dir / 'mlp.png'}", file=sys.stderr)
    if not all(m["parity_ok"] for n in networks for m in [*n["modes"].values(), *n["targets"]] if "parity_ok" in m):
        print(f"error: some generated code differs from torch by >= {PARITY_TOL}", file=sys.stderr)
        return 1
    if args.strict and not all(t["met"] for t in targets if t["met"] is not None):
        return 2
    return 0


# ---------------------------------------------------------------------------------------------
def _best(entry: dict):
    modes = [(m["seconds"], k) for k, m in entry["modes"].items() if m["parity_ok"]]
    return min(modes)[1] if modes else None


def evaluate_targets(networks: list[dict], peak: dict) -> list[dict]:
    """The targets; `met` is None when this run did not measure what a target needs."""
    lo, hi = TARGET_WIDTHS
    scope = [n for n in networks if lo <= n["width"] <= hi and n["depth"] in TARGET_DEPTHS]
    out = []

    def best_detail(key, fmt):
        return ", ".join(f"{n['name']}: {fmt(n['modes'][_best(n)][key])} ({_best(n)})" for n in scope if _best(n))

    if scope:
        ok = all(_best(n) and n["modes"][_best(n)]["speedup_vs_torch"] >= TARGET_SPEEDUP for n in scope)
        out.append({"target": f"GLSL >= {TARGET_SPEEDUP:g}x torch CPU (widths {lo}-{hi}, depth "
                              f"{'-'.join(map(str, TARGET_DEPTHS))}, fastest mode)", "met": ok,
                    "detail": best_detail("speedup_vs_torch", lambda v: f"{v:.1f}x")})
        ok = all(_best(n) and n["modes"][_best(n)]["fraction_of_sgemm"] >= TARGET_PEAK_FRACTION for n in scope)
        out.append({"target": f"GLSL >= {TARGET_PEAK_FRACTION:.0%} of sgemm "
                              f"({peak['gflops']:.1f} GFLOP/s, fastest mode)", "met": ok,
                    "detail": best_detail("fraction_of_sgemm", lambda v: f"{v:.0%}")})
    else:
        out.append({"target": f"GLSL >= {TARGET_SPEEDUP:g}x torch CPU", "met": None,
                    "detail": "no network of width 16-64, depth 3-4 in this run"})
        out.append({"target": f"GLSL >= {TARGET_PEAK_FRACTION:.0%} of sgemm", "met": None,
                    "detail": "no network of width 16-64, depth 3-4 in this run"})
    n64 = next((n for n in networks if n["width"] == 64 and n["depth"] == 4), None)
    modes = [m for m in ("ubo", "texture") if n64 and m in n64["modes"]]
    if modes:
        ok = all(n64["modes"][m]["compile_link_s"] < TARGET_COMPILE_S for m in modes)
        detail = ", ".join(f"{m}: {n64['modes'][m]['compile_link_s']:.3f} s compile+link "
                           f"(+{n64['modes'][m]['first_draw_s']:.2f} s first draw)" for m in modes)
        out.append({"target": f"ubo/texture compile+link of 64x4 < {TARGET_COMPILE_S:g} s", "met": ok,
                    "detail": detail})
    else:
        out.append({"target": f"ubo/texture compile+link of 64x4 < {TARGET_COMPILE_S:g} s", "met": None,
                    "detail": "64x4 with ubo/texture not in this run"})
    errs = [m["max_error"] for n in networks for m in n["modes"].values()]
    out.append({"target": f"every mode matches torch to {PARITY_TOL:g}",
                "met": all(m["parity_ok"] for n in networks for m in n["modes"].values()),
                "detail": f"max error {max(errs):.2e}" if errs else "nothing measured"})
    return out


def _mark(met) -> str:
    return "✅" if met else ("➖" if met is None else "❌")


def markdown(result: dict) -> str:
    m, peak = result["machine"], result["sgemm"]
    b = result["batch"]
    lines = [
        "# inshade bench mlp",
        "",
        machine_markdown(m),
        f"- CPU count: {m['cpu_count']}; torch {m['torch']} ({m['torch_threads']} threads); "
        f"numpy {m['numpy']}; LP_NUM_THREADS={m['LP_NUM_THREADS'] or 'default'}",
        f"- batch: {b['size']}x{b['size']} = {b['pixels']} pixels; median of {result['repeats']} repeats "
        f"after one warm-up; GLSL time = {result.get('clock_note') or 'draw + finish'} "
        f"(read-back listed separately)",
        f"- numpy sgemm {peak['n']}x{peak['n']} float32: {peak['gflops']:.1f} GFLOP/s (practical peak)",
        f"- GFLOP/s count the dense layers only (2*in*out + bias per pixel); parity tolerance "
        f"{result['parity_tolerance']:g}",
        "",
        "| network | dense FLOP/px | torch ms | storage | GLSL ms | speedup | GFLOP/s | % sgemm "
        "| compile+link s | first draw s | read-back ms | max err |",
        "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    quick = result.get("quick", False)
    if quick:   # a smoke test: per-call overhead dominates a tiny net on a small batch, ratios mean nothing
        lines[-3:-3] = ["- **--quick**: a smoke test (one tiny net, small batch); times are per-call overhead, so "
                        "no speedup or % of sgemm is reported. Run without --quick for comparable numbers."]
    for n in result["networks"]:
        first = True
        for mode, r in n["modes"].items():
            label = mode if r["resolved"] == mode else f"{mode} ({r['resolved']})"
            head = (f"| {n['name']} | {n['dense_flops_per_px']} | {n['torch_s'] * 1e3:.1f} " if first
                    else "| | | ")
            speedup, share = ("–", "–") if quick else (f"{r['speedup_vs_torch']:.2f}x", f"{r['fraction_of_sgemm']:.0%}")
            lines.append(head + f"| {label} | {r['seconds'] * 1e3:.1f} | {speedup} "
                         f"| {r['gflops']:.1f} | {share} | {r['compile_link_s']:.3f} "
                         f"| {r['first_draw_s']:.2f} | {r['read_s'] * 1e3:.1f} "
                         f"| {r['max_error']:.1e}{'' if r['parity_ok'] else ' ❌'} |")
            first = False
    lines += markdown_rows(result)
    lines += ["", "## Targets", "", "| target | met | detail |", "|---|:---:|---|"]
    lines += [f"| {t['target']} | {_mark(t['met'])} | {t['detail']} |" for t in result["targets"]]
    return "\n".join(lines) + "\n"


def plot(result: dict, path: Path) -> None:
    plt = matplotlib_pyplot()

    nets = result["networks"]
    modes = list(dict.fromkeys(k for n in nets for k in n["modes"]))
    series = [("torch CPU", [n["pixels"] / n["torch_s"] / 1e6 for n in nets])]
    series += [(f"GLSL {k}", [n["pixels"] / n["modes"][k]["seconds"] / 1e6 if k in n["modes"] else 0
                              for n in nets]) for k in modes]
    series += plot_series(nets)
    fig, ax = plt.subplots(figsize=(max(6, 1.4 * len(nets) + 2), 4.5))
    width = 0.8 / len(series)
    xs = np.arange(len(nets))
    for j, (label, vals) in enumerate(series):
        ax.bar(xs + (j - (len(series) - 1) / 2) * width, vals, width, label=label,
               color="0.4" if j == 0 else None)
    ax.set_yscale("log")
    ax.set_xticks(xs, [n["name"] for n in nets])
    ax.set_xlabel("network (hidden width x depth)")
    ax.set_ylabel("throughput, Mpixel/s (log)")
    ax.set_title(f"MLP evaluation, {result['batch']['size']}² batch — {result['machine']['gl_renderer']}",
                 fontsize=9)
    ax.grid(axis="y", which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper

CLAIMS = {"speedup": Claim("none (inshade's own targets)", "generated GLSL MLP vs torch on the CPU",
                           "GLSL >= 3x torch CPU (our target)", 3.0)}


def headlines(r: dict) -> list[dict]:
    best = []
    for net in r["networks"]:
        mode, m = max(net["modes"].items(), key=lambda kv: kv[1]["speedup_vs_torch"])
        best.append((net["name"], mode, m["speedup_vs_torch"]))
    worst = min(best, key=lambda b: b[2])
    return [claim_row(CLAIMS, "mlp", "speedup", ", ".join(f"{n}: {s:.1f}x ({m})" for n, m, s in best), worst[2],
                      "slowest network")]


BENCH = Bench("mlp", __doc__, Settings, run, cold_cache=True, formatter=argparse.ArgumentDefaultsHelpFormatter,
              quick={"size": 64, "repeats": 2, "widths": [8], "depths": [1]},
              sizes={"cpu": sized(60, size=256, repeats=5, depths=[3], storage=["inline", "texture"], sgemm_size=1024),
                     "device": sized(25, size=1024, repeats=5, clock="auto")},
              claims=CLAIMS, headlines=headlines)
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite
