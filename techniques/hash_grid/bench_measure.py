"""What the hash_grid bench measures through the GL driver, for any of its networks: a scene's pass
drawn and timed (``ScenePass``), a network's cost per evaluation in passes/evaluate.frag
(``evaluation_cost``), the codegen plan's totals, an asset folder's bytes on disk, and how many
network evaluations a marched pixel makes (counted by the torch twins of the marches, step for
step the shaders').

Timing: the first draw of a program (where llvmpipe JIT-compiles it) is made at a small ``probe``
size and reported apart; then ``frames`` draws at each size, redrawn every time, on the harness
clock. A size whose frame the probe predicts (scaled by pixels) past ``max_frame_s`` is skipped and
the prediction recorded instead: a software renderer would spend minutes on one frame.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bench.harness import WallClock, measure, portable_command

BUNDLE_FILES = ("bundle.json", "weights.safetensors")


@dataclass(frozen=True)
class Timing:
    """How frames are timed: ``sizes`` (square sides), ``frames`` per size, the ``probe`` side of
    the first draw, the ``max_frame_s`` a predicted frame may take, the harness ``clock``."""
    sizes: tuple
    frames: int
    probe: int
    max_frame_s: float
    clock: object


def load_asset(folder: Path, kind: str):
    """(bundle, metrics.json, the trainer's Settings) of a hash_grid asset folder of ``kind``;
    BenchError naming the folder when it is not one."""
    import json

    from inshade.bench.harness import BenchError
    from inshade.bundle import load

    from .train import APPS, Settings

    folder = Path(folder)
    app = next(name for name, a in APPS.items() if a.folder == kind)
    hint = f"train it: inshade train hash_grid {app} --preset ship -o {folder}"
    for name in ("bundle.json", "metrics.json", "scene.json"):
        if not (folder / name).is_file():
            raise BenchError(f"{folder}: no {name} ({hint})")
    bundle = load(folder)
    if bundle.kind != kind:
        raise BenchError(f"{folder / 'bundle.json'}: kind: {bundle.kind!r}, expected {kind!r}")
    metrics = json.loads((folder / "metrics.json").read_text())
    return bundle, metrics, Settings(**metrics["settings"])


def asset_record(bundle, metrics: dict) -> dict:
    """Which training run an asset is: its command, preset and date (the bundle's provenance)."""
    prov = bundle.meta.get("provenance", {})
    return {"command": portable_command(metrics.get("command")), "preset": metrics.get("preset"),
            "date_utc": prov.get("date_utc"), "train_seconds": metrics.get("train_seconds")}


def plan_summary(plan) -> dict:
    """The plan's totals per evaluation and where each node's weights live."""
    t = plan.totals()
    storage = sorted({r.storage for r in plan.rows if r.storage != "-"})
    return {"network": plan.network, "params": int(t["params"]), "flops": int(t["flops"]),
            "fetches": int(t["fetches"]), "texture_bytes": int(t["texture_bytes"]),
            "uniform_bytes": int(t["uniform_bytes"]), "storage": storage}


def folder_bytes(folder: Path, subfolders=()) -> int:
    """bundle.json + weights.safetensors of the folder (and of each subfolder's bundle)."""
    folder = Path(folder)
    return sum((d / name).stat().st_size for d in (folder, *(folder / s for s in subfolders)) for name in BUNDLE_FILES)


def _ms(t) -> dict:
    return {"ms_median": round(1e3 * t.median, 3), "ms_min": round(1e3 * t.min, 3), "ms_max": round(1e3 * t.max, 3),
            "frames": len(t.samples), "clock": t.clock}


class ScenePass:
    """One scene's pass on the runtime's SceneRenderer: compiled once, drawn at any size; call
    ``release()`` when done."""

    def __init__(self, ctx, scene, timing: Timing, settings: dict | None = None):
        from inshade.runtime.renderer import SceneRenderer

        self.ctx, self.timing = ctx, timing
        self.camera = scene.make_camera()
        self.renderer = SceneRenderer(scene, ctx, settings=settings)
        self.compile_s = round(self.renderer.compile_seconds, 3)
        probe = timing.probe
        self.first_draw_s = round(WallClock(ctx.finish).time(lambda: self.draw(probe)), 3)
        self.probe_s = measure(lambda: self.draw(probe, force=True), repeats=1, warmup=0, clock=timing.clock).median

    def draw(self, size: int, camera=None, force: bool = False):
        return self.renderer.render_network(camera or self.camera, size, size, force=force)

    def image(self, size: int, camera=None) -> np.ndarray:
        """Linear RGBA [size, size, 4], image orientation."""
        self.draw(size, camera, force=True)
        return self.renderer.read("network")

    def plans(self) -> list:
        return [g.plan for g in self.renderer.generated]

    def frames(self) -> dict:
        """{side: ms per frame (median, min, max of the timed draws) or the skipped prediction}."""
        out = {}
        for size in self.timing.sizes:
            predicted = self.probe_s * (size / self.timing.probe) ** 2
            if predicted > self.timing.max_frame_s:
                out[str(size)] = {"skipped": f"predicted {predicted:.0f} s a frame from the {self.timing.probe}² draw "
                                             f"(limit {self.timing.max_frame_s:g} s)", "predicted_ms": round(1e3 * predicted, 1)}
                continue
            t = measure(lambda: self.draw(size, force=True), repeats=self.timing.frames, warmup=0,
                        clock=self.timing.clock)
            out[str(size)] = _ms(t)
        return out

    def release(self) -> None:
        self.renderer.release()
        self.renderer.cache.release()


def evaluation_cost(ctx, bundle, inputs: np.ndarray, timing: Timing) -> dict:
    """ns per evaluation of ``bundle``'s generated function in passes/evaluate.frag over ``inputs``
    [N, in_dim] (one per pixel), the median of ``timing.frames`` draws after a first one (the JIT),
    and its plan per evaluation."""
    from inshade.codegen import generate
    from inshade.runtime.context import gl_info
    from inshade.runtime.network import NetworkEvaluator

    gen = generate(bundle, limits=gl_info(ctx))
    ev = NetworkEvaluator(ctx, gen, width=256)
    draw = ev.prepare(inputs)
    try:
        first = WallClock(ctx.finish).time(draw)
        t = measure(draw, repeats=timing.frames, warmup=0, clock=timing.clock)
    finally:
        draw.release()
        ev.release()
        ev.cache.release()
    n = len(inputs)
    return {"points": n, "ns_per_evaluation": round(1e9 * t.median / n, 2), "first_draw_s": round(first, 3),
            "draws": len(t.samples), "clock": t.clock, "plan": plan_summary(gen.plan)}


def lattice(n_side: int, dims: int, lo: float, hi: float) -> np.ndarray:
    """[n_side^dims, dims] points of a regular lattice over [lo, hi]^dims, x fastest (neighbouring
    evaluations near each other, as a ray's samples are)."""
    axis = np.linspace(lo, hi, n_side, dtype=np.float32)
    grids = np.meshgrid(*([axis] * dims), indexing="ij")
    return np.stack([g.reshape(-1) for g in reversed(grids)], -1).astype(np.float32)


# --- evaluations per marched pixel (torch twins) ---------------------------------------------------

class _Counting:
    """An SDF module that counts the points it is evaluated at (models/sdf.py trace calls it)."""

    def __init__(self, module):
        self.module, self.scene, self.count = module, module.scene, 0

    def __call__(self, p):
        self.count += len(p)
        return self.module(p)


def sdf_evaluations(module, camera, size: int) -> dict:
    """Mean scene_sdf evaluations per pixel of the sdf_diffuse pass from ``camera`` at ``size``²:
    the trace's (models/sdf.py trace, lib/sdf's twin) plus 6 for the normal of every hit."""
    from inshade.models.sdf import camera_rays, trace

    ro, rd = camera_rays(camera.uniforms(size, size), size, size)
    counting = _Counting(module)
    hit, _ = trace(counting, ro, rd)
    pixels = size * size
    hits = int(hit.sum())
    return {"per_pixel": round((counting.count + 6 * hits) / pixels, 3), "trace_per_pixel": round(counting.count / pixels, 3),
            "hit_fraction": round(hits / pixels, 4), "counted_at": size}


def march_evaluations(graph, occupancy, march_settings, camera, size: int) -> dict:
    """Mean field evaluations per pixel of the radiance-field march from ``camera`` at ``size``²
    (radiance_field_march.render, the shader's twin, with the occupancy grid)."""
    from .radiance_field_march import graph_field, render

    _, evals = render(graph_field(graph), occupancy, camera.uniforms(size, size), size, size, march_settings)
    return {"per_pixel": round(float(evals.mean()), 3), "max": int(evals.max()), "counted_at": size}
