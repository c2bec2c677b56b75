"""8-bit feature tables for a trained UV-free material, without retraining (post-training
quantisation) or with a short quantisation-aware fine-tune.

Command: ``python -m inshade.techniques.uvfree_material.quantize ASSET --out DIR [--steps N]
[--lr LR] [--mlp-lr LR] [--batch N] [--seed S] [--force] [--preview]``.

- ASSET: a uvfree_material asset folder (``material/`` + ``mesh.obj`` + the three reference
  textures, what ``inshade train uvfree_material`` writes). Its fp16 feature table is stored as
  precision ``u8`` (models/mesh_features.py): per feature lane c, value = offset[c] + scale[c] *
  q / 255, the range the table's per-lane min/max.
- ``--steps 0`` (default): post-training quantisation only. ``--steps N``: then N steps of the
  trainer's fit (train.py ``fit``: Adam, MSE on fresh area-weighted points, cosine decay) with the
  table fake-quantised in forward (straight-through: the gradient passes the rounding), the lane
  range fixed at the calibrated one (values outside are clamped); the exported codes are what the
  fit trained on. Fine-tuning learning rates default to a tenth of the trainer's.
- DIR (required; never the source): the asset folder with the u8 bundle, the source's mesh,
  textures and scene.json, and ``metrics.json`` (source, torch quality of the source and of the
  quantised material on the same points, memory as the GPU holds it, the fit's loss history).
"""
from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

import numpy as np
import torch

from inshade import command
from inshade.bundle import BundleError, load
from inshade.components import ComponentError
from inshade.files import atomic_write
from inshade.geometry.mesh import load_mesh
from inshade.models import GraphModule

from . import objects
from .memory import memory_report
from .model import KIND
from .fitting import BUNDLE, SurfaceSampler, TrainError, fit
from .train import Settings, evaluate, stored_textures, targets

COPIED = (objects.FILES["mesh"], *(objects.FILES[k] for k in objects.TEXTURES), "scene.json")


def quantize_asset(src, out, *, steps: int = 0, lr: float = 1e-3, mlp_lr: float = 5e-4, batch: int = 1 << 14,
                   seed: int = 0, force: bool = False, preview: bool = False, progress=None,
                   command_line: str | None = None) -> dict:
    """Write ``out``: the asset ``src`` with its feature table in precision u8 (fine-tuned for
    ``steps`` steps when > 0); returns the metrics written to ``out/metrics.json``."""
    src, out = Path(src), Path(out)
    if not (src / BUNDLE).is_dir():
        raise TrainError(f"{src}: not a {KIND} asset folder (no {BUNDLE}/)")
    if out.resolve() == src.resolve():
        raise TrainError("--out: must differ from the source asset")
    if out.exists() and any(out.iterdir()) and not force:
        raise TrainError(f"--out: {out} exists and is not empty (--force overwrites)")
    if steps < 0 or batch < 1:
        raise TrainError(f"--steps >= 0 and --batch >= 1, got {steps}, {batch}")
    started = time.perf_counter()
    bundle = load(src / BUNDLE)
    if bundle.kind != KIND:
        raise TrainError(f"{src / BUNDLE}: a {bundle.kind} bundle, not {KIND}")
    out.mkdir(parents=True, exist_ok=True)
    for name in COPIED:     # written atomically, like every file of an asset
        atomic_write(out / name, (src / name).read_bytes())
    mesh, textures = load_mesh(out / objects.FILES["mesh"]), stored_textures(out)
    sampler = SurfaceSampler(mesh)
    graph = GraphModule.from_bundle(bundle)
    features = graph.nodes["features"]
    source_quality = evaluate(graph, sampler, textures, 1 << 16, seed, "cpu")
    source_precision = features.precision
    features.precision = "u8"
    features.calibrate()
    ptq_quality = evaluate(graph, sampler, textures, 1 << 16, seed, "cpu")
    history = []
    if steps:
        s = Settings(steps=steps, batch=batch, lr=lr, mlp_lr=mlp_lr, seed=seed)

        def draw(rng):
            face, t0, t1, uv = sampler(s.batch, rng)
            return np.stack([face.astype(np.float32), t0, t1], 1), targets(textures, uv)

        history = fit(graph, draw, s, "cpu", f"{KIND} u8 fine-tune", progress)
    quality = evaluate(graph, sampler, textures, 1 << 16, seed, "cpu")
    record = {"source": str(src), "source_precision": source_precision, "precision": "u8", "steps": steps,
              "command": command_line or shlex.join(["python", "-m", "inshade.techniques.uvfree_material.quantize",
                                                     str(src), "--out", str(out), "--steps", str(steps)])}
    if steps:
        record.update(lr=lr, mlp_lr=mlp_lr, batch=batch, seed=seed)
    provenance = {**bundle.meta.get("provenance", {}), "quantized": record}
    exported = graph.export(KIND, bundle.name, provenance=provenance, metrics=quality)
    exported.save(out / BUNDLE)
    tex_res = textures["albedo"].shape[0]
    metrics = {**record, "seconds": round(time.perf_counter() - started, 1), "torch_threads": torch.get_num_threads(),
               "torch_quality_source": source_quality, "torch_quality_ptq": ptq_quality, "torch_quality": quality,
               "memory": memory_report(exported, tex_res),
               "memory_source": memory_report(bundle, tex_res), "history": history}
    atomic_write(out / "metrics.json", json.dumps(metrics, indent=2) + "\n")
    if preview:
        from .train import render_preview

        render_preview(out)
    return metrics


def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    p.add_argument("asset", help=f"a {KIND} asset folder (e.g. trained/{KIND}_fruit_balanced)")
    p.add_argument("--out", required=True, help="output asset folder (not the source)")
    p.add_argument("--steps", type=int, default=0, help="quantisation-aware fine-tuning steps (default 0: "
                   "post-training quantisation only)")
    p.add_argument("--lr", type=float, default=1e-3,
                   help="fine-tuning feature-table learning rate (default %(default)s)")
    p.add_argument("--mlp-lr", type=float, default=5e-4, help="fine-tuning MLP learning rate (default %(default)s)")
    p.add_argument("--batch", type=int, default=1 << 14, help="surface points per step (default %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default %(default)s)")
    p.add_argument("--force", action="store_true", help="overwrite a non-empty --out")
    p.add_argument("--preview", action="store_true", help="render preview.png")
    return p


def run(args: argparse.Namespace, argv: list[str]) -> int:
    m = quantize_asset(args.asset, args.out, steps=args.steps, lr=args.lr, mlp_lr=args.mlp_lr, batch=args.batch,
                       seed=args.seed, force=args.force, preview=args.preview,
                       command_line=shlex.join(["python", "-m", "inshade.techniques.uvfree_material.quantize", *argv]))
    q0, q1, mem = m["torch_quality_source"], m["torch_quality"], m["memory"]
    print(f"wrote {args.out}: albedo {q0['psnr_albedo']:.2f} -> {q1['psnr_albedo']:.2f} dB, normal "
          f"{q0['normal_mean_deg']:.2f} -> {q1['normal_mean_deg']:.2f} deg; features + MLP "
          f"{m['memory_source']['neural_bytes']} -> {mem['neural_bytes']} B ({mem['rate_features_mlp']:.1%}); "
          f"{m['seconds']:.0f} s")
    return 0


def main(argv=None) -> int:
    return command.main("python -m inshade.techniques.uvfree_material.quantize", __doc__, add_arguments, run, argv,
                        errors=(TrainError, BundleError, ComponentError, OSError))


if __name__ == "__main__":
    sys.exit(main())
