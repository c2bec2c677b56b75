"""Train Deep Appearance Prefiltering decoders (Bako et al. 2022) on a procedural scene or a user's
scene file and write the asset folder the runtime renders.

Command: ``inshade train appearance_prefilter [--scene grove|forest|slabs|FILE] [--preset quick|ship]
[--scales S_MIN S_MAX] [--views V] [--mask M] [--bins BT BP] [--rays-per-texel R] [--latent Z]
[--width W] [--steps N] [--batch N] [--lr LR] [--latent-lr LR] [--seed S] [--device auto|cpu|cuda[:N]]
[--workers N | --ray auto|ADDRESS] [--cache DIR] [--out DIR]``.

1. scene.py builds the scene (normalised into the unit box; ``quick`` detail for the quick preset),
   voxels.py voxelises it at scales S_MIN..S_MAX (sparse: only cells a triangle overlaps);
2. data.py bakes per voxel V views of coverage (M x M), albedo and phase over B = BT x BP light
   bins, through the bake executor (``--workers`` / ``--ray``), cached as safetensors shards under
   ``--cache`` (a rerun resumes; default ``~/.cache/inshade/appearance_prefilter``);
3. model.py's decoders (an auto-decoder: one learned latent row per voxel in place of the paper's
   CNN encoders, plus 4 fixed raw lanes) are fitted with Adam on random (voxel, view, light bin)
   samples under the paper's loss (Eq. 19); cosine learning-rate decay to 5 %.

Asset folder (default ``trained/appearance_prefilter_<scene>``): ``bundle.json`` +
``weights.safetensors`` (kind ``appearance_prefilter``; latents stored F16 for precision f16),
``scene.json`` (program passes/appearance_prefilter.frag, network prefix "dap") and ``metrics.json``
(preset, resolved settings, bake and training seconds, losses, memory). Presets: ``ship`` (scales 3..7,
V 16, M 8, bins 4 x 8: the shipped grove, forest and, at scales 3..6, slabs) and ``quick`` (slabs at quick detail,
scales 2..3, V 4, M 4, bins 2 x 4, seconds: tests).

``--scene FILE``: a glTF 2.0 file (.glb/.gltf) or an OBJ (PLY, STL) mesh in place of a procedural
scene (user_scene.py: per-face material from the glTF's base colour, roughness and metallic; a
constant one for a mesh without materials), normalised into the unit box; the bake, the decoders
and the reference are the procedural scenes'. The file is copied into the asset (``source.glb``,
byte-identical) and the camera frames it (user_asset.py). A glTF file's scene draws the file as its
mesh with passes/appearance_prefilter_gltf.frag (``view`` prefiltered | reference | split, ...:
the file's reference shading beside the prefiltered voxels), and ``metrics.json`` adds the
prefiltered render's PSNR against that reference and against the ray-traced ``reference.exr``
(both at the scene's camera through the GL runtime); an OBJ's scene is the procedural scenes' pass.
``--detail`` belongs to the procedural scenes. An unreadable file is one ``inshade: error: FILE:
FIELD: problem`` line before any work.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from inshade.models import bake
from inshade.models.bake import BakeError
from inshade.components import ComponentError
from inshade.files import atomic_write
from inshade.geometry.gltf import GltfError
from inshade.geometry.mesh import MeshError
from inshade.scene.builder import directional_light, network, orbit, reference, requires, scene_json, sky
from inshade.trainer import GIVEN, Run, Trainer, seed_setting, setting, steps_setting
from inshade.provenance import recorded_at

from .data import DataError
from .memory import memory_report
from .model import KIND, RAW, build_decoders, losses, split_outputs
from .scene import DETAILS, SCENES, SceneError
from .user_scene import is_file_scene, scene_name
from .voxels import VoxelError


@dataclass(frozen=True)
class Settings:
    """What an appearance_prefilter run is built from (metrics.json records it)."""
    scene: str = setting("grove", f"procedural scene ({' | '.join(sorted(SCENES))}), or a glTF 2.0 / OBJ file",
                         metavar="SCENE")
    detail: str = setting("ship", "the procedural scene's level of detail", choices=DETAILS,
                          only={"scene": tuple(sorted(SCENES))})
    scales: tuple[int, ...] = setting((3, 7), "voxel scales S_MIN S_MAX, 2^s cells per axis", metavar="S")
    views: int = setting(16, "view directions baked per voxel")
    mask: int = setting(8, "coverage mask side M")
    bins: tuple[int, ...] = setting((4, 8), "phase bins BT BP in cos(theta) x phi", metavar="B")
    rays_per_texel: int = setting(1, "rays per mask texel per view")
    latent: int = setting(60, "learned latent floats per voxel (+ 4 raw; the sum a multiple of 4, at most 64)")
    width: int = setting(32, "decoder width")
    steps: int = steps_setting(24000)
    batch: int = setting(4096, "(voxel, view, light) samples per step")
    seed: int = seed_setting()
    lr: float = setting(1e-3, "decoder learning rate (Adam; the paper uses 3e-4 over days of training, this "
                        "CPU budget a larger one)")
    latent_lr: float = setting(1e-2, "latent learning rate")
    precision: str = setting("f16", "latent storage", choices=("f16", "f32"))
    weight_decay: float | None = setting(
        None, "decoupled weight decay of the decoders (AdamW; e.g. 0.1): smaller weights keep the decoders' "
        "sums small enough for fp32 summation order to hold the shader within 1e-5 of torch",
        only={"weight_decay": GIVEN})


# ship (the defaults): ~51.5k voxels (grove, scales 3..7). Measured on grove scales 3..5 (1928 voxels,
# 5000 steps of 2048): latent 28 -> 60 lowered coverage L2 0.071 -> 0.066, width 64 to 0.057 at 4x the
# decoder FLOPs in the shader (kept 32: llvmpipe renders); lr 1e-3 beat the paper's 3e-4 at this step
# count (coverage 0.092 vs 0.119 after 1000 steps). One thread: ~42 ms per step of 4096: ~17 min of
# training. quick: a tiny bake and fit, seconds (tests).
PRESETS = {"quick": dict(scene="slabs", detail="quick", scales=(2, 3), views=4, mask=4, bins=(2, 4), latent=28,
                         steps=150, batch=512),
           "ship": {}}
# The inputs of each shipped asset (--scene beside --preset ship).
# forest: the paper's size class (1.3 M triangles; bake + train ~30 min with --workers 2). slabs: the
# hidden-occlusion case alone, scales 3..6 (its 96 faces fit any budget past those; scale 7 would
# quadruple the voxels of flat faces).
# The slabs' exactly binary masks grew the coverage decoder's sums (its head to ~570) until fp32
# summation order alone put the shader's coverage 1.5e-5 from torch's; weight decay 0.1 keeps the
# head's sums near 170 and the error at 8.7e-6, and lowers the phase loss (0.041 -> 0.031; coverage
# 0.036 -> 0.038).
SHIP_ASSETS = {f"{KIND}_grove": dict(scene="grove"), f"{KIND}_forest": dict(scene="forest"),
               f"{KIND}_slabs": dict(scene="slabs", scales=(3, 6), weight_decay=0.1)}
BLOCKS = 3
VIEW_FREQS = 4
LIGHT_FREQS = 4
PREFIX = "dap"
PROGRAM = "passes/appearance_prefilter.frag"


class TrainError(ValueError):
    """Bad training input; the message names the option."""


# ---------------------------------------------------------------------------------------------
# data

def prefilter_scene(settings: dict):
    """The PrefilterScene a run's settings name: the procedural scene at its detail, or the file's."""
    from .scene import build_scene
    from .user_scene import load_user_scene

    if is_file_scene(settings["scene"]):
        return load_user_scene(settings["scene"]).scene
    return build_scene(settings["scene"], settings["detail"])


def bake_data(settings: dict, *, executor=None, cache_dir=None, progress=None) -> dict:
    """Scene -> voxels -> the baked per-voxel arrays (data.py), plus "bake_seconds"."""
    from .data import bake_voxel_data
    from .voxels import voxelise

    started = time.perf_counter()
    scene = prefilter_scene(settings)
    cells, spheres = voxelise(scene, *settings["scales"])
    data = bake_voxel_data(scene, cells, spheres, views=settings["views"], mask=settings["mask"],
                           bins=tuple(settings["bins"]), rays_per_texel=settings["rays_per_texel"],
                           seed=settings["seed"], executor=executor, cache_dir=cache_dir, progress=progress)
    data["bake_seconds"] = time.perf_counter() - started
    data["faces"] = len(scene.mesh.faces)
    return data


class Samples:
    """The baked arrays on the training device, flattened for random (voxel, view, bin) draws."""

    def __init__(self, data: dict, device):
        n, v = data["views"].shape[:2]
        self.n, self.v, self.bins = n, v, data["phase"].shape[-1]
        t = lambda a: torch.from_numpy(np.ascontiguousarray(a, np.float32)).to(device)  # noqa: E731
        self.views = t(data["views"]).reshape(n * v, 3)
        self.coverage = t(data["coverage"]).reshape(n * v, -1)
        self.albedo = t(data["albedo"]).reshape(n * v, 3)
        self.light = t(data["light_local"]).reshape(n * v, self.bins, 3)
        self.phase = t(data["phase"]).reshape(n * v, self.bins)
        self.device = device

    def batch(self, index: torch.Tensor, bin_index: torch.Tensor):
        """Inputs [k, 7] (slot, view, light) and the targets of samples `index` (voxel * V + view)
        queried at light bins `bin_index`."""
        slot = torch.div(index, self.v, rounding_mode="floor").to(torch.float32)
        light = self.light[index, bin_index]
        x = torch.cat([slot[:, None], self.views[index], light], 1)
        return x, (self.coverage[index], self.albedo[index], self.phase[index, bin_index], self.phase[index])

    def draw(self, k: int, gen: torch.Generator):
        index = torch.randint(0, self.n * self.v, (k,), generator=gen).to(self.device)
        bin_index = torch.randint(0, self.bins, (k,), generator=gen).to(self.device)
        return self.batch(index, bin_index)


def evaluate(graph, samples: Samples, mask: int, limit: int = 1 << 18, chunk: int = 8192) -> dict:
    """Eq. 19's terms (each a mean over its samples) over every (voxel, view, light bin), or over
    ``limit`` of them drawn with a fixed seed when there are more; plus, on the views that hit, the
    plain phase MSE and the ratio of mean predicted to mean reference phase and slice (1 = unbiased:
    the relative MSE alone is dominated by the one-sample targets' noise)."""
    total = samples.n * samples.v * samples.bins
    if total <= limit:
        flat = torch.arange(total)
    else:
        flat = torch.randint(0, total, (limit,), generator=torch.Generator().manual_seed(12345))
    sums, weights = {}, {}

    def acc(key, value, weight):
        sums[key] = sums.get(key, 0.0) + float(value) * weight
        weights[key] = weights.get(key, 0.0) + weight

    with torch.no_grad():
        for part in flat.split(chunk):
            part = part.to(samples.device)
            x, (cov, alb, ph, bins) = samples.batch(torch.div(part, samples.bins, rounding_mode="floor"),
                                                    part % samples.bins)
            pred = split_outputs(graph(x), mask, samples.bins)
            hit = (cov > 0).any(-1)
            k = int(hit.sum())
            for name, val in losses(pred, cov, alb, ph, bins).items():
                if name != "total":
                    acc(name, val, len(part) if name == "coverage" else k)
            if k:
                acc("phase_mse", (pred["phase"][hit] - ph[hit]).square().mean(), k)
                acc("phase_pred_sum", pred["phase"][hit].sum(), 1)
                acc("phase_ref_sum", ph[hit].sum(), 1)
                acc("slice_pred_sum", pred["slice"][hit].sum(), 1)
                acc("slice_ref_sum", bins[hit].sum() * (4.0 * math.pi / samples.bins), 1)
    out = {k: round(v / weights[k], 7) for k, v in sums.items() if not k.endswith("_sum")}
    out["total"] = round(sum(out.get(k, 0.0) for k in ("coverage", "phase", "albedo", "slice")), 7)
    for name in ("phase", "slice"):
        ref = sums.get(f"{name}_ref_sum", 0.0)
        out[f"{name}_mean_ratio"] = round(sums.get(f"{name}_pred_sum", 0.0) / ref, 5) if ref else None
    out["samples"] = int(len(flat))
    return out


# ---------------------------------------------------------------------------------------------
# training

def fit(data: dict, settings: dict, *, device, progress=None, log_every: int = 25):
    """(graph on the CPU, history) after ``settings["steps"]`` Adam steps."""
    from inshade.models.fit_loop import adam, fit as fit_steps

    mask, bins = settings["mask"], settings["bins"][0] * settings["bins"][1]
    torch.manual_seed(settings["seed"])
    graph = build_decoders(data, data["cells"], data["spheres"], latent=settings["latent"], raw=RAW,
                           width=settings["width"], blocks=BLOCKS, mask=mask, bins=bins, view_freqs=VIEW_FREQS,
                           light_freqs=LIGHT_FREQS, precision=settings["precision"],
                           scale_min=settings["scales"][0], scale_max=settings["scales"][1],
                           seed=settings["seed"]).to(device)
    samples = Samples(data, device)
    latents = graph.nodes["vox"].latents
    rest = [p for name, p in graph.named_parameters() if not name.startswith("nodes.vox.")]
    opt = adam([{"params": [latents], "lr": settings["latent_lr"]},
                {"params": rest, "lr": settings["lr"], "weight_decay": settings.get("weight_decay") or 0.0}],
               decoupled_weight_decay=True)
    gen = torch.Generator().manual_seed(settings["seed"])
    steps, history = settings["steps"], []

    def step_loss(step):
        x, (cov, alb, ph, ph_bins) = samples.draw(settings["batch"], gen)
        terms = losses(split_outputs(graph(x), mask, bins), cov, alb, ph, ph_bins)
        return terms["total"], terms

    def after(step, returned, bar):
        terms = returned[1]
        if step % log_every == 0 or step == steps - 1:
            history.append({"step": step, **{k: round(v.item(), 6) for k, v in terms.items()}})
            bar.set_postfix(loss=f"{terms['total'].item():.4f}")

    def cosine(step):   # to 5 %, its angle rounded as (pi * step) / steps: what the shipped assets trained with
        return 0.05 + 0.95 * 0.5 * (1 + math.cos(math.pi * step / max(steps, 1)))

    fit_steps(opt, step_loss, steps, lr_factor=cosine, after_step=after, desc=f"{KIND} {settings['scene']}",
              progress=progress)
    return graph.to("cpu"), history


def train(run: Run) -> int:
    """Bake, fit and write the asset folder ``run.out``."""
    executor = bake.executor_from_args(run.args)
    settings, preset, device, out = dataclasses.asdict(run.settings), run.preset, run.device, run.out
    cache = Path(run.args.cache) if run.args.cache else Path.home() / ".cache" / "inshade" / KIND
    data = bake_data(settings, executor=executor, cache_dir=cache)
    started = time.perf_counter()
    graph, history = fit(data, settings, device=device)
    train_seconds = time.perf_counter() - started
    quality = evaluate(graph, Samples(data, "cpu"), settings["mask"])
    bt, bp = settings["bins"]
    provenance = {"command": run.command, "preset": preset, **settings, "voxels": int(len(data["cells"])),
                  "faces": int(data["faces"]), "torch": torch.__version__, "device": str(device),
                  **recorded_at()}
    user = None
    render = {"mask": settings["mask"], "bins": bt * bp, "bins_theta": bt, "bins_phi": bp}
    if is_file_scene(settings["scene"]):
        from .user_scene import load_user_scene

        user = load_user_scene(settings["scene"])
        if user.kind == "gltf":    # the file's map into the voxels' box (passes/appearance_prefilter_gltf.frag)
            render["world"] = user.world
    bundle = graph.export(KIND, scene_name(settings["scene"]), provenance=provenance, metrics=quality, render=render)
    if settings["precision"] == "f16":   # fp16 latents (what an RGBA16F texture holds) stored as F16
        bundle.tensors = {k: (v.astype(np.float16) if k == "vox.latents" else v) for k, v in bundle.tensors.items()}
    out.mkdir(parents=True, exist_ok=True)
    bundle.save(out)
    if user is None:
        write_reference(out, settings, preset)
        atomic_write(out / "scene.json", json.dumps(scene_description(out.name, settings), indent=2) + "\n")
    else:
        from .user_asset import write_user_scene

        write_user_scene(out, settings, user, scene_description(out.name, settings), REFERENCE_SPP[preset])
    counts = data["ray_counts"]
    m = {"device": str(device), "train_threads": torch.get_num_threads(), "voxels": int(len(data["cells"])),
         "voxels_per_scale": {str(s): int((data["cells"][:, 0] == s).sum())
                              for s in range(settings["scales"][0], settings["scales"][1] + 1)},
         "faces": int(data["faces"]), "bake_seconds": round(float(data["bake_seconds"]), 2),
         "bake_rays": {"primary": int(counts[0]), "shadow": int(counts[1])},
         "train_seconds": round(train_seconds, 2), "losses": quality, "memory": memory_report(bundle),
         "history": history}
    if user is not None:
        from .user_asset import compare_with_references

        m["user_scene"] = {"file": settings["scene"], "kind": user.kind, "notes": user.notes}
        started = time.perf_counter()
        m["reference"] = compare_with_references(out)
        m["reference_seconds"] = round(time.perf_counter() - started, 2)
    run.write_metrics(m)
    q, mem = m["losses"], m["memory"]
    print(f"wrote {out}: {m['voxels']} voxels; loss {q['total']:.4f} (coverage {q['coverage']:.4f}, albedo "
          f"{q['albedo']:.4f}, phase {q['phase']:.4f}, slice {q['slice']:.4f}); {mem['bytes_per_voxel']:.0f} B/voxel; "
          f"bake {m['bake_seconds']:.0f} s, training {m['train_seconds']:.0f} s")
    for name, r in m.get("reference", {}).items():
        if isinstance(r, dict):
            print(f"  PSNR against the {name} reference at the scene's camera: {r['psnr']:.2f} dB")
    return 0


# seen from afar, aimed at the objects (they span about half the picture: the regime prefiltering is
# for, a frame llvmpipe draws in about half a minute at 320^2); the "distance" setting dollies in
# (0.5 is the close-up) and out
CAMERA = orbit((0.5, 0.32, 0.5), 4.4, 30.0, -20.0, fov_y=35.0)
SUN = directional_light((0.4, 0.8, 0.45), 3.0)
SKY = sky("overcast", degree=3)
SIZE = (320, 320)
REFERENCE = "reference.exr"
REFERENCE_SPP = {"quick": 4, "ship": 64}   # the quick preset's reference only has to exist (tests)


def write_reference(out: Path, settings: dict, preset: str) -> Path:
    """The full geometry ray traced (reference.py) at the scene's camera, size, sun and sky, distance 1:
    the display's reference, so the viewer's split / error modes show prefiltered | supersampled mesh
    at the default view (a moved camera or another distance no longer matches it)."""
    from inshade.codegen.sdf import environment_sh
    from inshade.scene.image_io import write_exr

    from .reference import render_reference
    from .scene import build_scene

    image = render_reference(build_scene(settings["scene"], settings["detail"]), CAMERA, SIZE,
                             spp=REFERENCE_SPP[preset], sun_dir=SUN["direction"], sun_radiance=SUN["intensity"],
                             env_sh=environment_sh(SKY["sky"], SKY["rotation"], SKY["degree"]), seed=settings["seed"])
    return write_exr(out / REFERENCE, image)


def scene_description(name: str, settings: dict) -> dict:
    from . import SETTINGS

    return scene_json(
        name, f"Deep appearance prefiltering: {settings['scene']}, scales {settings['scales'][0]}.."
              f"{settings['scales'][1]} (voxel latents + coverage/albedo/phase decoders)",
        PROGRAM, SIZE,
        networks=[network(".", PREFIX)],
        reference=reference(REFERENCE, "linear", "screen"),
        camera=CAMERA,
        lights=[SUN],
        environment=SKY,
        settings={**SETTINGS, "force_scale": {**SETTINGS["force_scale"], "max": settings["scales"][1]}},
        requires=requires(),
        notes="the voxels are marched at the scale the pixel footprint asks for (next finer, blended with "
              "the coarser); 'distance' moves the camera away from the box centre; the reference is the "
              "full geometry ray traced at this camera and distance 1 (display modes split / error)",
    )


# ---------------------------------------------------------------------------------------------
# command line

def extra_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--cache", help="bake shard cache folder (default: ~/.cache/inshade/appearance_prefilter)")
    bake.add_arguments(parser)


def check(s: Settings) -> None:
    """A bad setting: TrainError naming the option (a scene file that cannot be read: the reader's
    own one-line error, before any work)."""
    for name in ("views", "mask", "rays_per_texel", "width", "batch"):
        if getattr(s, name) < 1:
            raise TrainError(f"--{name.replace('_', '-')}: must be >= 1, got {getattr(s, name)}")
    if s.steps < 0:
        raise TrainError(f"--steps: must be >= 0, got {s.steps}")
    if len(s.bins) != 2 or min(s.bins) < 1:
        raise TrainError(f"--bins: BT and BP must be >= 1, got {' '.join(map(str, s.bins))}")
    if len(s.scales) != 2 or not 0 <= s.scales[0] <= s.scales[1] <= 9:
        raise TrainError(f"--scales: need 0 <= S_MIN <= S_MAX <= 9, got {' '.join(map(str, s.scales))}")
    if s.latent < 0 or (s.latent + RAW) % 4 or s.latent + RAW > 64:
        raise TrainError(f"--latent: {s.latent} + {RAW} raw lanes must be a multiple of 4, at most 64")
    for name in ("lr", "latent_lr"):
        if not (math.isfinite(getattr(s, name)) and getattr(s, name) > 0):
            raise TrainError(f"--{name.replace('_', '-')}: must be > 0, got {getattr(s, name)}")
    if s.weight_decay is not None and not (math.isfinite(s.weight_decay) and s.weight_decay >= 0):
        raise TrainError(f"--weight-decay: must be >= 0, got {s.weight_decay}")
    if is_file_scene(s.scene):     # last: the file is read whole
        from .user_scene import load_user_scene

        if not Path(s.scene).exists():
            raise TrainError(f"--scene: {s.scene}: no such file (the procedural scenes: {', '.join(sorted(SCENES))})")
        load_user_scene(s.scene)


TRAINER = Trainer(KIND, __doc__, Settings, PRESETS, train, folder=lambda s: f"{KIND}_{scene_name(s.scene)}",
                  folder_hint=f"{KIND}_<scene>",
                  default_preset="ship", ship_assets=SHIP_ASSETS, extra_arguments=extra_arguments, check=check,
                  errors=(TrainError, ComponentError, BakeError, DataError, SceneError, VoxelError, GltfError,
                          MeshError))
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
