"""A PBR texture set compressed with Differentiable Indirection and shaded on a lit mesh
(Differentiable Indirection, Datta et al. 2023 §4.2.1: "for PBR textures, k includes albedo, normal, AO, roughness").

The set is eight lanes (models/pbr_lanes.py ``LANES``): albedo RGB (sRGB-encoded), the tangent-space
normal stored as 0.5 + 0.5 n (x along +u, y along +v), roughness and ambient occlusion; the material is
its procedural bricks. One DI cascade (models/texture_cascade.py ``compress`` with k = 8, no colour
decode) holds all eight; the shader (passes/mesh_pbr_set.frag, lib/pbr_set.glsl) evaluates it once per
visible pixel of a deferred mesh G-buffer and shades with the Disney BRDF (metallic 0, specular 0.5)
under point lights plus the SH environment's Lambert term times AO. The uncompressed set ships as two
RGBA8 textures of the same lanes, so the side-by-side view isolates the compression. render.py is the
pass's torch twin and the GL renders; report.py the quality metrics and the markdown report.

- ``build(out)``: the shipped asset: the DI bundle, the uncompressed lanes, a uv-mapped torus,
  scene.json, preview.png and metrics.json (per-lane-group quality of the GLSL-decoded set,
  ASTC on the same two RGBA textures, and the rendered torus DI vs uncompressed); ``gl_metrics=False``
  (``--no-gl``) keeps to the torch decode and needs no GL context.

With ``--gltf FILE`` (``--material INDEX``; default the textured material covering most faces) the set is
that glTF material instead of the bricks: its channels baked over the mesh's uv (gltf_lanes.py:
albedo, a two-lane normal, roughness, occlusion, metallic; the side from the textures unless
``--size`` is given), the same cascade and training, and an asset drawn next to the file's own
material (gltf_asset.py, passes/mesh_pbr_set_gltf.frag).

Command: ``inshade train di_pbr_set --force -o trained/di_pbr_set_bricks [--preset quick|ship]`` (``--help`` for
options). ``--preset ship`` is exactly what built trained/di_pbr_set_bricks; ``quick`` (the default) trains
3000 steps. metrics.json records the preset and the resolved settings (with ``--gltf``: the file, the
material and the bake side actually used).
"""
from __future__ import annotations

import argparse
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import torch

from inshade.files import atomic_files, atomic_write
from inshade.geometry.gltf import GltfError
from inshade.models.pbr_lanes import LANES, Bricks, PbrSetError, bricks, split_rgba8
from inshade.models.texture_cascade import FINISH_OPTIMIZERS, compress, torch_decode
from inshade.scene.builder import network, orbit, point_light, scene_json, texture, view_labels
from inshade.techniques.di_pbr_set import VIEWS
from inshade.techniques.di_pbr_set.render import DEFAULT_LIGHTS, LIGHTS, render_views
from inshade.techniques.di_pbr_set.report import astc_rows, lane_metrics, markdown, render_psnr
from inshade.techniques.di_pbr_set.scene import lit_parts
from inshade.trainer import (GIVEN, Run, Trainer, batch_setting, check_fit, lr_setting, seed_setting, setting,
                             steps_setting)
from inshade.provenance import recorded_at

PROGRAM = "passes/mesh_pbr_set.frag"
ASSET = "di_pbr_set_bricks"
RENDER_SIZE = 256       # the scene's render size


# the settings of a run that names a glTF file: a bricks run neither records them nor accepts --material
GLTF_RUN = {"gltf": GIVEN}


@dataclass(frozen=True)
class Settings:
    """What a di_pbr_set run is built from (metrics.json records it)."""
    size: int = setting(256, "texture side in texels (with --gltf: by default what the textures need)")
    ratio: float = setting(6.0, "compression ratio vs 8 lanes x 8 bit")
    steps: int = steps_setting(3000)
    lr: float = lr_setting(1e-2)
    batch: int = batch_setting(16384)
    seed: int = seed_setting()
    # "adam" on mixed texel-centre + stratified batches, as for RGB textures (models/texture_cascade.py
    # DEFAULTS); on this set full-batch L-BFGS was 0.17 dB worse with the ramp start
    finish_optimizer: str = setting("adam", "finish phase of the training (inshade train di_texture --help)",
                                    choices=FINISH_OPTIMIZERS)
    gltf: str | None = setting(None, "compress this glTF file's material (.glb/.gltf) instead of the bricks; "
                               "--size then defaults to what its textures need", metavar="FILE", only=GLTF_RUN)
    material: int | None = setting(None, "with --gltf: the material's index (none given: the textured one "
                                   "covering most faces)", metavar="INDEX", only=GLTF_RUN)


# --preset: "ship" is what built trained/di_pbr_set_bricks; "quick" keeps the 3000-step default.
PRESETS = {"quick": {}, "ship": dict(steps=12000)}


# ---------------------------------------------------------------------------------------------
# the asset

def scene_dict(name: str, title: str, size: int, lights: int) -> dict:
    return scene_json(
        name, title, PROGRAM, (size, size),
        networks=[network(".", "net")],
        mesh="mesh.obj",
        textures=[texture("u_pbr_set0", "set0.png", mipmaps=False, repeat=True),
                  texture("u_pbr_set1", "set1.png", mipmaps=False, repeat=True)],
        camera=orbit((0.0, 0.0, 0.0), 3.9, 25.0, -38.0),
        bookmarks={"close-up": orbit((0.9, 0.3, 0.3), 1.4, 35.0, -25.0)},
        **lit_parts([point_light(l[:3], l[3]) for l in LIGHTS], lights, VIEWS,
                    "texture set (split: left uncompressed, right DI)"),
        notes="a DI-compressed PBR set (albedo, normal, roughness, AO: 8 lanes) on a uv-mapped torus",
        labels=view_labels("uncompressed", "DI", {"view": "split"},
                           [("uncompressed", {"view": "uncompressed"}), ("DI", {"view": "di"})]),
    )


def build(out, *, size: int = Settings.size, ratio: float = Settings.ratio, steps: int = Settings.steps,
          lr: float = Settings.lr, batch: int = Settings.batch, seed: int = Settings.seed,
          render: int = RENDER_SIZE, lights: int = DEFAULT_LIGHTS, recipe: Bricks = Bricks(),
          finish_optimizer: str = Settings.finish_optimizer,
          gl_metrics: bool = True, command: str | None = None, progress: bool | None = None, device=None,
          preset: str | None = None) -> dict:
    """Write the asset folder; returns its metrics. `device`: where the DI training runs (default the CPU)."""
    from PIL import Image

    from inshade.geometry.mesh import write_torus

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    lanes = bricks(size, recipe)
    t0 = time.perf_counter()
    result = compress(lanes, ratio, steps=steps, lr=lr, batch=batch, seed=seed, decode=False,
                      finish_optimizer=finish_optimizer,
                      name=out.name, progress=progress, device=device,
                      provenance={"command": command, "material": {"generator": "models/pbr_lanes.py bricks",
                                                                   **asdict(recipe)},
                                  "lanes": {k: list(v) for k, v in LANES.items()}})
    train_seconds = time.perf_counter() - t0
    bundle = result.bundle      # kind "di_texture": a DI texture whose 8 lanes are the set
    bundle.save(out)
    set8 = split_rgba8(lanes)
    for i, img in enumerate(set8):
        with atomic_files(out / f"set{i}.png") as tmp:
            Image.fromarray(img, "RGBA").save(tmp, format="PNG", optimize=False)
    write_torus(out / "mesh.obj")
    title = f"DI PBR set (bricks, 8 lanes) at {result.metrics['ratio']:.2f}x on a torus: uncompressed | DI"
    atomic_write(out / "scene.json", json.dumps(scene_dict(out.name, title, render, lights), indent=2) + "\n")
    metrics = {"texture": {k: result.metrics[k] for k in ("width", "height", "channels", "ratio", "bytes",
                                                          "uncompressed_bytes", "n_primary", "n_cascaded",
                                                          "steps", "finish_steps", "finish_optimizer",
                                                          "train_seconds", "psnr_quantised")}}
    metrics["texture"]["total_seconds"] = round(train_seconds, 2)   # compress: training, the export, its torch PSNR
    metrics["di_torch"] = lane_metrics(torch_decode(bundle, size), lanes)
    if gl_metrics:      # the GLSL decode, ASTC, the rendered torus and its preview (a GL context)
        from inshade.runtime.context import gl_info, shared_context
        from inshade.scene.image_io import write_png
        from inshade.runtime.network import evaluate_on_pixels

        for f in ("exact", "fast"):
            metrics[f"di_glsl_{f}"] = lane_metrics(evaluate_on_pixels(bundle, size, f), lanes)
        metrics["astc"] = astc_rows(set8, lanes)
        views = render_views(out)
        mask = views["_gbuffer"][0][::-1, :, 3] != 0
        metrics["render"] = {"size": render, "lights": lights, "covered_pixels": int(mask.sum()),
                             "psnr_di_vs_uncompressed": round(render_psnr(views["di"], views["uncompressed"], mask), 3)}
        metrics["gl_renderer"] = gl_info(shared_context())["renderer"]
        write_png(out / "preview.png", views["split"][..., :3])
    metrics["command"] = command
    # the preset and the settings it resolved to (tests/test_presets.py holds the shipped asset's
    # equal to preset_settings("ship"))
    metrics["preset"] = preset
    metrics["settings"] = dict(size=size, ratio=ratio, steps=steps, lr=lr, batch=batch, seed=seed,
                               finish_optimizer=finish_optimizer)
    metrics["device"] = str(torch.device("cpu") if device is None else torch.device(device))
    metrics.update(recorded_at())
    atomic_write(out / "metrics.json", json.dumps(metrics, indent=1) + "\n")
    atomic_write(out / "report.md", markdown(metrics))
    return metrics


# ---------------------------------------------------------------------------------------------
# command line

def extra_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--render", type=int, default=RENDER_SIZE, help="scene render size (default %(default)s)")
    p.add_argument("--lights", type=int, default=DEFAULT_LIGHTS, choices=range(0, len(LIGHTS) + 1),
                   help="default point-light count (default %(default)s; a glTF scene has 2)")
    p.add_argument("--no-gl", action="store_true", help="skip GL metrics and the preview (no GL context)")


def check(s: Settings) -> None:
    check_fit(s, PbrSetError)
    if s.gltf is not None:      # a file that cannot be used fails before the asset folder is claimed
        from inshade.techniques.di_pbr_set.gltf_lanes import load

        load(s.gltf, s.material)


def train_gltf(run: Run) -> int:
    """The glTF mode: gltf_asset.build_gltf writes the folder, metrics.json and report.md."""
    from inshade.techniques.di_pbr_set.gltf_asset import LIGHTS as GLTF_LIGHTS, build_gltf

    args, s = run.args, run.settings
    if args.lights > GLTF_LIGHTS:
        raise PbrSetError(f"--lights {args.lights}: a glTF scene has {GLTF_LIGHTS} point lights")
    m = build_gltf(run.out, s.gltf, material=s.material, size=args.size, ratio=s.ratio, steps=s.steps, lr=s.lr,
                   batch=s.batch, seed=s.seed, finish_optimizer=s.finish_optimizer, render=args.render,
                   lights=args.lights, gl_metrics=not args.no_gl, device=run.device, preset=run.preset,
                   command=run.command)
    t = m["texture"]
    q = m.get("di_glsl_exact", m["di_torch"])
    shown = f", render {m['render']['psnr_di_vs_reference']:.2f} dB vs the file's material" if "render" in m else ""
    lanes = ", ".join(f"{name} {'exact' if q[f'psnr_{name}'] is None else format(q[f'psnr_{name}'], '.2f') + ' dB'}"
                      for name in ("albedo", "roughness", "occlusion", "metallic"))
    print(f"wrote {run.out}: material {m['source']['material']} baked {t['width']}^2, {t['ratio']:.2f}x "
          f"({t['bytes']} bytes), {lanes}, normal {q['normal_mean_deg']:.2f} deg mean{shown}, "
          f"{t['train_seconds']:.1f} s")
    return 0


def train(run: Run) -> int:
    """build() writes the folder and its metrics.json (the run's command, preset and settings with the
    metrics), and report.md from the same metrics."""
    if run.settings.gltf is not None:
        return train_gltf(run)
    args = run.args
    settings = {k: v for k, v in asdict(run.settings).items() if k not in ("gltf", "material")}
    m = build(run.out, **settings, render=args.render, lights=args.lights, gl_metrics=not args.no_gl,
              device=run.device, preset=run.preset, command=run.command)
    t = m["texture"]
    q = m.get("di_glsl_exact", m["di_torch"])
    print(f"wrote {run.out}: {t['ratio']:.2f}x ({t['bytes']} bytes), albedo {q['psnr_albedo']:.2f} dB, "
          f"normal {q['normal_mean_deg']:.2f} deg mean, roughness {q['psnr_roughness']:.2f} dB, "
          f"AO {q['psnr_ao']:.2f} dB, {t['train_seconds']:.1f} s")
    return 0


def folder(s: Settings) -> str:
    return f"di_pbr_set_{Path(s.gltf).stem}" if s.gltf is not None else ASSET


TRAINER = Trainer("di_pbr_set", __doc__, Settings, PRESETS, train, folder=folder,
                  folder_hint=f"{ASSET}, with --gltf di_pbr_set_<file name>", ship_assets={ASSET: {}},
                  extra_arguments=extra_arguments, check=check, errors=(PbrSetError, GltfError))
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
