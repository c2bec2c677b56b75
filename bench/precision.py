"""`inshade bench precision`: what storing a network at f16 or i8 saves and costs.

Per shipped asset whose networks hold dense layers or float tables (or the ones named), each network
(and network SDF) quantized as
``inshade.export(..., precision=P)`` stores it (inshade/quantize.py), P in f32 / f16 / i8: the dense
weights at P, the float32 tables at f16 below f32, and at i8 every table in its 8-bit codes (u8, or a
lookup array's 8 bits);

- bytes: every resource the generated code binds with the weights in textures (dense rows at the
  precision's texel size, the lookup arrays, grids, latents, voxels and mesh features at theirs), and
  the dense weights alone;
- the twin's error: max |twin(P) - twin(f32)| over the networks' outputs on random rows in [-1, 1]
  (integer lanes: ids in [0, 1000));
- the picture: ``inshade render`` at ``--size`` with the quantized networks against the f32 render
  (PSNR of the 8-bit sRGB pictures, the weights in textures where the scene has the setting), and the
  render's seconds in this process (programs compiled cold for each precision); where the scene has a
  reference image, a render at its size against it too (each precision's PSNR against the asset's own
  reference, and its distance from f32's);
- the web page: ``inshade export-web`` of the asset with its networks so stored, its folder's bytes;
- fp16 arithmetic (at f16): each network generated for Vulkan GLSL with the weights in textures and
  computed in float32, float16 and float16 with float32 sums (``--arithmetic``) on the compute device
  (lavapipe here), its seconds per batch of rows, max |shader - twin| and the float16 envelope's bound
  (inshade/convert/half_envelope.py); a network a target or the envelope cannot take is listed with why.

Writes ``precision.json``, ``precision.md`` and ``precision.png`` into ``--out``.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bench.contract import Bench, option, sized
from inshade.bench.entry import Claim, claim_row
from inshade.bench.harness import asset_folders, machine, machine_markdown, matplotlib_pyplot, write_report

DEFAULT_OUT = "bench-out/precision"
PRECISIONS = ("f32", "f16", "i8")
ROWS = 4096
ARITHMETIC = ("f32", "f16", "f16_acc32")
ARITHMETIC_TARGET = "vulkan"
REPEATS = 5   # timed runs of a batch (the median)
F16_RENDER_DB = 0.1   # the bar: an f16 render within this of the f32 one (PSNR against it: at least 50 dB)
I8_RENDER_DB = 0.5    # an i8 render's PSNR against the asset's reference within this of f32's


@dataclass
class Settings:
    assets: list[str] = option((), "asset folders (default: every shipped asset a precision changes)",
                               positional="ASSET", nargs="*")
    size: int = option(64, "render side in pixels")
    out: str = option(DEFAULT_OUT, "output folder")
    quick: bool = option(False, "one small asset (a smoke run)")


def _inputs(bundle, rng) -> np.ndarray:
    cols = [rng.integers(0, 1000, (ROWS, p.dim)).astype(np.float32) if p.dtype == "uint"
            else rng.uniform(-1.0, 1.0, (ROWS, p.dim)).astype(np.float32) for p in bundle.inputs]
    return np.concatenate(cols, 1)


def _twin_error(fp32, quantized, x) -> float:
    import torch

    from inshade.models import GraphModule

    with torch.no_grad():
        a = GraphModule.from_bundle(fp32)(torch.from_numpy(x)).numpy()
        b = GraphModule.from_bundle(quantized)(torch.from_numpy(x)).numpy()
    return float(np.abs(a - b).max())


def _gpu_bytes(bundle) -> int:
    from inshade.codegen import generate
    from inshade.codegen.glsl import TextureResource

    gen = generate(bundle, storage="texture")
    return int(sum(r.data.nbytes + sum(m.nbytes for m in r.mips) if isinstance(r, TextureResource) else r.nbytes
                   for r in gen.resources))


def _page_bytes(asset: Path, bundles, sdf, tmp: Path) -> int:
    """Bytes of the page ``inshade export-web`` writes for a copy of ``asset`` holding ``bundles`` (and the
    network SDF ``sdf``)."""
    import shutil

    from inshade.scene.description import load_scene
    from inshade.web.export import export_web

    copy = tmp / "asset"
    shutil.rmtree(copy, ignore_errors=True)
    shutil.copytree(asset, copy)
    scene = load_scene(copy)
    for n, b in zip(scene.networks, bundles):
        b.save(n.bundle)
    if sdf is not None:
        sdf.save(scene.sdf.bundle)
    export_web(copy, tmp / "page", force=True)
    return sum(f.stat().st_size for f in (tmp / "page").rglob("*") if f.is_file())


def _arithmetic_row(bundle, x, arithmetic: str) -> dict:
    from inshade.codegen import generate
    from inshade.convert.half_envelope import half_envelope
    from inshade.runtime.compute import prepare

    run = prepare(generate(bundle, target=ARITHMETIC_TARGET, storage="texture", arithmetic=arithmetic), x,
                  ARITHMETIC_TARGET)
    run.run()
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        run.run()
        times.append(time.perf_counter() - start)
    twin, bound = half_envelope(bundle, x, arithmetic)
    finite = bound[np.isfinite(bound)]
    return {"batch_s": float(np.median(times)), "max_abs": float(np.abs(run.read() - twin).max()),
            "max_bound": float(finite.max()) if finite.size else float("inf")}


def measure_arithmetic(bundles, xs) -> dict:
    """Per arithmetic, summed over the networks: seconds per batch, the largest error and bound; or why not."""
    from inshade.codegen.targets import TargetError

    out = {}
    for a in ARITHMETIC:
        try:
            rows = [_arithmetic_row(b, x, a) for b, x in zip(bundles, xs)]
        except (TargetError, ValueError) as exc:   # a component without a Vulkan lowering or a float16 rule
            return {"skipped": str(exc)}
        out[a] = {"batch_s": sum(r["batch_s"] for r in rows), "max_abs": max(r["max_abs"] for r in rows),
                  "max_bound": max(r["max_bound"] for r in rows)}
    return out


def reference_view(scene) -> str | None:
    """The setting whose choices offer "reference" (a view the program draws without its networks), if any."""
    return next((name for name, st in scene.settings.items() if "reference" in st.choices), None)


def _reference_psnr(scene, settings: dict, fp32, sdf, size: int) -> dict | None:
    """Per precision: PSNR of the 8-bit render against the asset's own reference: the scene's reference
    image (rendered at its size), else the program's reference view (at ``size``); None without either."""
    from inshade.runtime.headless import render_scene
    from inshade.runtime.scene_inputs import load_reference
    from inshade.web.browser import psnr8, srgb8

    view = reference_view(scene)
    if scene.reference is not None:
        reference = srgb8(load_reference(scene.reference.image, scene.reference.colour))
    elif view is not None:
        reference = srgb8(render_scene(scene, width=size, height=size, settings={**settings, view: "reference"},
                                       bundles=fp32, sdf_bundle=sdf)[0][..., :3])
    else:
        return None
    h, w = reference.shape[:2]
    out = {"against": "image" if scene.reference is not None else f"{view}=reference"}
    for p in PRECISIONS:
        bundles, sdf_q = _at(p, fp32, sdf)
        image, _ = render_scene(scene, width=w, height=h, settings=settings, bundles=bundles, sdf_bundle=sdf_q)
        out[p] = psnr8(srgb8(image[..., :3]), reference)
    return out


def _at(precision: str, fp32, sdf):
    """The networks and the network SDF (or None) at ``precision``."""
    from inshade.quantize import quantized

    return [quantized(b, precision) for b in fp32], None if sdf is None else quantized(sdf, precision)


def measure_asset(asset: Path, size: int) -> dict | None:
    from inshade.bundle import load
    from inshade.quantize import QUANTIZED_TYPES, lower_tables, weight_bytes
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import NetworkSdfRef, load_scene
    from inshade.web.browser import psnr8, srgb8

    scene = load_scene(asset)
    fp32 = [load(n.bundle) for n in scene.networks]
    sdf = load(scene.sdf.bundle) if isinstance(scene.sdf, NetworkSdfRef) else None
    every = fp32 + ([sdf] if sdf is not None else [])
    if not any(n.type in QUANTIZED_TYPES for b in every for n in b.nodes) and not any(map(lower_tables, every)):
        return None   # nothing a precision changes
    settings = {"labels": False, **({"storage": "texture"} if "storage" in scene.settings else {})}
    rng = np.random.default_rng(0)
    xs = [_inputs(b, rng) for b in every]
    row = {"asset": asset.name, "networks": len(every), "settings": settings, "bytes": {}, "dense_bytes": {},
           "twin_max_abs": {}, "render_psnr": {}, "render_s": {}, "page_bytes": {}}
    pictures = {}
    for p in PRECISIONS:
        bundles, sdf_q = _at(p, fp32, sdf)
        quantized_every = bundles + ([sdf_q] if sdf_q is not None else [])
        row["bytes"][p] = sum(_gpu_bytes(b) for b in quantized_every)
        row["dense_bytes"][p] = sum(weight_bytes(b) for b in quantized_every)
        row["twin_max_abs"][p] = max(_twin_error(a, b, x) for a, b, x in zip(every, quantized_every, xs))
        start = time.perf_counter()
        image, info = render_scene(scene, width=size, height=size, settings=settings, bundles=bundles,
                                   sdf_bundle=sdf_q)
        row["render_s"][p] = time.perf_counter() - start
        row["renderer"] = info.get("gl_renderer") or row.get("renderer")
        pictures[p] = srgb8(image[..., :3])
        row["render_psnr"][p] = psnr8(pictures[p], pictures["f32"])
        with tempfile.TemporaryDirectory() as tmp:
            row["page_bytes"][p] = _page_bytes(asset, bundles, sdf_q, Path(tmp))
        if p == "f16":
            row["arithmetic"] = measure_arithmetic(quantized_every, xs)
    reference = _reference_psnr(scene, settings, fp32, sdf, size)
    if reference is not None:
        row["reference_psnr"] = reference
    print(f"{asset.name}: " + ", ".join(f"{p} {row['bytes'][p]} B, {row['render_psnr'][p]:.1f} dB"
                                        for p in PRECISIONS[1:]), file=sys.stderr, flush=True)
    return row


def run(settings: Settings) -> int:
    """Measure each asset and write the report after each one (a run stopped half way keeps what it
    measured: compiles of minutes per precision add up on a software driver)."""
    from inshade.runtime.compute import compute_device
    from inshade.runtime.context import gl_info, shared_context

    report = {"benchmark": "precision", "machine": machine(gl_info(shared_context())), "size": settings.size,
              "precisions": list(PRECISIONS), "assets": [], "compute_device": compute_device().description}
    folders = asset_folders(settings.assets)
    for i, folder in enumerate(folders):
        row = measure_asset(folder, settings.size)
        if row is not None:
            report["assets"].append(row)
        report["measured"] = f"{i + 1} of {len(folders)} assets"
        write_report(settings.out, "precision", report, markdown, plot, echo=i + 1 == len(folders))
    return 0


def _db(v: float) -> str:
    return "identical" if v == float("inf") else f"{v:.1f}"


def markdown(r: dict) -> str:
    lines = ["# inshade bench precision", "", machine_markdown(r["machine"]), "",
             "Each shipped asset's networks with their dense weights at f16 and i8 and, at i8, their tables in "
             "8-bit codes (inshade/quantize.py), against "
             f"f32: bytes of everything the code binds with the weights in textures (dense share in brackets), "
             f"the twin's max error on {ROWS} random rows, and `inshade render` at {r['size']}^2 against the f32 "
             "render (PSNR of the 8-bit pictures; `identical`: not one 8-bit value moved)."
             + (f" Measured: {r['measured']}." if "measured" in r else ""), "",
             "| asset | f32 bytes | f16 bytes | i8 bytes | f16 twin error | i8 twin error | f16 render | i8 render | "
             "page f32 / f16 / i8 |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for a in r["assets"]:
        b, d, e, q = a["bytes"], a["dense_bytes"], a["twin_max_abs"], a["render_psnr"]
        lines.append(f"| {a['asset']} | {b['f32']} ({d['f32']}) | {b['f16']} ({d['f16']}) | {b['i8']} ({d['i8']}) | "
                     f"{e['f16']:.2g} | {e['i8']:.2g} | {_db(q['f16'])} dB | {_db(q['i8'])} dB | "
                     f"{' / '.join(str(a['page_bytes'].get(p, '-')) for p in PRECISIONS)} |")
    rows = r["assets"]
    if rows:
        worst16 = min(rows, key=lambda a: a["render_psnr"]["f16"])
        worst8 = min(rows, key=lambda a: a["render_psnr"]["i8"])
        lines += ["", f"Lowest: f16 {_db(worst16['render_psnr']['f16'])} dB ({worst16['asset']}), i8 "
                      f"{_db(worst8['render_psnr']['i8'])} dB ({worst8['asset']}) from the f32 render. Most "
                      "shipped tables are float16 or 8-bit already: f16 changes their dense weights only, i8 "
                      "their float16 tables too."]
    return "\n".join(lines + _reference_markdown(r) + _arithmetic_markdown(r)) + "\n"


def _reference_markdown(r: dict) -> list[str]:
    rows = [a for a in r["assets"] if "reference_psnr" in a]
    if not rows:
        return []
    lines = ["", "Against each asset's own reference (PSNR of the 8-bit pictures): the scene's reference image "
             "(rendered at its size), else the program's reference view (at the bench's size), and each "
             f"precision's change from f32 (goals: f16 within {F16_RENDER_DB} dB, i8 within {I8_RENDER_DB} dB):", "",
             "| asset | against | f32 | f16 (change) | i8 (change) |", "|---|---|---:|---:|---:|"]
    for a in rows:
        q = a["reference_psnr"]
        lines.append(f"| {a['asset']} | {q.get('against', 'image')} | {q['f32']:.2f} dB | {q['f16']:.2f} dB "
                     f"({q['f16'] - q['f32']:+.3f}) | {q['i8']:.2f} dB ({q['i8'] - q['f32']:+.3f}) |")
    for p, goal in (("f16", F16_RENDER_DB), ("i8", I8_RENDER_DB)):
        change = {a["asset"]: a["reference_psnr"][p] - a["reference_psnr"]["f32"] for a in rows}
        missed = [f"{name} ({v:+.3f})" for name, v in change.items() if v < -goal]
        lines += ["", f"{p}: {len(rows) - len(missed)} of {len(rows)} within {goal} dB"
                  + (": misses " + ", ".join(missed) if missed else ".")]
    return lines


def _arithmetic_markdown(r: dict) -> list[str]:
    rows = [a for a in r["assets"] if "arithmetic" in a]
    if not rows:
        return []
    lines = ["", f"fp16 arithmetic (f16 weights in textures, `--target {ARITHMETIC_TARGET} --arithmetic`) on "
             f"`{r.get('compute_device', '?')}`, a batch of {ROWS} rows per network (seconds: median of {REPEATS}); "
             "error: max |shader - twin| and the envelope's largest bound.", "",
             "| asset | f32 s | f16 s | f16_acc32 s | f16 error / bound | f16_acc32 error / bound |",
             "|---|---:|---:|---:|---:|---:|"]
    for a in rows:
        m = a["arithmetic"]
        if "skipped" in m:
            lines.append(f"| {a['asset']} | not run: {m['skipped'][:110]} | | | | |")
            continue
        lines.append(f"| {a['asset']} | {m['f32']['batch_s']:.4f} | {m['f16']['batch_s']:.4f} | "
                     f"{m['f16_acc32']['batch_s']:.4f} | {m['f16']['max_abs']:.2g} / {m['f16']['max_bound']:.2g} | "
                     f"{m['f16_acc32']['max_abs']:.2g} / {m['f16_acc32']['max_bound']:.2g} |")
    return lines


def plot(r: dict, path: Path) -> None:
    plt = matplotlib_pyplot()
    rows = r["assets"]
    fig, ax = plt.subplots(figsize=(7, max(2.5, 0.25 * len(rows))))
    y = np.arange(len(rows))
    for k, (p, colour) in enumerate((("f16", "tab:blue"), ("i8", "tab:orange"))):
        v = [min(a["render_psnr"][p], 100.0) for a in rows]
        ax.barh(y + 0.4 * k, v, height=0.4, color=colour, label=p)
    ax.set_yticks(y + 0.2, [a["asset"] for a in rows], fontsize=6)
    ax.set_xlabel("render PSNR against f32 (dB; 100 = identical)")
    ax.legend()
    ax.set_title(r["machine"]["gl_renderer"], fontsize=8)
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=120)
    plt.close(fig)


CLAIMS = {"f16_render": Claim("none (inshade's own bar)", "an asset's render at f16 dense weights against f32",
                              "within 0.1 dB (>= 50 dB from the f32 picture)", 50.0, higher_better=True)}


def headlines(r: dict) -> list[dict]:
    rows = r["assets"]
    if not rows:
        return []
    worst = min(rows, key=lambda a: a["render_psnr"]["f16"])
    v = min(worst["render_psnr"]["f16"], 999.0)
    return [claim_row(CLAIMS, "precision", "f16_render", f"lowest {_db(worst['render_psnr']['f16'])} dB "
                      f"({worst['asset']}) over {len(rows)} assets", v)]


BENCH = Bench("precision", __doc__, Settings, run, claims=CLAIMS, headlines=headlines,
              quick={"assets": ["trained/neural_image"], "size": 32},
              formatter=argparse.ArgumentDefaultsHelpFormatter, sizes={
    "cpu": sized(900, assets=("trained/neural_image", "trained/hash_grid_image", "trained/prt_mesh",
                              "trained/uvfree_material_fruit_balanced"), size=64),
    # a GPU compiles each precision's programs in a moment: three assets of different kinds at 256^2
    "device": sized(10, assets=("trained/neural_image", "trained/hash_grid_image", "trained/prt_mesh"), size=256),
})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite


if __name__ == "__main__":
    sys.exit(main())
