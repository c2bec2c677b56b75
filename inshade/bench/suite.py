"""`inshade bench suite`: every bench in one run, sized by a preset, and a one-page summary of its
headline numbers next to the papers' claims.

Runs ``inshade bench mlp`` and every registered technique's bench (the technique registry's
``bench`` field), one after another in this process, each with the command line of ``--preset``:

- ``cpu``: small sizes that finish in a few minutes on a 2-core machine (Mesa llvmpipe);
- ``device``: the sizes for one GPU, all benches together within 8 minutes.

Every bench writes its JSON, markdown and plot into ``--out`` (default
``docs/bench/<renderer-slug>/``, the slug from GL_RENDERER, e.g. ``nvidia-h200``). A bench that
fails (exit status, exception) is recorded with its error line and the suite goes on. Then
``summary.json``, ``summary.md`` and ``summary.png`` (ours / paper per claim): GL_RENDERER, the
paper's number next to ours for each technique's headline measure, and each bench's wall time
against its budget in the preset. The budgets are reported, not enforced: a bench over its budget
still finishes. Exit status 1 when any bench was not ok, 2 for a bad option.
"""
from __future__ import annotations

import argparse
import contextlib
import gc
import importlib
import io
import json
import math
import re
import shlex
import sys
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from inshade import command, papers
from inshade.bench.harness import BenchError, machine, machine_markdown, markdown_table, matplotlib_pyplot, write_report

PRESETS = ("cpu", "device")
DEVICE_MINUTES = 8          # the device preset's budget, all benches together
NAME = "suite"              # this bench's own name in the bench table (it does not run itself)


@dataclass(frozen=True)
class Sizing:
    """One bench's command line in a preset (without --out) and the wall time it should take."""
    argv: tuple[str, ...]
    budget_s: float


# Per bench, per preset. A bench registered without an entry here is reported as not run (and
# tests/test_bench_suite.py fails), so a new technique's bench gets its sizes here.
SIZES: dict[str, dict[str, Sizing]] = {
    "mlp": {
        "cpu": Sizing(("--size", "256", "--repeats", "5", "--depths", "3", "--storage", "inline,texture",
                       "--sgemm-size", "1024"), 60),
        "device": Sizing(("--size", "1024", "--repeats", "5", "--clock", "auto"), 25),
    },
    "export": {
        # the ONNX check compiles a 512-wide network cold on llvmpipe: about a minute of it
        "cpu": Sizing(("--repeats", "2"), 180),
        "device": Sizing(("--repeats", "3"), 20),
    },
    "prt": {
        "cpu": Sizing(("--assets", "trained/prt_creature,trained/prt_mesh", "--sizes", "64:512",
                       "--repeats", "3", "--rays", "500"), 60),
        "device": Sizing(("--sizes", "64:512,1024;128:1024;256:512", "--repeats", "10", "--torch-size", "256"), 75),
    },
    "di_texture": {
        # trains the DI textures here (the shipped ones are found only at their own size)
        "cpu": Sizing(("--images", "astronaut", "--ratios", "6"), 60),
        "device": Sizing(("--images", "astronaut,chelsea", "--size", "256", "--ratios", "6",
                          "--steps", "2000"), 60),
    },
    "di_footprint": {
        "cpu": Sizing(("--ss", "8"), 30),
        "device": Sizing((), 45),
    },
    "di_brdf": {
        "cpu": Sizing((), 30),
        # 2880^2 ~ the paper's 4K pixel count (Table 1)
        "device": Sizing(("--size", "2880", "--rounds", "15"), 25),
    },
    "di_sdf": {
        "cpu": Sizing(("--di-steps", "500", "--mlp-steps", "600", "--mlp-samples", "50000", "--size", "128",
                       "--frames", "3"), 150),
        "device": Sizing(("--mlp-steps", "2000", "--size", "512", "--frames", "10"), 60),   # 2000 MLP steps: seconds on a GPU
    },
    "di_radiance_field": {
        "cpu": Sizing(("--quick",), 60),
        "device": Sizing(("--quick", "--time-size", "2048", "--rounds", "7"), 15),
    },
    "di_shading": {
        "cpu": Sizing(("--time-size", "256", "--repeats", "3"), 30),
        "device": Sizing(("--time-size", "2048", "--repeats", "10"), 15),
    },
    "neural_appearance": {
        # ~35 s with Mesa's shader cache warm; a cold cache adds minutes of llvmpipe JIT
        "cpu": Sizing(("--assets", "trained/neural_appearance_ceramic", "--size", "256", "--quality-size", "64",
                       "--quality-spp", "2", "--sampler-frames", "4", "--rounds", "3", "--warmup", "1"), 90),
        "device": Sizing(("--size", "2048", "--rounds", "15"), 50),
    },
    "uvfree_material": {
        "cpu": Sizing(("--assets", "trained/uvfree_material_fruit_balanced", "--quality-size", "128",
                       "--width", "512", "--height", "384", "--rounds", "5", "--warmup", "1",
                       "--codecs", "BC1,BC7,ASTC 6x6,ASTC 8x8"), 90),
        # the thesis times a 1280x720 query
        "device": Sizing(("--width", "1280", "--height", "720", "--rounds", "15"), 80),
    },
    "appearance_prefilter": {
        "cpu": Sizing(("--assets", "trained/appearance_prefilter_grove", "--scales", "3", "4", "--spp", "16",
                       "--rounds", "2"), 60),
        "device": Sizing(("--scales", "3", "4", "5", "--rounds", "5"), 10),
    },
}


# ---------------------------------------------------------------------------------------------
# the papers' claims, and our headline numbers read from each bench's JSON

@dataclass(frozen=True)
class Claim:
    paper: str                    # short citation
    measure: str                  # what is compared
    says: str                     # the paper's number, in words
    value: float | None = None    # the paper's number, where there is one
    higher_better: bool = True    # False for times


DI = "Differentiable Indirection (Datta et al. 2023)"
CLAIMS: dict[str, dict[str, Claim]] = {
    "mlp": {"speedup": Claim("none (inshade's own targets)", "generated GLSL MLP vs torch on the CPU",
                             "GLSL >= 3x torch CPU (our target)", 3.0)},
    "export": {"export_check": Claim("none (inshade's own targets)", "inshade.export + check of a 64x4 MLP, "
                                                                    "cold shader compile", "under 5 s (our target)",
                                     5.0, higher_better=False)},
    "prt": {
        "fps": Claim("Learnt Transfer (Dhawal et al. 2022), Table 2", "k=64 transfer net on an analytic SDF, "
                     "FPS at 1024² (ours scaled by pixel count)", "173.6-320.1 FPS on an RTX 3090", 173.6),
        "torch": Claim("Learnt Transfer, Table 4", "GLSL vs the torch/CUDA path, k=64 (speed-up)",
                       "GLSL 64.4 vs CUDA 55.1 FPS: 1.17x", 64.4 / 55.1),
    },
    "di_texture": {"astc": Claim(f"{DI}, Fig. 14a", "DI (exact) PSNR minus ASTC's at the nearest ratio (dB)",
                                 "'comparable in quality with ASTC' at 1K (no number in the text)", 0.0)},
    "di_footprint": {"trilinear": Claim(f"{DI}, Fig. 12", "DI footprint sampler PSNR minus GL trilinear's "
                                        "(RGB8 + mips), vs supersampled truth (dB)",
                                        "quality 'much superior to 1-spp ASTC' at 12x (no number in the text)")},
    "di_brdf": {"disney4": Claim(f"{DI}, Table 1", "Disney BRDF cost (minus the diffuse base), analytic / "
                                 "learned, 4 lights, hardware filtering", "0.742 / 0.255 ms: 2.9x on a mobile "
                                 "RTX 3070 Ti at 4K", 0.742 / 0.255)},
    "di_sdf": {"mlp": Claim(f"{DI}, Fig. 8 / 14c", "surface error of the MLP SDF / the DI-SDF's at equal bytes "
                            "(> 1: DI better)", "'compares favourably with MRHE at equal parameter count' "
                            "(MRHE, not an MLP; no number in the text)")},
    "di_radiance_field": {"10x": Claim(f"{DI}, Sec. 6.0.3 / Fig. 7", "PSNR of DI renders vs the uncompressed-grid "
                                       "renders at ~10x overall (dB)", "density to 10x, RGB to 100x 'without losing "
                                       "significant details' (no number in the text)")},
    "di_shading": {"gain": Claim(f"{DI}, Fig. 1 / 13", "end-to-end (best lambda) PSNR gain over independent "
                                 "training vs the 16-sample reference (%)", "+5% (Fig. 13) to +8% (Fig. 1)", 8.0)},
    "neural_appearance": {
        "2x16": Claim("Real-Time Neural Appearance Models (2024), Figs. 15-16", "2x16 decoder vs the reference "
                      "material (speed-up)", "4.14x, full frame, RTX 4090", 4.14),
        "2x32": Claim("Real-Time Neural Appearance Models, Table 5", "2x32 decoder vs the reference material "
                      "shading (speed-up)", "9.06x, material shading, RTX 4090", 9.06),
        "3x64": Claim("Real-Time Neural Appearance Models, Table 5", "3x64 decoder vs the reference material "
                      "shading (speed-up)", "2.30x, material shading, RTX 4090", 2.30),
    },
    "uvfree_material": {
        "ms": Claim("Feature hierarchy (Walloner 2024)", "decode cost (decoded minus textured frame), ms per "
                    "1280x720 (ours scaled by pixel count)", "5-12 ms per 1280x720 query, RTX 2080 Ti (CUDA)", 12.0, higher_better=False),
        "rate": Claim("Feature hierarchy (Walloner 2024)", "memory, % of the uncompressed textures (features + "
                      "MLP)", "66.6% down to 8.3%"),
    },
    "appearance_prefilter": {
        "crossover": Claim("Deep Appearance Prefiltering (Bako et al. 2022), Sec. 6.3", "finest scale at which the "
                           "prefiltered frame is faster than equal-quality ray tracing", "around scale 5 (GPU beam "
                           "tracer + TensorRT vs OptiX)", 5.0),
        "voxel": Claim("Deep Appearance Prefiltering, Sec. 5.4", "bytes per voxel", "just over 3 KB (797 fp32 floats)",
                       3188.0, higher_better=False),
    },
}
# the paper record behind each claim table (for the summary's links)
PAPERS = {"prt": papers.LEARNT_TRANSFER, "di_texture": papers.DIFFERENTIABLE_INDIRECTION,
          "di_footprint": papers.DIFFERENTIABLE_INDIRECTION, "di_brdf": papers.DIFFERENTIABLE_INDIRECTION,
          "di_sdf": papers.DIFFERENTIABLE_INDIRECTION, "di_shading": papers.DIFFERENTIABLE_INDIRECTION,
          "di_radiance_field": papers.DIFFERENTIABLE_INDIRECTION,
          "neural_appearance": papers.NEURAL_APPEARANCE,
          "uvfree_material": papers.FEATURE_HIERARCHY, "appearance_prefilter": papers.APPEARANCE_PREFILTERING}


def _row(bench: str, key: str, ours: str, value: float | None = None, subject: str = "") -> dict:
    c = CLAIMS[bench][key]
    ratio = value / c.value if value is not None and c.value not in (None, 0.0) else None
    return {"bench": bench, "claim": key, "subject": subject, "paper": c.paper, "measure": c.measure,
            "paper_says": c.says, "paper_value": c.value, "higher_better": c.higher_better, "ours": ours,
            "ours_value": value, "ours_over_paper": ratio}


def _x(v: float | None) -> str:
    return "?" if v is None else f"{v:.2f}"   # the harness stores a non-finite ratio as None


def _verdict(ratio: Mapping) -> str:
    return f"{_x(ratio['median'])}x ({_x(ratio['low'])}-{_x(ratio['high'])}, {ratio['verdict']})"


def _mlp(r: Mapping) -> list[dict]:
    best = []
    for net in r["networks"]:
        mode, m = max(net["modes"].items(), key=lambda kv: kv[1]["speedup_vs_torch"])
        best.append((net["name"], mode, m["speedup_vs_torch"]))
    worst = min(best, key=lambda b: b[2])
    return [_row("mlp", "speedup", ", ".join(f"{n}: {s:.1f}x ({m})" for n, m, s in best), worst[2],
                 "slowest network")]


def _export(r: Mapping) -> list[dict]:
    e, t, o, m = r["export"], r["export_texture"], r["onnx"], r["memory"]
    return [_row("export", "export_check", f"{e['median_s']:.1f} s (check storage {e['storage']}), "
                 f"{t['median_s']:.1f} s (texture); ONNX import {o['import_s'] * 1e3:.0f} ms; memory "
                 f"{m['over_params']:.2f}x the parameters", e["median_s"], "64x4 MLP")]


def _prt(r: Mapping) -> list[dict]:
    rows = []
    sdf = [f for f in r["frames"] if f["k"] == 64 and f["geometry"] == "analytic SDF"]
    for shading in sorted({f["shading"] for f in sdf}):
        f = max((f for f in sdf if f["shading"] == shading), key=lambda f: f["size"])
        fps_1024 = f["fps"] * (f["size"] / 1024) ** 2
        scaled = f" ({fps_1024:.1f} at 1024²)" if f["size"] != 1024 else ""
        rows.append(_row("prt", "fps", f"{f['fps']:.1f} FPS at {f['size']}²{scaled}, {f['asset']}", fps_1024, shading))
    for t in r["torch"]:
        rows.append(_row("prt", "torch", f"{t['speedup']:.1f}x at {t['size']}² ({t['asset']}, torch on "
                                         f"{t['torch_threads']} CPU threads)", t["speedup"], t["shading"]))
    return rows


def _di_texture(r: Mapping) -> list[dict]:
    rows = []
    for image in r["images"]:
        entries = [e for e in image["entries"] if e.get("available")]
        astc = [e for e in entries if e["family"] == "ASTC"]
        for di in (e for e in entries if e["codec"] == "DI (exact)"):
            near = min(astc, key=lambda e: abs(math.log(e["ratio"] / di["ratio"])))
            gap = di["psnr"] - near["psnr"]
            rows.append(_row("di_texture", "astc", f"{gap:+.2f} dB: DI {di['psnr']:.2f} dB at {di['ratio']:.1f}x, "
                             f"{near['codec']} {near['psnr']:.2f} dB at {near['ratio']:.1f}x ({image['size']}²)",
                             gap, image["image"].rsplit(".", 1)[-1]))
    return rows


def _di_footprint(r: Mapping) -> list[dict]:
    by = {row["mode"]: row for row in r["rows"]}
    di = by["di"]
    gl = next(row for row in r["rows"] if row["label"].startswith("GL trilinear (RGB8"))
    gap = di["psnr_vs_truth"] - gl["psnr_vs_truth"]
    return [_row("di_footprint", "trilinear", f"{gap:+.2f} dB: DI {di['psnr_vs_truth']:.2f} dB in "
                 f"{di['bytes']} B, trilinear {gl['psnr_vs_truth']:.2f} dB in {gl['bytes']} B", gap)]


def _di_brdf(r: Mapping) -> list[dict]:
    rows = []
    for model in ("disney",):
        for row in r["models"].get(model, {}).get("rows", []):
            if row["filter"] == "fast" and row["lights"] == 4:
                rows.append(_row("di_brdf", "disney4", f"{_verdict(row['speedup'])}; analytic "
                                 f"{row['analytic_minus_base_ms']:.3f} ms, learned {row['learned_minus_base_ms']:.3f} "
                                 f"ms at {r['size']}²", row["speedup"]["median"], model))
    return rows


def _di_sdf(r: Mapping) -> list[dict]:
    rows = []
    for budget in r["budgets"]:
        di = next(x for x in budget["rows"] if x["method"] == "DI-SDF (exact)")
        mlp = next((x for x in budget["rows"] if x.get("kind") == "neural_sdf" and "surface_mae" in x), None)
        if mlp is None:
            rows.append(_row("di_sdf", "mlp", f"no MLP at {budget['di_bytes']} B (skipped); DI MAE/r "
                             f"{di['surface_mae_per_radius']:.2e}, IoU {di['iou']:.3f}", None, f"{budget['di_bytes']} B"))
            continue
        ratio = mlp["surface_mae"] / di["surface_mae"]
        rows.append(_row("di_sdf", "mlp", f"{ratio:.1f}x: MAE/r DI {di['surface_mae_per_radius']:.2e} vs "
                         f"{mlp['method']} {mlp['surface_mae_per_radius']:.2e}; IoU {di['iou']:.3f} vs "
                         f"{mlp['iou']:.3f}", ratio, f"{budget['di_bytes']} B"))
    return rows


def _di_radiance_field(r: Mapping) -> list[dict]:
    rows = []
    for x in r["rows"]:
        if x["density_ratio"] == 10 and x["colour_ratio"] == 10:
            flip = "" if x["flip_mean"] is None else f", FLIP {x['flip_mean']:.4f}"
            rows.append(_row("di_radiance_field", "10x", f"{x['psnr_mean']:.2f} dB (min {x['psnr_min']:.2f}){flip} at "
                             f"{x['overall_ratio']:.1f}x overall, {r['field']['grid']}³", x["psnr_mean"]))
    return rows


def _di_shading(r: Mapping) -> list[dict]:
    base = next(x for x in r["rows"] if x["lambda"] == 0.0)
    best = max((x for x in r["rows"] if x["lambda"] > 0), key=lambda x: x["psnr"])
    return [_row("di_shading", "gain", f"{best['psnr_gain_percent']:+.1f}%: lambda {best['lambda']:g} "
                 f"{best['psnr']:.2f} dB vs independent {base['psnr']:.2f} dB", best["psnr_gain_percent"])]


def _neural_appearance(r: Mapping) -> list[dict]:
    rows = []
    for asset, a in r["assets"].items():
        speed = a["speed"]["speedup_vs_reference"]
        for decoder in ("2x16", "2x32", "3x64"):
            if decoder in speed:
                rows.append(_row("neural_appearance", decoder, f"{_verdict(speed[decoder])} at "
                                 f"{a['speed']['size']}²", speed[decoder]["median"],
                                 asset.removeprefix("neural_appearance_")))
    return rows


def _uvfree_material(r: Mapping) -> list[dict]:
    rows = []
    for asset, a in r["assets"].items():
        d = a["decode"]
        ms = 1e3 * (d["ms"]["decoded"]["median_s"] - d["ms"]["reference"]["median_s"])
        per_720p = ms * 1280 * 720 / (d["width"] * d["height"])
        name = asset.removeprefix("uvfree_material_")
        rows.append(_row("uvfree_material", "ms", f"{per_720p:.2f} ms ({ms:.2f} ms at {d['width']}x{d['height']}, "
                         f"{d['coverage']:.0%} covered)", per_720p, name))
        m = a["memory"]
        albedo = next(q["albedo_psnr"] for q in a["quality"] if q["view"] == "all")
        rows.append(_row("uvfree_material", "rate", f"{m['rate_features_mlp']:.1%} at albedo {albedo:.2f} dB "
                         f"({m['rate_all']:.1%} with owner tables)", 100 * m["rate_features_mlp"], name))
    return rows


def _appearance_prefilter(r: Mapping) -> list[dict]:
    rows = []
    for asset, a in r["assets"].items():
        name = asset.removeprefix("appearance_prefilter_")
        c = a["crossover_scale"]
        rows.append(_row("appearance_prefilter", "crossover", "none (ray tracing faster at every scale)" if c is None
                         else f"scale {c}", None if c is None else float(c), name))
        per = a["memory"]["bytes_per_voxel"]
        rows.append(_row("appearance_prefilter", "voxel", f"{per:.0f} B", float(per), name))
    return rows


HEADLINES: dict[str, Callable[[Mapping], list[dict]]] = {
    "mlp": _mlp, "export": _export, "prt": _prt, "di_texture": _di_texture, "di_footprint": _di_footprint, "di_brdf": _di_brdf,
    "di_sdf": _di_sdf, "di_shading": _di_shading, "di_radiance_field": _di_radiance_field, "neural_appearance": _neural_appearance, "uvfree_material": _uvfree_material,
    "appearance_prefilter": _appearance_prefilter,
}


def headlines(name: str, result: Mapping) -> list[dict]:
    """The summary rows of one bench's JSON; a JSON this code cannot read gives one row saying so."""
    if name not in HEADLINES:
        return []
    try:
        return HEADLINES[name](result)
    except (KeyError, IndexError, TypeError, ValueError, StopIteration, ZeroDivisionError) as exc:
        return [{"bench": name, "claim": None, "subject": "", "paper": "", "measure": "headline numbers",
                 "paper_says": "", "paper_value": None, "higher_better": True, "ours": f"could not read {name}.json: "
                 f"{type(exc).__name__}: {exc}", "ours_value": None, "ours_over_paper": None}]


# ---------------------------------------------------------------------------------------------
# running

def slug(renderer: str) -> str:
    """A folder name for a GL_RENDERER string: the part before the first '/' (NVIDIA appends
    '/PCIe/SSE2'), lower case, runs of other characters as '-'.
    'llvmpipe (LLVM 15.0.6, 256 bits)' -> 'llvmpipe-llvm-15-0-6-256-bits'; 'NVIDIA H200/PCIe/SSE2' -> 'nvidia-h200'."""
    text = re.sub(r"[^a-z0-9]+", "-", renderer.split("/", 1)[0].lower()).strip("-")
    return text or "unknown-renderer"


def registered() -> dict[str, str]:
    """name -> module of every bench `inshade bench` mounts, but this one."""
    from inshade.cli import benches

    return {name: module for name, (module, _) in benches().items() if name != NAME}


class _Tee(io.TextIOBase):
    """stderr that is also kept, to find a failing bench's error line."""

    def __init__(self, stream):
        self.stream, self.kept = stream, io.StringIO()

    def write(self, text: str) -> int:
        self.stream.write(text)
        self.kept.write(text)
        return len(text)

    def flush(self) -> None:
        self.stream.flush()

    def isatty(self) -> bool:   # progress bars stay as they would be
        return self.stream.isatty()

    def fileno(self) -> int:
        return self.stream.fileno()

    @property
    def encoding(self):
        return getattr(self.stream, "encoding", "utf-8")


def _error_line(stderr: str) -> str | None:
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("inshade: error:")]
    if errors:
        return errors[-1].removeprefix("inshade: error:").strip()
    return lines[-1] if lines else None


def run_bench(name: str, main: Callable[[list[str]], int], argv: list[str], out: Path) -> dict:
    """Run one bench's main(argv) and return its record: status ok | failed, the error line, the
    wall time, and its JSON result (read only when written by this run)."""
    started_ns, start = time.time_ns(), time.perf_counter()
    tee, error = _Tee(sys.stderr), None
    try:
        with contextlib.redirect_stderr(tee):
            rc = main(argv)
    except SystemExit as exc:   # argparse rejected an option of the preset
        rc = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
        error = None if isinstance(exc.code, int) or exc.code is None else str(exc.code)
    except Exception as exc:  # noqa: BLE001 - one bench's failure must not cost the others' results
        traceback.print_exc()
        rc, error = 1, f"{type(exc).__name__}: {exc}"
    seconds = time.perf_counter() - start
    gc.collect()   # GL objects a failed bench left behind
    record = {"name": name, "argv": argv, "seconds": round(seconds, 2), "status": "ok", "error": None,
              "json": None, "result": None}
    path = out / f"{name}.json"
    if rc:
        error = error or _error_line(tee.kept.getvalue()) or f"exit status {rc}"
    elif not path.is_file() or path.stat().st_mtime_ns < started_ns:
        error = f"exited 0 but wrote no {path.name}"
    else:
        try:
            record["result"] = json.loads(path.read_text())
            record["json"] = path.name
        except (OSError, ValueError) as exc:
            error = f"{path.name}: {exc}"
    if error is not None:
        record.update(status="failed", error=" ".join(str(error).split()))
    return record


def run_suite(out: Path, plan: Mapping[str, Sizing | None], mains: Mapping[str, Callable[[list[str]], int]],
              *, preset: str, gl: Mapping, log=print) -> dict:
    """Run each bench of ``plan`` (name -> its sizing, None: not in the preset) into ``out`` and
    write the summary after each one (a suite stopped half way leaves the summary so far)."""
    out.mkdir(parents=True, exist_ok=True)
    result = {"benchmark": "suite", "preset": preset, "out": str(out), "machine": machine(gl),
              "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
              "budget_s": sum(s.budget_s for s in plan.values() if s is not None), "seconds": 0.0,
              "benches": [], "headlines": []}
    for name, sizing in plan.items():
        if sizing is None:
            record = {"name": name, "argv": None, "seconds": 0.0, "status": "not run", "budget_s": None,
                      "error": f"no '{preset}' sizing for it in inshade/bench/suite.py SIZES", "json": None}
        else:
            argv = [*sizing.argv, "--out", str(out)]
            log(f"suite: {name} ({sizing.budget_s:g} s budget): inshade bench {name} {shlex.join(argv)}")
            record = run_bench(name, mains[name], argv, out)
            record["budget_s"] = sizing.budget_s
            record["over_budget"] = record["seconds"] > sizing.budget_s
            bench_result = record.pop("result")
            if bench_result is not None:
                result["headlines"] += headlines(name, bench_result)
            log(f"suite: {name} {record['status']} in {record['seconds']:.1f} s"
                + (f": {record['error']}" if record["error"] else ""))
        result["benches"].append(record)
        result["seconds"] = round(sum(b["seconds"] for b in result["benches"]), 2)
        write_report(out, "summary", result, markdown, plot, echo=False)
    return result


# ---------------------------------------------------------------------------------------------
# report

def _num(v: float | None) -> str:
    return "—" if v is None else f"{v:.3g}"


def _ratio(v: float | None) -> str:
    if v is None:
        return "—"
    return f"{v:.0f}" if v >= 100 else f"{v:.2f}" if v >= 0.1 else f"{v:.2g}"


def markdown(r: Mapping) -> str:
    m = r["machine"]
    failed = [b for b in r["benches"] if b["status"] != "ok"]
    lines = [f"# inshade bench suite: preset `{r['preset']}`", "",
             f"**GL_RENDERER: `{m['gl_renderer']}`**", "",
             machine_markdown(m),
             f"- {r['created']}; {len(r['benches'])} benches, {len(failed)} not ok; wall time {r['seconds']:.0f} s "
             f"(budget {r['budget_s']:.0f} s); each bench's own report: its `NAME.md` / `NAME.json` / `NAME.png` "
             "beside this file", "",
             "## Against the papers", "",
             "Ours is measured on the renderer above; the papers' numbers are from their own GPUs, so a ratio is "
             "a pointer, not a verdict. ours / paper: ours divided by the paper's number, where both are numbers.", ""]
    rows = [[h["bench"], h["subject"] or "—", h["measure"], h["paper_says"] or "—", h["ours"],
             _ratio(h["ours_over_paper"])] for h in r["headlines"]]
    lines += markdown_table(["bench", "subject", "measure", "paper", "ours", "ours / paper"], rows, "lllllr")
    lines += ["", "## Benches", ""]
    rows = [[b["name"], b["status"], f"{b['seconds']:.1f}", _num(b["budget_s"]),
             "over" if b.get("over_budget") else "", f"[{b['name']}.md]({b['name']}.md)" if b["json"] else "—",
             b["error"] or ""] for b in r["benches"]]
    lines += markdown_table(["bench", "status", "seconds", "budget s", "", "report", "error"], rows, "llrrlll")
    lines += ["", "Command lines (each with `--out` this folder):", ""]
    lines += [f"- `inshade bench {b['name']} {shlex.join(b['argv'][:-2])}`" for b in r["benches"] if b["argv"]]
    cited = {PAPERS[b["name"]].cite() for b in r["benches"] if b["name"] in PAPERS}
    lines += ["", "Papers:", ""] + [f"- {c}" for c in sorted(cited)]
    return "\n".join(lines) + "\n"


def plot(r: Mapping, path: Path) -> None:
    plt = matplotlib_pyplot()
    rows = [h for h in r["headlines"] if h["ours_over_paper"] is not None and h["ours_over_paper"] > 0]
    fig, ax = plt.subplots(figsize=(8, 1.2 + 0.3 * max(1, len(rows))))
    labels = [f"{h['bench']} {h['claim']} {h['subject']}" + ("" if h["higher_better"] else " (lower is better)")
              for h in rows]
    # green: ours beats the paper's number in its own direction (more speed-up, fewer ms)
    good = [(h["ours_over_paper"] >= 1) == h["higher_better"] for h in rows]
    ax.scatter([h["ours_over_paper"] for h in rows], range(len(rows)),
               c=["tab:green" if g else "tab:red" for g in good], zorder=3)
    ax.axvline(1.0, color="k", lw=0.8)
    ax.grid(axis="x", which="major", alpha=0.3)
    ax.set_yticks(range(len(rows)), labels, fontsize=7)
    ax.set_xscale("log")
    ax.invert_yaxis()
    ax.set_xlabel("ours / paper (1 = the paper's number)")
    ax.set_title(f"{r['machine']['gl_renderer']}, preset {r['preset']}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# command line

def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    p.add_argument("--preset", choices=PRESETS, required=True,
                   help="cpu: minutes on a 2-core machine; device: one GPU, <= 8 minutes in all")
    p.add_argument("--out", help="output folder (default docs/bench/<renderer-slug>, e.g. docs/bench/nvidia-h200)")
    p.add_argument("--only", metavar="NAME,...", help="run only these benches (comma-separated)")
    p.add_argument("--dry-run", action="store_true", help="print each bench's command line and budget, run nothing")
    return p


def main(argv=None) -> int:
    return command.main("inshade bench suite", __doc__, add_arguments, run, argv, errors=(BenchError,))


def plan_for(preset: str, names: list[str]) -> dict[str, Sizing | None]:
    return {name: SIZES.get(name, {}).get(preset) for name in names}


def run(args) -> int:
    modules = registered()
    names = list(modules)
    if args.only is not None:
        names = [n.strip() for n in args.only.split(",") if n.strip()]
        unknown = [n for n in names if n not in modules]
        if unknown or not names:
            raise BenchError(f"--only: unknown bench {', '.join(unknown) or '(none given)'} "
                             f"(known: {', '.join(modules)})")
    plan = plan_for(args.preset, names)
    if args.dry_run:
        for name, sizing in plan.items():
            print(f"{sizing.budget_s:5.0f} s  inshade bench {name} {shlex.join(sizing.argv)}" if sizing
                  else f"    —    {name}: no '{args.preset}' sizing")
        print(f"{sum(s.budget_s for s in plan.values() if s):5.0f} s  in all")
        return 0
    from inshade.runtime.context import gl_info, shared_context

    # This makes the process's first GL context, so `inshade bench mlp`'s own MESA_SHADER_CACHE_DISABLE
    # default comes too late: in the suite, shader caches stay as the environment sets them
    # (first-draw times are then warm on a rerun; steady-state timings, the summary's, are not affected).
    gl = gl_info(shared_context())
    out = Path(args.out) if args.out else Path("docs/bench") / slug(gl["renderer"])
    print(f"inshade bench suite: GL_RENDERER {gl['renderer']}; preset {args.preset}; writing {out}", file=sys.stderr)

    def loader(module: str):
        def bench_main(argv: list[str]) -> int:
            return importlib.import_module(module).main(argv)
        return bench_main

    result = run_suite(out, plan, {n: loader(modules[n]) for n in plan}, preset=args.preset, gl=gl,
                       log=lambda text: print(text, file=sys.stderr))
    print(markdown(result))
    bad = [b["name"] for b in result["benches"] if b["status"] != "ok"]
    print(f"wrote {out / 'summary.md'} ({len(bad)} of {len(result['benches'])} benches not ok"
          + (f": {', '.join(bad)})" if bad else ")"), file=sys.stderr)
    return 1 if bad else 0
