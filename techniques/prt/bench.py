"""`inshade bench prt`: learnt-transfer PRT (Dhawal et al. 2022) frame times through the GL driver.

For each PRT scene (the shipped ``trained/prt_*`` assets: analytic and neural SDFs, sphere traced
in the fragment shader), each transfer width k, each shading mode (diffuse, glossy) and each
size, the scene's pass is drawn by the same ``SceneRenderer`` that ``inshade render`` uses:

- the first draw is timed alone (llvmpipe JIT-compiles the fragment shader there);
- then ``--repeats`` forced redraws, each timed by ``--clock`` (``inshade.bench.harness``: a GL
  timer query on a hardware driver, redraw + ``glFinish`` wall time on llvmpipe); the median is
  the frame time, min and max are kept.

Widths the asset ships (k=64, and k=128 where present) use its trained bundle; other widths
(256, 512: the sizes where the paper's GLSL path failed to compile) use an untrained network of
the same shape, which costs the same per pixel (the number of sphere-tracing steps depends on
the geometry, not on the transfer weights). Storage is codegen's ``auto`` choice for the live
renderer (inline literals for small nets, textures for wide ones on software renderers).

Also measured side by side in the same run: the torch reference renderer of the same pass on
the same view (ours vs torch), and the ground-truth transfer generator's throughput (visibility
rays per second; SDF: batched sphere tracing in torch; mesh: trimesh + embree).

Writes ``prt.json``, ``prt.md`` and ``prt.png`` into ``--out``. ``--quick``: one asset, k=64 and
16, 64x64, diffuse only (for tests / smoke runs).
``--sizes`` says which frame sizes each width k is drawn at.
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from inshade.bench.contract import Bench, clock_option, option, sized
from inshade.bench.entry import Claim, claim_row
from inshade.bench.harness import (BenchError, WallClock, clock_for, clock_record, label_axes, machine,
                                   machine_markdown, matplotlib_pyplot, measure, write_report)
from inshade.techniques.prt.codegen import KINDS

DEFAULT_OUT = "bench-out/prt"
DEFAULT_ASSETS = "trained/prt_creature,trained/prt_mechanical,trained/prt_neural_bunny,trained/prt_mesh"
PAPER_RTX3090_FPS_1024 = (173.6, 320.1)   # Table 2, k=64, analytic SDFs


def _size_plan(text: str) -> dict[int, list[int]]:
    """'64:512,1024;128:512' -> {64: [512, 1024], 128: [512]}."""
    try:
        plan = {}
        for part in filter(None, (p.strip() for p in text.split(";"))):
            k, sizes = part.split(":")
            plan[int(k)] = [int(v) for v in sizes.split(",") if v.strip()]
        return plan
    except ValueError:
        raise BenchError(f"--sizes: expected 'k:size,size;k:size', got {text!r}") from None


@dataclass
class Settings:
    out: str = option(DEFAULT_OUT, f"output folder (default {DEFAULT_OUT})")
    assets: str = option(DEFAULT_ASSETS, "PRT scene folders, comma-separated")
    sizes: str = option("64:512,1024;128:512,1024;256:256;512:256", "square frame sizes per transfer width k, "
                        "'k:s,s;k:s' (default %(default)s: the wide nets need seconds to minutes per frame on llvmpipe)")
    shading: str = option("diffuse,glossy", "shading modes (default %(default)s)")
    storage: str = option("auto", "weight storage of the networks (default %(default)s: codegen's choice for this "
                                  "renderer)", choices=("auto", "inline", "ubo", "texture"))
    repeats: int = option(3, "timed redraws per configuration (median)")
    torch_size: int = option(128, "frame size of the ours-vs-torch comparison")
    rays: int = option(2000, "surface points for the rays/s measurement")
    mesh: str = option("trained/prt_mesh/mesh.ply", "mesh for the embree rays/s measurement")
    quick: bool = option(False, "tiny run for tests")
    clock: str = clock_option()


# ---------------------------------------------------------------------------------------------
def _transfer_index(scene, bundles) -> int:
    for i, b in enumerate(bundles):
        if b.kind in KINDS:
            return i
    raise BenchError(f"{scene.source}: no transfer network (not a PRT scene)")


def _width_of(bundle) -> int:
    return max(n.out_dim for n in bundle.nodes if n.type == "dense" and n.id != _last_dense(bundle))


def _last_dense(bundle) -> str:
    return [n.id for n in bundle.nodes if n.type == "dense"][-1]


def _bundle_of_width(trained, width: int, seed: int = 0):
    """The trained bundle when it has this width, else an untrained one of the same design."""
    import torch

    from inshade.techniques.prt.transfer_model import TransferFrame, transfer_graph

    if _width_of(trained) == width:
        return trained, "trained"
    params = {n.id: n.params for n in trained.nodes}
    layers = sum(1 for n in trained.nodes if n.type == "dense") - 1
    out_act = "tanh" if any(n.type == "tanh" for n in trained.nodes) else "identity"
    torch.manual_seed(seed + width)
    g = transfer_graph(width=width, layers=layers, pos_freqs=params["enc_p"]["n_freqs"],
                       normal_freqs=params["enc_n"]["n_freqs"], output=out_act)
    frame = TransferFrame.from_bundle(trained)
    return g.export("transfer", name=f"untrained_k{width}", render={"transfer": frame.to_dict()}), "untrained"


def _time_frames(renderer, camera, size: int, repeats: int, clock) -> dict:
    def redraw():
        renderer.weights_version += 1          # forces the pass to redraw
        renderer.render_network(camera, size, size)

    first = WallClock(renderer.ctx.finish).time(redraw)   # llvmpipe JIT-compiles here
    t = measure(redraw, repeats=repeats, warmup=0, clock=clock)
    return {"first_draw_s": first, "seconds": t.median, "min_s": t.min, "max_s": t.max, "all_s": t.samples,
            "clock": t.clock, "fps": 1.0 / t.median}


def _storages(renderer) -> str:
    kinds = set()
    for g in renderer.generated:
        kinds |= {r.storage for r in g.plan.rows if r.type == "dense"}
    return "+".join(sorted(kinds))


def _sdf_module(scene):
    """The torch SDF module of a PRT scene's geometry (analytic description or network bundle)."""
    from inshade.bundle import load
    from inshade.techniques.prt import twin as prt
    from inshade.scene.description import NetworkSdfRef

    if isinstance(scene.sdf, NetworkSdfRef):
        from inshade.models.network_sdf import NetworkSdfModule
        return NetworkSdfModule.from_bundle(load(scene.sdf.bundle))
    return prt.sdf_module(scene.sdf)


def _geometry(scene) -> str:
    from inshade.scene.description import NetworkSdfRef
    if scene.sdf is None:
        return "mesh (rasterised)"
    return "neural SDF" if isinstance(scene.sdf, NetworkSdfRef) else "analytic SDF"


def _sdf_assets(paths: list[str]) -> list[str]:
    from inshade.scene.description import load_scene
    return [p for p in paths if load_scene(p).sdf is not None]


def bench_asset(path: str, args, ctx, cache, clock) -> list[dict]:
    from inshade.bundle import load
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(path)
    trained = [load(n.bundle) for n in scene.networks]
    ti = _transfer_index(scene, trained)
    camera = scene.make_camera()
    rows = []
    for width, sizes in args.size_plan.items():
        bundle, origin = _bundle_of_width(trained[ti], width)
        bundles = list(trained)
        bundles[ti] = bundle
        for shading in args.shading_list:
            renderer = SceneRenderer(scene, ctx, cache=cache, settings={"shading": shading, "storage": args.storage},
                                     bundles=bundles)
            try:
                for size in sizes:
                    t = _time_frames(renderer, camera, size, args.repeats, clock)
                    rows.append({"asset": scene.name, "geometry": _geometry(scene), "k": width, "weights": origin,
                                 "shading": shading, "size": size, "storage": _storages(renderer),
                                 "compile_link_s": renderer.compile_seconds, **t})
                    print(f"{scene.name} k={width} {shading} {size}²: {t['seconds'] * 1e3:.1f} ms "
                          f"(first draw {t['first_draw_s']:.1f} s)", file=sys.stderr)
            finally:
                renderer.release()
    return rows


def torch_comparison(path: str, args, ctx, cache) -> dict:
    """Same view, same size, k as shipped, diffuse: GL pass vs the torch reference renderer (both
    wall clock: the GL frame as redraw + glFinish)."""
    import torch

    from inshade.techniques.prt import twin as prt
    from inshade.models.graph import GraphModule
    from inshade.techniques.prt.transfer_model import TransferFrame
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(path)
    size = args.torch_size
    camera = scene.make_camera()
    renderer = SceneRenderer(scene, ctx, cache=cache, settings={"shading": "diffuse"})
    try:
        gl = _time_frames(renderer, camera, size, args.repeats, WallClock(ctx.finish))
        bundles = renderer.bundles
        ti = _transfer_index(scene, bundles)
        net = GraphModule.from_bundle(bundles[ti]).eval()
        frame = TransferFrame.from_bundle(bundles[ti])
        sdf = _sdf_module(scene)
        sh = renderer.environment_sh()
        shading = prt.PrtShading.from_settings(renderer.values, scene)
        uniforms = camera.uniforms(size, size)
        torch.set_num_threads(os.cpu_count() or 1)
        with torch.inference_mode():
            start = time.perf_counter()
            prt.render(sdf, net, frame, uniforms, size, size, sh, shading)
            torch_s = time.perf_counter() - start
    finally:
        renderer.release()
    return {"asset": scene.name, "size": size, "k": _width_of(bundles[ti]), "shading": "diffuse",
            "torch_threads": torch.get_num_threads(),
            "gl_seconds": gl["seconds"], "torch_seconds": torch_s, "speedup": torch_s / gl["seconds"]}


def _timed_rays(geometry: str, backend: str, p, n, transfer_fn, dirs: int = 256) -> dict:
    """One rays/s record: ``transfer_fn(dirs)`` over the surface points ``p`` timed once."""
    start = time.perf_counter()
    transfer_fn(dirs)
    secs = time.perf_counter() - start
    return {"geometry": geometry, "backend": backend, "points": int(p.shape[0]), "dirs": dirs, "seconds": secs,
            "rays_per_second": p.shape[0] * dirs / secs}


def rays_per_second(args) -> list[dict]:
    """Ground-truth transfer throughput: visibility rays per second on this CPU, with one torch
    thread (what ``inshade train prt`` uses: on 2 shared cores two threads ran ~10x slower)."""
    import torch

    from inshade.techniques.prt import transfer, transfer_surface
    from inshade.scene.description import load_scene

    torch.set_num_threads(1)

    out = []
    for path in _sdf_assets(args.asset_list):
        scene = load_scene(path)
        sdf = _sdf_module(scene)
        p, n = transfer_surface.sample_sdf_surface(sdf, args.rays, seed=0)
        out.append(_timed_rays(scene.name, "torch sphere tracing", p, n,
                               lambda dirs: transfer.sdf_transfer(sdf, p, n, n_dirs=dirs, seed=0)))
    mesh_path = Path(args.mesh)
    if mesh_path.is_file():
        import trimesh

        from inshade.geometry.mesh import load_mesh
        mesh = load_mesh(mesh_path)
        p, n = transfer_surface.sample_mesh_surface(mesh, args.rays, seed=0)
        backend = "trimesh + embree" if trimesh.ray.has_embree else "trimesh (no embree)"
        out.append(_timed_rays(mesh_path.parent.name, backend, p, n,
                               lambda dirs: transfer.mesh_transfer(mesh, p, n, n_dirs=dirs, seed=0)))
    return out


def run(args) -> int:
    from inshade.runtime.context import gl_info, shared_context
    from inshade.runtime.programs import ProgramCache

    if args.quick:
        args.assets = args.assets.split(",")[0]
    args.asset_list = [a.strip() for a in args.assets.split(",") if a.strip()]
    args.size_plan = _size_plan(args.sizes)
    args.shading_list = [s.strip() for s in args.shading.split(",") if s.strip()]
    missing = [a for a in args.asset_list if not Path(a).is_dir()]
    if missing:
        raise BenchError(f"no such asset folder: {', '.join(missing)}")
    ctx = shared_context()
    info = gl_info(ctx)
    clock = clock_for(ctx, args.clock, software=info["software"])
    cache = ProgramCache(ctx)
    result = {
        "benchmark": "prt", "quick": bool(args.quick),
        "machine": machine(info), **clock_record(clock),
        "method": f"median of --repeats forced redraws ({clock.note}), after a timed first draw (JIT)",
        "paper_rtx3090_fps_1024_k64": list(PAPER_RTX3090_FPS_1024),
        "frames": [], "torch": [], "rays": [],
    }
    for path in args.asset_list:
        result["frames"] += bench_asset(path, args, ctx, cache, clock)
    sdf_assets = _sdf_assets(args.asset_list)
    if sdf_assets:
        result["torch"].append(torch_comparison(sdf_assets[0], args, ctx, cache))
    result["rays"] = rays_per_second(args)
    cache.release()
    out = Path(args.out)
    write_report(out, "prt", result, markdown, plot)
    print(f"wrote {out / 'prt.json'}, {out / 'prt.md'}, {out / 'prt.png'}", file=sys.stderr)
    return 0


def markdown(result: dict) -> str:
    m = result["machine"]
    lines = ["# PRT with a learnt transfer network: frame times", "",
             machine_markdown(m),
             f"- {result['method']}; paper (RTX 3090, 1024², k=64): "
             f"{result['paper_rtx3090_fps_1024_k64'][0]}–{result['paper_rtx3090_fps_1024_k64'][1]} FPS", "",
             "| asset | geometry | k | weights | shading | size | storage | ms/frame | min–max ms | FPS "
             "| first draw s |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in result["frames"]:
        lines.append(f"| {r['asset']} | {r['geometry']} | {r['k']} | {r['weights']} | {r['shading']} | "
                     f"{r['size']}² | {r['storage']} | {r['seconds'] * 1e3:.1f} | "
                     f"{r['min_s'] * 1e3:.1f}–{r['max_s'] * 1e3:.1f} | {r['fps']:.2f} | {r['first_draw_s']:.1f} |")
    lines += ["", "## Ours (GLSL) vs the torch reference renderer, same view", "",
              "| asset | size | k | GL s | torch s | GL speed-up |", "|---|---|---|---|---|---|"]
    for r in result["torch"]:
        lines.append(f"| {r['asset']} | {r['size']}² | {r['k']} | {r['gl_seconds']:.3f} | "
                     f"{r['torch_seconds']:.3f} | {r['speedup']:.1f}× |")
    lines += ["", "## Ground-truth transfer generation throughput", "",
              "| geometry | backend | points | dirs | seconds | rays/s |", "|---|---|---|---|---|---|"]
    for r in result["rays"]:
        lines.append(f"| {r['geometry']} | {r['backend']} | {r['points']} | {r['dirs']} | {r['seconds']:.2f} | "
                     f"{r['rays_per_second'] / 1e6:.2f} M |")
    return "\n".join(lines) + "\n"


def plot(result: dict, path: Path) -> None:
    plt = matplotlib_pyplot()

    fig, ax = plt.subplots(figsize=(7, 4.5))
    series = {}
    for r in result["frames"]:
        series.setdefault((r["asset"], r["shading"], r["size"]), []).append((r["k"], r["seconds"] * 1e3))
    for (asset, shading, size), pts in sorted(series.items()):
        pts.sort()
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "-o" if shading == "diffuse" else "--s",
                label=f"{asset} {shading} {size}²")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    label_axes(ax, "transfer network width k", "ms / frame")
    ax.set_title(f"PRT frame time — {result['machine']['gl_renderer']}", fontsize=9)
    ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper

CLAIMS = {
    "fps": Claim("Learnt Transfer (Dhawal et al. 2022), Table 2", "k=64 transfer net on an analytic SDF, "
                 "FPS at 1024² (ours scaled by pixel count)", "173.6-320.1 FPS on an RTX 3090", 173.6),
    "torch": Claim("Learnt Transfer, Table 4", "GLSL vs the torch/CUDA path, k=64 (speed-up)",
                   "GLSL 64.4 vs CUDA 55.1 FPS: 1.17x", 64.4 / 55.1),
}


def headlines(r: dict) -> list[dict]:
    rows = []
    sdf = [f for f in r["frames"] if f["k"] == 64 and f["geometry"] == "analytic SDF"]
    for shading in sorted({f["shading"] for f in sdf}):
        f = max((f for f in sdf if f["shading"] == shading), key=lambda f: f["size"])
        fps_1024 = f["fps"] * (f["size"] / 1024) ** 2
        scaled = f" ({fps_1024:.1f} at 1024²)" if f["size"] != 1024 else ""
        rows.append(claim_row(CLAIMS, "prt", "fps", f"{f['fps']:.1f} FPS at {f['size']}²{scaled}, {f['asset']}",
                              fps_1024, shading))
    for t in r["torch"]:
        rows.append(claim_row(CLAIMS, "prt", "torch", f"{t['speedup']:.1f}x at {t['size']}² ({t['asset']}, torch on "
                                                      f"{t['torch_threads']} CPU threads)", t["speedup"], t["shading"]))
    return rows


BENCH = Bench("prt", __doc__, Settings, run, claims=CLAIMS, headlines=headlines,
              quick={"sizes": "16:64;64:64", "shading": "diffuse", "repeats": 1, "torch_size": 32, "rays": 64},
              sizes={"cpu": sized(60, assets="trained/prt_creature,trained/prt_mesh", sizes="64:512", repeats=3, rays=500),
                     "device": sized(75, sizes="64:512,1024;128:1024;256:512", repeats=10, torch_size=256)})
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite
