"""A PBR texture set compressed with Differentiable Indirection and shaded on a lit mesh
(Differentiable Indirection, Datta et al. 2023 §4.2.1: "for PBR textures, k includes albedo, normal, AO, roughness").

The set is eight lanes (``LANES``): albedo RGB (sRGB-encoded), the tangent-space normal stored
as 0.5 + 0.5 n (x along +u, y along +v), roughness and ambient occlusion. One DI cascade
(techniques/di_texture/train.py ``compress`` with k = 8, no colour decode) holds all eight; the
shader (passes/mesh_pbr_set.frag, lib/pbr_set.glsl) evaluates it once per visible pixel of a
deferred mesh G-buffer and shades with the Disney BRDF (metallic 0, specular 0.5) under point
lights plus the SH environment's Lambert term times AO. The uncompressed set ships as two RGBA8
textures of the same lanes, so the side-by-side view isolates the compression.

- ``bricks(size)``: the procedural material (no downloads here): a running-bond brick wall,
  periodic in both axes (it tiles on the torus), with per-brick colour, bevelled edges, mortar,
  FFT-filtered noise; normal and AO derived from its height field.
- ``unpack`` / ``shade`` / ``render_gbuffer``: the torch twin of lib/pbr_set.glsl and the pass,
  fed the G-buffer the GL pass rasterised (same operations in the same order, float32).
- ``build(out)``: the shipped asset: the DI bundle, the uncompressed lanes, a uv-mapped torus,
  scene.json, preview.png and metrics.json (per-lane-group quality of the GLSL-decoded set,
  ASTC on the same two RGBA textures, and the rendered torus DI vs uncompressed).

Command: ``inshade train di_pbr_set --force -o trained/di_pbr_set_bricks [--preset quick|ship]`` (``--help`` for
options). ``--preset ship`` is exactly what built trained/di_pbr_set_bricks; ``quick`` (the default) trains
3000 steps. metrics.json records the preset and the resolved settings.
"""
from __future__ import annotations

import argparse
import datetime
import json
import math
import shlex
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch

from inshade.files import atomic_files, atomic_write
from inshade import asset_folder, command
from inshade.devices import DeviceError, add_device_argument, resolve_device
from inshade.lit_settings import lit_settings
from inshade.metrics import psnr, srgb_oetf

from inshade.models import brdf
from inshade.models.pbr_lanes import CHANNELS, LANES, Bricks, PbrSetError, bricks, dot3, split_rgba8, unpack
from inshade.models.texture_cascade import FINISH_OPTIMIZERS

PROGRAM = "passes/mesh_pbr_set.frag"
# (world position, intensity): lib/pbr_set.glsl PBR_SET_LIGHTS
LIGHTS = ((2.5, 3.0, 2.5, 16.0), (-3.0, 1.5, 1.5, 8.0), (0.5, -2.5, 3.0, 5.0), (-1.5, 3.5, -2.5, 6.0))
VIEWS = ("uncompressed", "di", "split")      # u_pbr_view index
# finish_optimizer "adam": on this set the minibatch Adam finish beat full-batch L-BFGS (12000 steps,
# all lanes 27.67 vs 27.50 dB), unlike on RGB images (techniques/di_texture/train.py FINISH_OPTIMIZERS)
DEFAULTS = dict(size=256, ratio=6.0, steps=3000, lr=1e-2, batch=16384, seed=0, render=256, lights=2,
                finish_optimizer="adam")
# --preset: "ship" is what built trained/di_pbr_set_bricks; "quick" keeps the 3000-step default.
PRESETS = {"quick": dict(steps=3000), "ship": dict(steps=12000)}
SETTINGS = ("size", "ratio", "steps", "lr", "batch", "seed", "finish_optimizer")
ASTC_BLOCKS = (4, 5, 6, 8)


def preset_settings(preset: str, asset: str | None = None) -> dict:
    """The settings ``--preset PRESET`` resolves to with no other option (one asset: ``asset`` is ignored)."""
    return {k: PRESETS[preset].get(k, DEFAULTS[k]) for k in SETTINGS}


# ---------------------------------------------------------------------------------------------
# torch twin of lib/pbr_set.glsl

def _normalise(x, floor=None):
    d = dot3(x, x)
    if floor is not None:
        d = torch.clamp(d, min=floor)
    return x * torch.rsqrt(d)[:, None]


def shade(s: dict, p, ng, tangent, rd, sh: torch.Tensor, light_count: int) -> torch.Tensor:
    """lib/pbr_shading pbr_shade with metallic 0: [N, 3] linear radiance (the same operations in the same order)."""
    from inshade.models.sdf import sh_irradiance_t

    t = _normalise(tangent[:, :3] - ng * dot3(ng, tangent[:, :3])[:, None], 1e-30)
    b = torch.cross(ng, t, dim=-1) * torch.where(tangent[:, 3] < 0.0, -1.0, 1.0)[:, None]
    nts = s["normal_ts"]
    n = _normalise(t * nts[:, 0:1] + b * nts[:, 1:2] + ng * nts[:, 2:3])
    ts = _normalise(t - n * dot3(n, t)[:, None], 1e-30)
    bs = torch.cross(n, ts, dim=-1)

    def local(w):
        return torch.stack([dot3(w, ts), dot3(w, bs), dot3(w, n)], -1)

    params = torch.zeros(len(p), len(brdf.PARAMS))
    params[:, brdf.PARAMS.index("roughness")] = s["roughness"]
    params[:, brdf.PARAMS.index("specular")] = 0.5
    params[:, brdf.PARAMS.index("sheen_tint")] = 0.5
    params[:, brdf.PARAMS.index("clearcoat_gloss")] = 1.0
    v = local(-rd)
    colour = s["albedo"] * (s["ao"] * np.float32(1.0 / math.pi))[:, None] * sh_irradiance_t(sh, n)
    for x, y, z, power in LIGHTS[:light_count]:
        d = torch.tensor([x, y, z], dtype=torch.float32) - p
        d2 = dot3(d, d)
        l = local(d * torch.rsqrt(d2)[:, None])
        colour = colour + brdf.disney(l, v, s["albedo"], params) * (power / d2)[:, None]
    return colour


def bilinear_repeat(image8: np.ndarray, uv: torch.Tensor) -> torch.Tensor:
    """GL LINEAR + REPEAT sampling of an RGBA8 image (row 0 = top, uv (0,0) bottom-left) at texel
    centres, float32 weights (the driver's are 8-bit fixed point: see tests for the bound)."""
    img = torch.from_numpy(np.ascontiguousarray(image8[::-1]).astype(np.float32) / 255.0)  # row 0 = v 0
    h, w = img.shape[:2]
    x, y = uv[:, 0] * w - 0.5, uv[:, 1] * h - 0.5
    x0, y0 = torch.floor(x), torch.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.long() % w, y0.long() % h
    x1, y1 = (x0 + 1) % w, (y0 + 1) % h
    top = img[y0, x0] * (1 - fx) + img[y0, x1] * fx
    bottom = img[y1, x0] * (1 - fx) + img[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def render_gbuffer(gbuffer, uniforms: dict, width: int, height: int, sh, *, graph=None, set8=None,
                   view: str = "di", light_count: int = DEFAULTS["lights"]) -> np.ndarray:
    """The mesh_pbr_set pass in torch, fed the G-buffer (MeshGBuffer.read(): position, normal, uv,
    tangent in data orientation) the GL pass used: linear RGBA [H, W, 4], image orientation.
    ``graph``: the DI GraphModule (views "di"/"split"); ``set8``: the two RGBA8 images
    (views "uncompressed"/"split")."""
    from inshade.models.sdf import camera_rays, sh_background_t

    def flat(x):
        return torch.from_numpy(np.ascontiguousarray(np.asarray(x, np.float32)[::-1]).reshape(-1, 4))

    pos, nrm, uvs, tan = (flat(x) for x in gbuffer[:4])
    _, rd = camera_rays(uniforms, width, height)
    sh = torch.as_tensor(np.asarray(sh, np.float32))
    out = sh_background_t(sh, rd)
    hit = pos[:, 3] != 0.0
    idx = hit.nonzero().squeeze(1)
    if idx.numel():
        uv = uvs[idx, :2] - torch.floor(uvs[idx, :2])
        column = (idx % width).float() + 0.5
        compressed = {"di": column >= 0.0, "uncompressed": column < 0.0, "split": column >= 0.5 * width}[view]
        lanes = torch.zeros(len(idx), CHANNELS)
        if compressed.any():
            with torch.no_grad():
                lanes[compressed] = graph(uv[compressed])[:, :CHANNELS].float()
        if (~compressed).any():
            lanes[~compressed] = torch.cat([bilinear_repeat(set8[0], uv[~compressed]),
                                            bilinear_repeat(set8[1], uv[~compressed])], -1)
        with torch.no_grad():
            out[idx] = shade(unpack(lanes[:, :4], lanes[:, 4:]), pos[idx, :3], nrm[idx, :3], tan[idx], rd[idx], sh,
                             light_count)
    rgba = torch.cat([out, torch.ones(len(out), 1)], -1)
    return rgba.reshape(height, width, 4).numpy()


# ---------------------------------------------------------------------------------------------
# quality of a decoded set

def lane_metrics(test: np.ndarray, ref: np.ndarray) -> dict:
    """Per lane group: PSNR of the 8-bit values (albedo in sRGB-encoded bytes, as texture codecs
    are scored) and, for the normal, the mean / 99th-percentile angle between decoded normals."""
    t8 = np.round(np.clip(test, 0.0, 1.0) * 255.0)
    r8 = np.round(np.clip(ref, 0.0, 1.0) * 255.0)
    out = {}
    for name, (first, width) in LANES.items():
        out[f"psnr_{name}"] = round(psnr(t8[..., first:first + width], r8[..., first:first + width], 255.0), 3)
    nt, nr = test[..., 3:6] * 2.0 - 1.0, ref[..., 3:6] * 2.0 - 1.0
    cos = np.sum(nt * nr, -1) / np.maximum(np.linalg.norm(nt, axis=-1) * np.linalg.norm(nr, axis=-1), 1e-12)
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    out["normal_mean_deg"] = round(float(angle.mean()), 3)
    out["normal_p99_deg"] = round(float(np.percentile(angle, 99)), 3)
    out["psnr_all_lanes"] = round(psnr(t8, r8, 255.0), 3)
    return out


def astc_rows(set8: tuple[np.ndarray, np.ndarray], ref: np.ndarray) -> list[dict]:
    """ASTC (LDR, the benchmark's quality) on the same two RGBA8 textures, per block size."""
    from inshade.codecs import ASTC_QUALITY, CodecError, astc_roundtrip

    rows = []
    raw = ref.shape[0] * ref.shape[1] * CHANNELS
    for block in ASTC_BLOCKS:
        try:
            decoded, nbytes = zip(*(astc_roundtrip(img, block) for img in set8))
        except CodecError as exc:
            rows.append({"codec": f"ASTC {block}x{block}", "available": False, "reason": str(exc)})
            continue
        test = np.concatenate(decoded, -1).astype(np.float32) / 255.0
        rows.append({"codec": f"ASTC {block}x{block}", "available": True, "bytes": int(sum(nbytes)),
                     "ratio": round(raw / sum(nbytes), 3), "settings": f"2 RGBA textures, quality {ASTC_QUALITY:g}",
                     **lane_metrics(test, ref)})
    return rows


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


def render_views(folder, views=VIEWS, size: int | None = None, ctx=None) -> dict:
    """GL renders of the asset's scene per view: {view: linear RGBA [H, W, 4]} plus "_gbuffer"
    (the G-buffer read back) and "_uniforms"/"_sh" for the torch twin."""
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer
    from inshade.runtime.scene import load_scene

    scene = load_scene(folder)
    w, h = (size, size) if size else scene.size
    r = SceneRenderer(scene, ctx)
    out = {}
    try:
        cam = scene.make_camera()
        for view in views:
            r.set_setting("view", view)
            out[view] = read_rgba(r.render_network(cam, w, h)).copy()
        out["_gbuffer"] = tuple(a.copy() for a in r.gbuffer.read())
        out["_uniforms"] = cam.uniforms(w, h)
        out["_sh"] = r.environment_sh()
    finally:
        r.release()
    return out


def render_psnr(test: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> float:
    """PSNR over mesh pixels of display values (linear clamped to [0, 1], sRGB-encoded, 8-bit)."""
    a = np.round(srgb_oetf(np.clip(test[..., :3], 0, 1)) * 255.0)
    b = np.round(srgb_oetf(np.clip(ref[..., :3], 0, 1)) * 255.0)
    return psnr(a, b, 255.0, mask=mask)


def markdown(metrics: dict) -> str:
    """The asset's quality table: DI (GLSL-decoded, both LUT paths) against ASTC on the same lanes."""
    t = metrics["texture"]
    lines = [f"# PBR set (8 lanes) compressed with DI: {t['width']}x{t['height']}", "",
             f"- GL_RENDERER: `{metrics.get('gl_renderer', 'n/a')}`",
             "- PSNR of 8-bit lane values (albedo sRGB-encoded) against the uncompressed set; normal: "
             "angle between decoded and original normals", ""]
    head = "| codec | bytes | ratio | albedo dB | normal dB | normal mean / p99 deg | roughness dB | AO dB | all lanes dB |"
    lines += [head, "|---" * (head.count("|") - 1) + "|"]

    def row(name, nbytes, ratio, q):
        return (f"| {name} | {nbytes} | {ratio:.2f} | {q['psnr_albedo']:.2f} | {q['psnr_normal']:.2f} | "
                f"{q['normal_mean_deg']:.2f} / {q['normal_p99_deg']:.2f} | {q['psnr_roughness']:.2f} | "
                f"{q['psnr_ao']:.2f} | {q['psnr_all_lanes']:.2f} |")

    for key, label in (("di_glsl_exact", "DI (GLSL exact)"), ("di_glsl_fast", "DI (GLSL fast)"), ("di_torch", "DI (torch)")):
        if key in metrics:
            lines.append(row(label, t["bytes"], t["ratio"], metrics[key]))
    for a in metrics.get("astc", []):
        lines.append(row(a["codec"], a["bytes"], a["ratio"], a) if a["available"]
                     else f"| {a['codec']} | unavailable: {a['reason']} |||||||")
    lines.append("")
    device = metrics.get("device", "cpu")
    lines.append(f"DI: N_p {t['n_primary']}, N_c {t['n_cascaded']}, {t['steps']} steps, {t['train_seconds']:.0f} s "
                 f"training on {'1 CPU thread' if device == 'cpu' else device}.")
    if "render" in metrics:
        r = metrics["render"]
        lines.append(f"Rendered torus ({r['size']}^2, {r['lights']} lights + environment): DI vs uncompressed "
                     f"{r['psnr_di_vs_uncompressed']:.2f} dB over {r['covered_pixels']} mesh pixels (display sRGB 8-bit).")
    return "\n".join(lines) + "\n"


def build(out, *, size: int = DEFAULTS["size"], ratio: float = DEFAULTS["ratio"], steps: int = DEFAULTS["steps"],
          lr: float = DEFAULTS["lr"], batch: int = DEFAULTS["batch"], seed: int = DEFAULTS["seed"],
          render: int = DEFAULTS["render"], lights: int = DEFAULTS["lights"], recipe: Bricks = Bricks(),
          finish_optimizer: str = DEFAULTS["finish_optimizer"],
          gl_metrics: bool = True, command: str | None = None, progress: bool | None = None, device=None,
          preset: str | None = None) -> dict:
    """Write the asset folder; returns its metrics. `device`: where the DI training runs (default the CPU)."""
    from PIL import Image

    from inshade.mesh import write_torus
    from inshade.runtime.image_io import write_png

    from inshade.models.texture_cascade import compress, torch_decode
    from inshade.runtime.network import evaluate_on_pixels

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
    metrics["texture"]["total_seconds"] = round(train_seconds, 2)   # + export and the GL decode metrics
    metrics["di_torch"] = lane_metrics(torch_decode(bundle, size), lanes)
    if gl_metrics:
        for f in ("exact", "fast"):
            metrics[f"di_glsl_{f}"] = lane_metrics(evaluate_on_pixels(bundle, size, f), lanes)
        metrics["astc"] = astc_rows(set8, lanes)
        views = render_views(out)
        mask = views["_gbuffer"][0][::-1, :, 3] != 0
        metrics["render"] = {"size": render, "lights": lights, "covered_pixels": int(mask.sum()),
                             "psnr_di_vs_uncompressed": round(render_psnr(views["di"], views["uncompressed"], mask), 3)}
        from inshade.runtime.context import gl_info, shared_context

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

