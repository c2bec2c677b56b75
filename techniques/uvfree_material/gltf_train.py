"""A UV-free material learnt from a glTF file (``inshade train uvfree_material --gltf FILE``).

- Mesh: the file's own (geometry/gltf.py: every triangle the default scene draws, in world space),
  read back from the copy in the asset folder, so face ids are the faces the scene draws; the
  hierarchy welds it by position as for any mesh (model.py material_graph).
- Targets: at each training point (area-weighted, fresh every step: train.py SurfaceSampler), the
  material of its face sampled at its interpolated uv (geometry/gltf_sample.py
  ``material_channels``: texture transform, wrap, factors, colour decode), stored as
  gltf_channels.py says. A file with several materials is one decoder over all faces, each point
  learning its own material's values.
- Sizes: the hierarchy's levels from the texels the surface carries (gltf_source.py
  ``surface_texels``), the hash table from ``--config``'s share of the file's textures uncompressed
  (RGBA8, what the renderer uploads), as model.py does for the uv textures.
- Metrics: per-channel PSNR of the decoded channels against the targets at fresh points (as
  stored), the mean normal angle, the render PSNR of the network against the file's material at
  the scene's camera (GL, gltf_scene.py), and the bytes of features + MLP against the file's
  texture bytes (uncompressed, and as the file stores them).

Asset folder: ``source.glb`` (the file, byte-identical; a .gltf keeps its files beside it),
``material/`` (bundle kind ``uvfree_material_gltf``; ``render.channels`` names its lanes),
``scene.json``, ``metrics.json``, ``preview.png``.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import torch

from inshade.files import atomic_write
from inshade.geometry.gltf import copy_gltf
from inshade.geometry.gltf_sample import material_channels
from inshade.geometry.mesh_topology import mesh_topology
from inshade.metrics import psnr
from inshade.trainer import Run
from inshade.provenance import recorded_at

from . import KIND_GLTF, gltf_channels, gltf_scene, gltf_source
from .memory import network_bytes
from .model import CONFIGS, choose_levels, choose_table_size, material_graph
from .fitting import BUNDLE, SurfaceSampler, fit, render_preview


class GltfTargets:
    """The stored channel values (gltf_channels.py) at points (face, project uv) of a glTF asset."""

    def __init__(self, asset):
        self.asset = asset
        self.channels = gltf_channels.channels_of(asset)
        self.scale = gltf_channels.emissive_scale(asset)
        self.width = gltf_channels.width(self.channels)

    def __call__(self, face: np.ndarray, uv: np.ndarray) -> np.ndarray:
        material = self.asset.face_material[face]
        out = np.empty((len(face), self.width), np.float32)
        for m in np.unique(material):
            sel = material == m
            out[sel] = gltf_channels.encode(material_channels(self.asset, int(m), uv[sel]), self.channels, self.scale)
        return out


def evaluate(graph, sampler, targets: GltfTargets, n: int, seed: int) -> dict:
    """PSNR per channel (stored values) and the mean normal angle at fresh area-weighted points."""
    rng = np.random.default_rng(seed + 7_777_777)
    face, t0, t1, uv = sampler(n, rng)
    want = targets(face, uv)
    with torch.no_grad():
        got = graph(torch.from_numpy(np.stack([face.astype(np.float32), t0, t1], 1))).numpy()
    lanes = gltf_channels.lanes(targets.channels)
    out = {f"psnr_{c}": round(psnr(got[:, a:a + w], want[:, a:a + w]), 3) for c, (a, w) in lanes.items()}
    if "normal" in lanes:
        a = lanes["normal"][0]
        n_got, n_want = (v[:, a:a + 3].astype(np.float64) * 2 - 1 for v in (got, want))
        cos = (n_got * n_want).sum(1) / np.maximum(np.linalg.norm(n_got, axis=1) * np.linalg.norm(n_want, axis=1),
                                                   1e-12)
        out["normal_mean_deg"] = round(float(np.degrees(np.arccos(np.clip(cos, -1, 1))).mean()), 3)
    return out


def memory(bundle, asset, path) -> dict:
    feats, mlp, topo = network_bytes(bundle)
    tex = gltf_source.texture_bytes(asset)
    stored = gltf_source.file_image_bytes(path)
    rate = lambda b, ref: round(b / ref, 4) if ref else None  # noqa: E731
    return {"features_bytes": feats, "mlp_bytes": mlp, "topology_bytes": topo, "neural_bytes": feats + mlp,
            "neural_bytes_all": feats + mlp + topo, "texture_bytes": tex, "texture_bytes_file": stored,
            "textures": len(gltf_source.used_images(asset)), "rate_features_mlp": rate(feats + mlp, tex),
            "rate_all": rate(feats + mlp + topo, tex), "rate_file": rate(feats + mlp, stored)}


def write_gltf_material(run: Run, progress=None) -> dict:
    """Train on ``run.args.gltf`` with ``run.settings`` and write the asset folder ``run.out``
    (metrics.json through the run, preview.png unless --no-preview); returns the metrics."""
    s, args, device, out = run.settings, run.args, run.device, run.out
    hidden = tuple(s.hidden)
    started = time.perf_counter()
    gltf_source.read(args.gltf)             # refused before anything is written
    out.mkdir(parents=True, exist_ok=True)
    mesh_name = copy_gltf(args.gltf, out, gltf_source.SOURCE)
    asset = gltf_source.read(out / mesh_name)   # as the scene reads it: its faces are the ids trained
    mesh, faces = asset.mesh, np.asarray(asset.mesh.faces)
    targets = GltfTargets(asset)
    tex_bytes = gltf_source.texture_bytes(asset)
    levels = args.levels or choose_levels(len(faces), gltf_source.surface_texels(asset))
    table_size = args.table_size or choose_table_size(CONFIGS[s.config] * tex_bytes, levels, s.features)
    torch.manual_seed(s.seed)
    graph = material_graph(mesh.vertices, faces, levels=levels, table_size=table_size, features=s.features,
                           hidden=hidden, seed=s.seed, outputs=targets.width).to(device)
    sampler = SurfaceSampler(mesh)

    def batch(rng):
        face, t0, t1, uv = sampler(s.batch, rng)
        return np.stack([face.astype(np.float32), t0, t1], 1), targets(face, uv)

    history = fit(graph, batch, s, device, f"uvfree_material {Path(args.gltf).name} {s.config}", progress)
    seconds = time.perf_counter() - started
    graph = graph.to("cpu")
    quality = evaluate(graph, sampler, targets, 1 << 16, s.seed)
    provenance = {"command": run.command, "preset": run.preset, "gltf": Path(args.gltf).name, "config": s.config,
                  "channels": list(targets.channels), "levels": levels, "features": s.features,
                  "table_size": table_size, "hidden": list(hidden), "steps": s.steps, "batch": s.batch,
                  "seed": s.seed, "lr": s.lr, "mlp_lr": s.mlp_lr, "mesh_digest": mesh_topology(mesh.vertices, faces).digest,
                  "faces": int(len(faces)), "torch": torch.__version__, "device": str(device),
                  **recorded_at()}
    bundle = graph.export(KIND_GLTF, f"{s.object}_{s.config}", provenance=provenance, metrics=quality,
                          render=gltf_channels.render_meta(targets.channels, targets.scale))
    # the fp16 table (what an RGBA16F texture holds) stored as F16: half the file, widened exactly at load
    bundle.tensors = {k: (v.astype(np.float16) if k.endswith(".table") and v.dtype.kind == "f" else v)
                      for k, v in bundle.tensors.items()}
    bundle.save(out / BUNDLE)
    scene = gltf_scene.scene_description(out.name, mesh_name, Path(args.gltf).name, out, BUNDLE, s.config,
                                         targets.channels)
    atomic_write(out / "scene.json", json.dumps(scene, indent=2) + "\n")
    metrics = {"gltf": str(args.gltf), "channels": list(targets.channels), "emissive_scale": targets.scale,
               "materials": len(asset.used_materials()), "train_seconds": round(seconds, 1),
               "train_threads": torch.get_num_threads(), "device": str(device), "levels": levels,
               "table_size": table_size, "features": s.features, "faces": int(len(faces)),
               "memory": memory(bundle, asset, out / mesh_name), "torch_quality": quality,
               "render": gltf_scene.render_metrics(out), "history": history}
    run.write_metrics(metrics)
    if not args.no_preview:
        render_preview(out)
    return metrics
