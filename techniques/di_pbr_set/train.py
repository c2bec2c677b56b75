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

Command: ``inshade train di_pbr_set --force -o trained/di_pbr_set_bricks [--preset quick|ship]`` (``--help`` for
options). ``--preset ship`` is exactly what built trained/di_pbr_set_bricks; ``quick`` (the default) trains
3000 steps. metrics.json records the preset and the resolved settings.
"""
from __future__ import annotations

import argparse
import datetime
import json
import shlex
import sys
import time
from dataclasses import asdict
from pathlib import Path

import torch

from inshade.files import atomic_files, atomic_write
from inshade import asset_folder, command
from inshade.devices import DeviceError, add_device_argument, resolve_device
from inshade.lit_settings import lit_settings
from inshade.models.pbr_lanes import LANES, Bricks, PbrSetError, bricks, split_rgba8
from inshade.models.texture_cascade import FINISH_OPTIMIZERS, compress, torch_decode
from inshade.techniques.di_pbr_set.render import DEFAULT_LIGHTS, LIGHTS, VIEWS, render_views
from inshade.techniques.di_pbr_set.report import astc_rows, lane_metrics, markdown, render_psnr

PROGRAM = "passes/mesh_pbr_set.frag"
# finish_optimizer "adam": on this set the minibatch Adam finish beat full-batch L-BFGS (12000 steps,
# all lanes 27.67 vs 27.50 dB), unlike on RGB images (models/texture_cascade.py FINISH_OPTIMIZERS)
DEFAULTS = dict(size=256, ratio=6.0, steps=3000, lr=1e-2, batch=16384, seed=0, render=256, lights=DEFAULT_LIGHTS,
                finish_optimizer="adam")
# --preset: "ship" is what built trained/di_pbr_set_bricks; "quick" keeps the 3000-step default.
PRESETS = {"quick": dict(steps=3000), "ship": dict(steps=12000)}
SETTINGS = ("size", "ratio", "steps", "lr", "batch", "seed", "finish_optimizer")


def preset_settings(preset: str, asset: str | None = None) -> dict:
    """The settings ``--preset PRESET`` resolves to with no other option (one asset: ``asset`` is ignored)."""
    return {k: PRESETS[preset].get(k, DEFAULTS[k]) for k in SETTINGS}


# ---------------------------------------------------------------------------------------------
# the asset

def scene_dict(name: str, title: str, size: int, lights: int) -> dict:
    return {
        "format": "inshade.scene", "version": 1, "name": name, "title": title,
        "program": PROGRAM, "size": [size, size],
        "networks": [{"bundle": ".", "prefix": "net"}],
        "mesh": "mesh.obj",
        "textures": [{"uniform": "u_pbr_set0", "image": "set0.png", "mipmaps": False, "repeat": True},
                     {"uniform": "u_pbr_set1", "image": "set1.png", "mipmaps": False, "repeat": True}],
        "camera": {"type": "orbit", "fov_y": 40.0, "target": [0.0, 0.0, 0.0], "distance": 3.9, "yaw": 25.0,
                   "pitch": -38.0},
        "bookmarks": {"close-up": {"type": "orbit", "fov_y": 40.0, "target": [0.9, 0.3, 0.3], "distance": 1.4,
                                   "yaw": 35.0, "pitch": -25.0}},
        "lights": [{"type": "point", "position": list(l[:3]), "intensity": l[3]} for l in LIGHTS],
        "environment": {"sky": "studio", "rotation": 0.0, "degree": 3},
        "display": {"mode": "final", "modes": ["final"], "split": 0.5},
        "settings": {
            **lit_settings("studio"),
            "view": {"type": "choice", "default": "split", "choices": list(VIEWS), "uniform": "u_pbr_view",
                     "label": "texture set (split: left uncompressed, right DI)"},
            "lights": {"type": "int", "default": lights, "min": 0, "max": len(LIGHTS), "uniform": "u_light_count",
                       "label": "point lights"},
            "lut_filter": {"type": "choice", "default": "exact", "choices": ["exact", "fast"],
                           "codegen": "lut_filter", "label": "LUT filtering"},
        },
        "requires": {"gl": 330},
        "notes": "a DI-compressed PBR set (albedo, normal, roughness, AO: 8 lanes) on a uv-mapped torus",
        "labels": [
            {"text": "uncompressed", "at": [0.25, 0.95], "when": {"view": "split"}},
            {"text": "DI", "at": [0.75, 0.95], "when": {"view": "split"}},
            {"line": [[0.5, 0.0], [0.5, 1.0]], "when": {"view": "split"}},
            {"text": "uncompressed", "at": [0.5, 0.95], "when": {"view": "uncompressed"}},
            {"text": "DI", "at": [0.5, 0.95], "when": {"view": "di"}},
        ],
    }


def build(out, *, size: int = DEFAULTS["size"], ratio: float = DEFAULTS["ratio"], steps: int = DEFAULTS["steps"],
          lr: float = DEFAULTS["lr"], batch: int = DEFAULTS["batch"], seed: int = DEFAULTS["seed"],
          render: int = DEFAULTS["render"], lights: int = DEFAULTS["lights"], recipe: Bricks = Bricks(),
          finish_optimizer: str = DEFAULTS["finish_optimizer"],
          gl_metrics: bool = True, command: str | None = None, progress: bool | None = None, device=None,
          preset: str | None = None) -> dict:
    """Write the asset folder; returns its metrics. `device`: where the DI training runs (default the CPU)."""
    from PIL import Image

    from inshade.mesh import write_torus

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
        from inshade.runtime.image_io import write_png
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
    metrics["date_utc"] = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    atomic_write(out / "metrics.json", json.dumps(metrics, indent=1) + "\n")
    atomic_write(out / "report.md", markdown(metrics))
    return metrics


# ---------------------------------------------------------------------------------------------
# command line

def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    d = DEFAULTS
    asset_folder.add_arguments(p, "di_pbr_set_bricks")
    p.add_argument("--size", type=int, default=d["size"], help="texture side in texels (default %(default)s)")
    p.add_argument("--ratio", type=float, default=d["ratio"], help="compression ratio vs 8 lanes x 8 bit "
                   "(default %(default)s)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="quick",
                   help="ship: exactly what built trained/di_pbr_set_bricks (12000 steps); quick: 3000 steps; "
                        "options given explicitly override it (default %(default)s)")
    p.add_argument("--steps", type=int, help="training steps (default: the preset's)")
    p.add_argument("--lr", type=float, default=d["lr"], help="Adam learning rate (default %(default)s)")
    p.add_argument("--batch", type=int, default=d["batch"], help="samples per step (default %(default)s)")
    p.add_argument("--seed", type=int, default=d["seed"])
    p.add_argument("--finish-optimizer", choices=FINISH_OPTIMIZERS, default=d["finish_optimizer"],
                   help="finish phase of the training (inshade train di_texture --help; default %(default)s)")
    p.add_argument("--render", type=int, default=d["render"], help="scene render size (default %(default)s)")
    p.add_argument("--lights", type=int, default=d["lights"], choices=range(0, len(LIGHTS) + 1),
                   help="default point-light count (default %(default)s)")
    p.add_argument("--no-gl", action="store_true", help="skip GL metrics and the preview (no GL context)")
    add_device_argument(p)
    return p


def run(args, argv=None) -> int:
    device = resolve_device(args.device)     # first: a missing CUDA device fails before any work
    args.out = str(asset_folder.claim(args.out, "di_pbr_set_bricks", force=args.force))
    if args.steps is None:
        args.steps = PRESETS[args.preset]["steps"]
    if args.steps < 0 or args.batch < 1:
        raise PbrSetError("--steps must be >= 0 and --batch >= 1")
    argv = list(sys.argv[1:] if argv is None else argv)
    m = build(args.out, size=args.size, ratio=args.ratio, steps=args.steps, lr=args.lr, batch=args.batch,
              seed=args.seed, render=args.render, lights=args.lights, finish_optimizer=args.finish_optimizer,
              gl_metrics=not args.no_gl, device=device, preset=args.preset,
              command=shlex.join(["inshade", "train", "di_pbr_set", *argv]))
    t = m["texture"]
    q = m.get("di_glsl_exact", m["di_torch"])
    print(f"wrote {args.out}: {t['ratio']:.2f}x ({t['bytes']} bytes), albedo {q['psnr_albedo']:.2f} dB, "
          f"normal {q['normal_mean_deg']:.2f} deg mean, roughness {q['psnr_roughness']:.2f} dB, "
          f"AO {q['psnr_ao']:.2f} dB, {t['train_seconds']:.1f} s")
    return 0


def main(argv=None) -> int:
    return command.main("inshade train di_pbr_set", __doc__, add_arguments, run, argv, errors=(DeviceError,))

