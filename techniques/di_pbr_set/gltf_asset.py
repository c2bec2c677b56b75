"""The asset of ``inshade train di_pbr_set --gltf FILE``: one material of a glTF file compressed by
the DI cascade and drawn next to the file's own material.

``build_gltf(out, path, ...)`` bakes the material's lanes over its uv domain (gltf_lanes.py), trains
the cascade exactly as the bricks set is trained (models/texture_cascade.py ``compress``, k = 8, no
colour decode), and writes:

- ``source.glb`` (or ``source.gltf`` and the files it names): the file, byte-identical, as the
  scene's mesh (its normals, tangents and materials: the reference);
- the DI bundle (``bundle.json`` + ``weights.safetensors``), whose ``render.uv_domain`` says which
  material and uv rectangle the lanes cover;
- ``scene.json``: passes/mesh_pbr_set_gltf.frag, views reference | di | split, the camera, lights and
  environment ``inshade render FILE.glb`` frames the file with;
- ``metrics.json`` / ``report.md``: per lane group PSNR of the decoded set (torch, GLSL exact and
  fast) against the bake, ASTC on the same lanes, and the render PSNR of DI against the reference
  at the scene's camera, both drawn through the GL runtime; ``preview.png``: the split view.
"""
from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import numpy as np
import torch

from inshade.files import atomic_write
from inshade.geometry.gltf import GltfError, copy_gltf
from inshade.models.pbr_lanes import split_rgba8
from inshade.models.texture_cascade import compress, torch_decode
from inshade.scene.builder import float_setting, network, scene_json, view_labels
from inshade.techniques.di_pbr_set import ERROR_SCALE, GLTF_PROGRAM, GLTF_VIEWS
from inshade.techniques.di_pbr_set import gltf_lanes as L
from inshade.techniques.di_pbr_set.render import render_views
from inshade.techniques.di_pbr_set.report import astc_rows, gltf_lane_metrics, gltf_markdown, render_psnr
from inshade.techniques.di_pbr_set.scene import lit_parts
from inshade.provenance import recorded_at

LIGHTS = 2          # the point lights of a glTF scene (as ``inshade render FILE.glb`` places them)


def framing(path: Path) -> tuple[dict, list]:
    """(camera, lights) of the scene the file opens as on its own (``inshade render FILE.glb``,
    through the registry's opener), so the reference side is exactly that render."""
    from inshade.technique import opener

    opened = opener(path.suffix)(path)
    return opened["camera"], opened["lights"]


def scene_dict(name: str, title: str, mesh_file: str, camera: dict, lights: list, size: int, light_count: int,
               notes: list) -> dict:
    return scene_json(
        name, title, GLTF_PROGRAM, (size, size),
        networks=[network(".", "net")],
        mesh=mesh_file,
        camera=camera,
        **lit_parts(lights, light_count, GLTF_VIEWS, "material (split: left the file's, right DI)",
                    error_scale=float_setting(ERROR_SCALE, 1.0, 64.0, "error view: |DI - reference| x",
                                              uniform="u_pbr_error_scale")),
        notes="; ".join(notes),
        labels=view_labels("reference", "DI", {"view": "split"},
                           [("reference", {"view": "reference"}), ("DI", {"view": "di"}),
                            ("|DI - reference|", {"view": "error"})]),
    )


def domain_note(domain: L.UvDomain) -> str:
    axes = []
    for a, name in enumerate("uv"):
        o, e = domain.origin[a], domain.extent[a]
        axes.append(f"{name} repeats every {e:g}" if domain.repeat[a] else f"{name} spans [{o:g}, {o + e:g}]")
    return ("DI is evaluated at the mesh uv mapped onto the baked rectangle (" + ", ".join(axes) +
            "): fract() along a repeating axis, clamped along a spanning one")


def build_gltf(out, path, *, material: int | None, size: int | None, ratio: float, steps: int, lr: float,
               batch: int, seed: int, finish_optimizer: str, render: int, lights: int = LIGHTS,
               gl_metrics: bool = True, command: str | None = None, progress: bool | None = None, device=None,
               preset: str | None = None) -> dict:
    """Write the asset folder for material ``material`` (None: the textured one covering most faces) of the glTF
    file ``path``; ``size`` None: the bake side the textures ask for. Returns the metrics."""
    path = Path(path)
    out = Path(out)
    asset, m, domain = L.load(path, material)
    auto_size, capped = L.bake_size(asset, m, domain)
    side = auto_size if size is None else int(size)
    if side < 8:
        raise GltfError(f"{path}: --size {side}: the bake needs at least 8x8 texels")
    out.mkdir(parents=True, exist_ok=True)
    lanes = L.bake_lanes(asset, m, domain, side)
    mat = asset.materials[m]
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    t0 = time.perf_counter()
    result = compress(lanes, ratio, steps=steps, lr=lr, batch=batch, seed=seed, decode=False,
                      finish_optimizer=finish_optimizer, name=out.name, progress=progress, device=device,
                      provenance={"command": command,
                                  "material": {"file": path.name, "sha256": sha, "index": m, "name": mat.name},
                                  "lanes": {k: list(v) for k, v in L.LANES.items()},
                                  "uv_domain": domain.as_dict()})
    train_seconds = time.perf_counter() - t0
    bundle = type(result.bundle)({**result.bundle.meta, "render": {"uv_domain": domain.as_dict()}},
                                 result.bundle.tensors)
    bundle.save(out)
    mesh_file = copy_gltf(path, out)
    camera, scene_lights = framing(out / mesh_file)
    notes = [f"material {m} ({mat.name or 'unnamed'}) of {path.name} compressed by DI: albedo, normal (x, y; "
             "z rebuilt), roughness, occlusion, metallic in 8 lanes; emission, alpha, clearcoat, sheen, "
             "anisotropy and ior stay the file's", domain_note(domain),
             "DI is read at the base level (no footprint); the reference samples the file's mip maps", *asset.notes]
    title = (f"DI PBR set of {path.name} ({mat.name or f'material {m}'}) at {result.metrics['ratio']:.2f}x: "
             "reference | DI")
    atomic_write(out / "scene.json", json.dumps(scene_dict(out.name, title, mesh_file, camera, scene_lights, render,
                                                           min(lights, len(scene_lights)), notes),
                                                indent=2) + "\n")
    src = L.source_bytes(asset, m)
    metrics = {"texture": {k: result.metrics[k] for k in ("width", "height", "channels", "ratio", "bytes",
                                                          "uncompressed_bytes", "n_primary", "n_cascaded",
                                                          "steps", "finish_steps", "finish_optimizer",
                                                          "train_seconds", "psnr_quantised")}}
    metrics["texture"]["total_seconds"] = round(train_seconds, 2)
    metrics["source"] = {"file": path.name, "sha256": sha, "material": m, "material_name": mat.name,
                         "textures": {slot: list(asset.images[ref.image].shape[1::-1])
                                      for slot, ref in mat.textures().items() if slot in L.SLOTS},
                         "lane_texture_bytes_rgba8": src,
                         "ratio_vs_lane_textures": round(src / result.metrics["bytes"], 4)}
    metrics["bake"] = {"size": side, "size_from": "textures" if size is None else "--size",
                       "size_from_textures": auto_size, "capped_at": L.MAX_BAKE if capped else None,
                       "texels_per_uv": [round(r, 3) for r in L.texels_per_uv(asset, m)], **domain.as_dict()}
    metrics["lanes"] = {k: list(v) for k, v in L.LANES.items()}
    metrics["di_torch"] = gltf_lane_metrics(torch_decode(bundle, side), lanes)
    if gl_metrics:      # the GLSL decode, ASTC, the render against the reference and the preview
        from inshade.runtime.context import gl_info, shared_context
        from inshade.runtime.network import evaluate_on_pixels
        from inshade.scene.image_io import write_png

        for f in ("exact", "fast"):
            metrics[f"di_glsl_{f}"] = gltf_lane_metrics(evaluate_on_pixels(bundle, side, f), lanes)
        metrics["astc"] = astc_rows(split_rgba8(lanes), lanes, measure=gltf_lane_metrics)
        views = render_views(out, views=GLTF_VIEWS)
        gb_pos, gb_uv = views["_gbuffer"][0][::-1], views["_gbuffer"][2][::-1]
        covered = gb_pos[..., 3] != 0
        on_material = covered & (np.rint(gb_uv[..., 2]) == m)
        metrics["render"] = {"size": render, "lights": min(lights, len(scene_lights)),
                             "covered_pixels": int(covered.sum()), "material_pixels": int(on_material.sum()),
                             # over the compressed material's pixels: other materials are the file's in both
                             "psnr_di_vs_reference": round(render_psnr(views["di"], views["reference"], on_material),
                                                           3),
                             "split_left_equals_reference": bool(np.array_equal(
                                 views["split"][:, :render // 2], views["reference"][:, :render // 2]))}
        metrics["gl_renderer"] = gl_info(shared_context())["renderer"]
        write_png(out / "preview.png", views["split"][..., :3])
    metrics["command"] = command
    metrics["preset"] = preset
    # what the run was built from: the bake side and the material actually used
    metrics["settings"] = dict(size=side, ratio=ratio, steps=steps, lr=lr, batch=batch, seed=seed,
                               finish_optimizer=finish_optimizer, gltf=str(path), material=m)
    metrics["device"] = str(torch.device("cpu") if device is None else torch.device(device))
    metrics.update(recorded_at())
    atomic_write(out / "metrics.json", json.dumps(metrics, indent=1) + "\n")
    atomic_write(out / "report.md", gltf_markdown(metrics))
    return metrics
