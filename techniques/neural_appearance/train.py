"""Bake a reference material into a neural material (Real-Time Neural Appearance Models §3).

Command: ``inshade train neural_appearance [--material ceramic|brushed_metal|FILE.json] [--gltf FILE
[--material INDEX]] [--preset quick|ship] [--device auto|cpu|cuda[:N]] [--out DIR] [--resolution N]
[--steps1 N] [--steps2 N] [--seed S] [--restart]``. ``--preset ship`` is what built
``trained/neural_appearance_<material>``; ``quick`` is the same pipeline at 32x32 for a few seconds
(tests). Options given explicitly override the preset.

The reference (sources.py): one of the technique's layered materials, or with ``--gltf FILE`` the
material of a glTF file (``--material INDEX``, default the one covering most faces) under the spec's
BRDF with its clearcoat, sheen and anisotropy lobes, over the uv box its faces use (gltf_source.py).

Training (one run per material; every network shares one latent pyramid):
- **samples online** (§3.1): uv uniform; the pyramid level drawn from an exponential distribution
  favouring fine levels (§3.3); directions half of the time from uniformly sampled half and
  difference vectors (Rusinkiewicz), half cosine-weighted pairs; both above the horizon;
- **prefiltered targets** (§3.3): the reference averaged over uv points drawn from a Gaussian
  matching the level's footprint (1 point at level 0, ``--footprint-samples`` above), and over a
  cone of light directions whose angle shrinks to 0 (the mollification curriculum, §3.4);
- **losses** (§3.5): L1 between the decoders' output and log(1 + target) — the three decoders
  (2x16, 2x32, 3x64) are trained together on the same latents; for the samplers (learned and
  isotropic) the KL divergence from the current 3x64 decoder's cosine-weighted BRDF to the proxy
  density, estimated with directions drawn half from the proxy and half cosine-weighted (a
  defensive mixture, so a lobe the proxy misses still gets samples), with the latents detached;
- **two phases** (§3.2): phase 1 trains the encoder (material parameters -> latents, LEAN-
  prefiltered for coarse levels) end to end; then every texel of every level is encoded into the
  latent pyramid, the encoder is dropped and phase 2 fine-tunes the latents and the decoders.
- Adam, cosine learning-rate decay per phase; a checkpoint every ``--checkpoint-every`` steps in the
  output folder (resumed by the same command unless ``--restart``; removed when done).

Writes the asset folder: one bundle per network (``latents/``, ``decoder_2x16/`` ...), the material
description and its parameter textures (for the reference shader), ``scene.json`` (the teapot),
``metrics.json`` (with the rebuild command) and ``preview.png``. From a glTF file: the file
(``source.glb``) and ``gltf_material.json`` in place of the description and textures, a scene.json of
the file's mesh showing the neural material next to the file's shading, and in metrics.json the
render PSNR against it at the scene's camera (``render``, gltf_scene.py).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import shlex
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from inshade import asset_folder
from inshade.devices import resolve_device
from inshade.files import atomic_write
from inshade.models.checkpoint import read_checkpoint, write_checkpoint
from inshade.models.fit_loop import adam, cosine, fit, learning_rates
from inshade.components.latent_pyramid.torch_twin import LatentPyramid
from inshade.provenance import recorded_at
from inshade.trainer import GIVEN, Run, Trainer, finetune_setting, precision_setting, seed_setting, setting

from . import KIND, NETWORKS

from .data import Targets, direction_pairs, draw_levels
from .model import LATENT, NeuralMaterial, decoder_loss, export_graphs, sampler_loss
from .sources import open_source

MATERIALS = ("ceramic", "brushed_metal")
CHECKPOINT = "checkpoint.safetensors"
GLTF_SUFFIXES = (".glb", ".gltf")


@dataclass(frozen=True)
class Settings:
    """What a neural_appearance run is built from (metrics.json records it, a description file's
    material by its name, a glTF file's by its index)."""
    material: str | None = setting(None, f"{' | '.join(MATERIALS)} or a material description .json (none given: "
                                         "ceramic); with --gltf, the index of the file's material (none given: "
                                         "the one covering most faces)")
    gltf: str | None = setting(None, "learn the material of this glTF 2.0 file (.glb or .gltf) on its own mesh",
                               metavar="FILE", only={"gltf": GIVEN})   # a run without one records what it always did
    resolution: int = setting(512, "finest latent/texture side, a power of two")
    steps1: int = setting(10000, "phase 1 (encoder) steps")
    steps2: int = setting(20000, "phase 2 (latent fine-tuning) steps")
    batch: int = setting(4096, "BRDF samples per step")
    sampler_batch: int = setting(512, "samples per step of the samplers' KL loss")
    sampler_samples: int = setting(8, "directions per sample of the samplers' KL estimate")
    footprint_samples: int = setting(8, "uv points averaged per prefiltered target above level 0")
    seed: int = seed_setting()
    lr: float = setting(2e-3, "encoder and network learning rate (Adam)")
    latent_lr: float = setting(1e-3, "phase 2 latent learning rate (Adam)")
    level_scale: float = setting(1.5, "scale of the exponential level distribution (favouring fine levels)")
    mollify_degrees: float = setting(12.0, "light cone of the phase 1 targets, shrinking to 0")
    precision: str | None = precision_setting(None, only={"precision": GIVEN})
    finetune_steps: int = finetune_setting(only={"precision": GIVEN})


# "ship" (the defaults) built trained/neural_appearance_*; "quick" is the same pipeline at 32x32
# for a few seconds (tests).
PRESETS = {"quick": dict(resolution=32, steps1=30, steps2=30, batch=512, sampler_batch=64, sampler_samples=4,
                         footprint_samples=4),
           "ship": {}}
# The inputs of each shipped asset (--material beside --preset ship). Both materials keep improving
# with steps at a batch of 4096, more than with the batch at equal samples (brushed metal 3x64:
# 26.5 / 27.5 / 29.9 dB at 4k / 15k / 30k steps; ceramic 2x32: 28.3 -> 38.9 dB from 15k to 30k).
SHIP_ASSETS = {f"neural_appearance_{m}": dict(material=m) for m in MATERIALS}


# ---------------------------------------------------------------------------------------------
# checkpoints

def _save_checkpoint(path: Path, model, opt, phase: int, step: int, config: dict) -> None:
    tensors = {f"model.{k}": v for k, v in model.state_dict().items()}
    state = opt.state_dict()
    for idx, st in state["state"].items():
        for key, value in st.items():
            tensors[f"opt.{idx}.{key}"] = torch.as_tensor(value).reshape(-1).float() if key == "step" else value
    groups = [{k: v for k, v in g.items() if k != "params"} for g in state["param_groups"]]
    write_checkpoint(path, "neural_appearance", tensors, config, phase=phase, step=step, groups=json.dumps(groups))


def _load_checkpoint(path: Path, config: dict):
    """(phase, step, tensors, groups); ValueError naming the field if it belongs to another run."""
    tensors, meta = read_checkpoint(path, "neural_appearance", config, "pass --restart to start over")
    return int(meta["phase"]), int(meta["step"]), tensors, json.loads(meta["groups"])


def _restore(model, opt, tensors, groups) -> None:
    model.load_state_dict({k[6:]: v for k, v in tensors.items() if k.startswith("model.")})
    state = {"state": {}, "param_groups": []}
    params = [p for g in opt.param_groups for p in g["params"]]
    start = 0
    for g, saved in zip(opt.param_groups, groups):
        ids = list(range(start, start + len(g["params"])))
        state["param_groups"].append({**saved, "params": ids})
        start += len(g["params"])
    for i in range(len(params)):
        st = {}
        for key in ("step", "exp_avg", "exp_avg_sq"):
            t = tensors.get(f"opt.{i}.{key}")
            if t is not None:
                st[key] = t.reshape(()) if key == "step" else t
        if st:
            state["state"][i] = st
    opt.load_state_dict(state)


# ---------------------------------------------------------------------------------------------
# training

def _optimizer(model: NeuralMaterial, phase: int, lr: float, latent_lr: float):
    nets = [p for name, p in model.named_parameters() if not name.startswith(("pyramid.", "encoder."))]
    if phase == 1:
        groups = [{"params": list(model.encoder.parameters()), "lr": lr}, {"params": nets, "lr": lr}]
    else:
        groups = [{"params": list(model.pyramid.parameters()), "lr": latent_lr}, {"params": nets, "lr": lr}]
    return adam(groups, eps=1e-15)


def _phase_loss(model: NeuralMaterial, s: Settings, targets: Targets, encoder_inputs, levels: int, phase: int,
                steps: int, device):
    """Step -> (decoders' loss + 0.1 x sampler loss, decoder terms, sampler terms) on the step's own
    seeded batch: phase 1 decodes the encoder's latents, phase 2 the pyramid's."""
    def step_loss(step):
        gen = torch.Generator().manual_seed(s.seed * 1_000_003 + phase * 100_000 + step)
        uv = torch.rand(s.batch, 2, generator=gen).to(device)
        level = draw_levels(s.batch, levels, s.level_scale, gen).to(device)
        light, view = (d.to(device) for d in direction_pairs(s.batch, gen))
        cone = math.radians(s.mollify_degrees) * max(0.0, 1.0 - 2.0 * (step / max(steps, 1))) if phase == 1 else 0.0
        with torch.no_grad():
            target = targets(uv, level, light, view, s.footprint_samples, cone, gen)
        if phase == 1:
            z = model.encoder(encoder_inputs(torch.cat([uv, level[:, None].float()], -1)))
        else:
            z = model.pyramid(torch.cat([uv, level[:, None].float()], -1))
        loss, parts = decoder_loss(model, z, light, view, target)
        s_loss, s_parts = sampler_loss(model, z[:s.sampler_batch], view[:s.sampler_batch], s.sampler_samples, gen)
        return loss + 0.1 * s_loss, parts, s_parts
    return step_loss


def encode_pyramid(model: NeuralMaterial, encoder_levels: list[torch.Tensor]) -> list[torch.Tensor]:
    """Phase 2's initial latents: the encoder run on every texel of every level (§3.2)."""
    with torch.no_grad():
        return [model.encoder(t.reshape(-1, t.shape[-1])).reshape(*t.shape[:2], LATENT) for t in encoder_levels]


def train(*, material=None, gltf=None, preset="ship", out=None, resolution=None, steps1=None, steps2=None,
          batch=None, sampler_batch=None, sampler_samples=None, footprint_samples=None, seed=None, device="cpu",
          lr=None, latent_lr=None, level_scale=None, mollify_degrees=None, precision=None, finetune_steps=None,
          checkpoint_every=250,
          restart=False, progress=None, command_line=None, write_preview=True, render_spp=16,
          render_decoders=(32,)) -> Path:
    """Train and write the asset folder; returns it. The keyword form of ``inshade train
    neural_appearance``: a setting left None is the preset's (``material`` None: ceramic, or with
    ``gltf`` the material covering most faces). `device`: a torch.device or a --device spelling
    (auto, cpu, cuda, cuda:N)."""
    given = dict(material=None if material is None else str(material), gltf=None if gltf is None else str(gltf),
                 resolution=resolution, steps1=steps1, steps2=steps2, batch=batch,
                 sampler_batch=sampler_batch, sampler_samples=sampler_samples, footprint_samples=footprint_samples,
                 seed=seed, lr=lr, latent_lr=latent_lr, level_scale=level_scale, mollify_degrees=mollify_degrees,
                 precision=precision, finetune_steps=finetune_steps)
    settings = Settings(**{**TRAINER.defaults(preset), **{k: v for k, v in given.items() if v is not None}})
    check(settings)
    source = open_source(settings.material, settings.gltf)
    out = Path(out) if out else asset_folder.default(_folder(settings))
    device = resolve_device(device) if isinstance(device, str) else torch.device(device)
    command_line = command_line or _command_line(preset, out, settings, source.setting)
    options = argparse.Namespace(checkpoint_every=checkpoint_every, restart=restart, no_preview=not write_preview,
                                 render_spp=render_spp, render_decoders=tuple(render_decoders))
    fit_material(Run(settings, preset, device, out, command_line, options), progress)
    return out


def fit_material(run: Run, progress=None) -> dict:
    """Train on ``run.settings`` and write the asset folder ``run.out`` (metrics.json through the
    run, then preview.png unless --no-preview); returns the metrics beside the run's record."""
    from inshade.trainer import recorded

    source = open_source(run.settings.material, run.settings.gltf)
    run = dataclasses.replace(run, settings=dataclasses.replace(run.settings, material=source.setting))
    s, out, device, checkpoint_every = run.settings, run.out, run.device, run.args.checkpoint_every
    resolution, steps1, steps2, seed, lr, latent_lr = s.resolution, s.steps1, s.steps2, s.seed, s.lr, s.latent_lr
    levels = int(math.log2(resolution)) + 1
    config = recorded(s)

    torch.manual_seed(seed)
    raw = source.bake(resolution)
    # the encoder inputs per level, looked up like latents (bilinear within a level, repeat); fixed data
    encoder_inputs = LatentPyramid.from_arrays(source.encoder_levels(raw, levels)).requires_grad_(False).to(device)
    enc_levels = [encoder_inputs.level(k) for k in range(levels)]
    targets = Targets(source, raw, device)
    model = NeuralMaterial(source.encoder_inputs, resolution, levels).to(device)

    ckpt = out / CHECKPOINT
    start_phase, start_step, saved = 1, 0, None
    if ckpt.is_file() and not run.args.restart:
        start_phase, start_step, tensors, groups = _load_checkpoint(ckpt, config)
        saved = (tensors, groups)
        print(f"resuming {ckpt}: phase {start_phase}, step {start_step}")
    history = {"phase1": [], "phase2": []}
    started = time.perf_counter()
    for phase, steps in ((1, steps1), (2, steps2)):
        if phase < start_phase:
            continue
        if phase == 2 and model.pyramid is None:
            if saved is not None and start_phase == 2:
                shapes = [(resolution >> k, resolution >> k, LATENT) for k in range(levels)]
                model.make_pyramid([torch.zeros(s) for s in shapes])
            else:
                model.make_pyramid(encode_pyramid(model, enc_levels))
            model.pyramid.to(device)
            if checkpoint_every and saved is None:
                _save_checkpoint(ckpt, model, _optimizer(model, 2, lr, latent_lr), 2, 0, config)
        opt = _optimizer(model, phase, lr, latent_lr)
        base = learning_rates(opt)       # a restored state holds decayed rates; the schedule starts from these
        first = 0
        if saved is not None and phase == start_phase:
            _restore(model, opt, *saved)
            first, saved = start_step, None

        def after(step, returned, bar, phase=phase, steps=steps):
            _, parts, s_parts = returned
            if step % 25 == 0 or step == steps - 1:
                history[f"phase{phase}"].append({"step": step, **{f"l1_{k}": round(v, 5) for k, v in parts.items()},
                                                 **{f"kl_{k}": round(v, 5) for k, v in s_parts.items()}})
                bar.set_postfix(l1=f"{parts['3x64']:.4f}")

        fit(opt, _phase_loss(model, s, targets, encoder_inputs, levels, phase, steps, device), steps, start=first,
            lr_factor=cosine(steps), base_lrs=base, after_step=after, checkpoint_every=checkpoint_every,
            checkpoint=lambda done, phase=phase, opt=opt: _save_checkpoint(ckpt, model, opt, phase, done, config),
            checkpoint_last=False, desc=f"neural_appearance {source.name} phase {phase}", progress=progress)
    if model.pyramid is None:     # steps2 == 0: latents straight from the encoder
        model.make_pyramid(encode_pyramid(model, enc_levels))
    if s.precision not in (None, "f32"):
        history["holdout_quantized_without_finetune"], history["holdout"] = finetune(
            model, s, targets, encoder_inputs, levels, device, progress)
    else:
        history["holdout"] = holdout(model, targets, levels, device, seed)
    seconds = time.perf_counter() - started
    sizes = write_asset(out, model, source, raw, config, run.command, run.preset, device, s.precision)
    metrics = {"train_seconds": round(seconds, 1), "train_threads": torch.get_num_threads(), "device": str(device),
               "bundle_bytes": sizes, "history": history}
    spp = getattr(run.args, "render_spp", 16)
    metrics.update(source.render_metrics(out, spp, getattr(run.args, "render_decoders", (32,))))
    run.write_metrics(metrics)
    ckpt.unlink(missing_ok=True)
    if not run.args.no_preview:
        render_preview(out, spp=spp if run.settings.gltf is not None else 4)
    return metrics


def finetune(model: NeuralMaterial, s: Settings, targets: Targets, encoder_inputs, levels: int, device,
             progress=None) -> tuple[dict, dict]:
    """The quantization-aware fine-tune (precision below f32): ``finetune_steps`` more phase-2 steps at a
    tenth of the rates, the networks' dense weights (and at i8 the latents' u8 codes) seen as
    ``precision`` stores them (models/quantize_aware.py). Returns the holdout before and after it, both
    of the quantized networks."""
    from inshade.models.quantize_aware import quantizer_in_loop

    steps = s.finetune_steps
    with quantizer_in_loop(model, s.precision):
        before = holdout(model, targets, levels, device, s.seed)
        opt = _optimizer(model, 2, s.lr / 10, s.latent_lr / 10)
        fit(opt, _phase_loss(model, s, targets, encoder_inputs, levels, 3, steps, device), steps,
            lr_factor=cosine(steps), desc=f"quantization-aware fine-tune ({s.precision})", progress=progress)
        after = holdout(model, targets, levels, device, s.seed)
    return before, after


def holdout(model: NeuralMaterial, targets: Targets, levels: int, device, seed: int, n: int = 8192) -> dict:
    """L1 (log space) of each decoder on fixed samples the training never drew, per level 0..2."""
    out = {}
    for level in range(min(3, levels)):
        gen = torch.Generator().manual_seed(10_000_019 + seed + level)
        uv = torch.rand(n, 2, generator=gen).to(device)
        lv = torch.full((n,), level, dtype=torch.long, device=device)
        light, view = (d.to(device) for d in direction_pairs(n, gen))
        with torch.no_grad():
            target = targets(uv, lv, light, view, 16, 0.0, gen)
            z = model.pyramid(torch.cat([uv, lv[:, None].float()], -1))
            _, parts = decoder_loss(model, z, light, view, target)
        out[f"level{level}"] = {k: round(v, 5) for k, v in parts.items()}
    return out


# ---------------------------------------------------------------------------------------------
# the asset

def write_asset(out: Path, model: NeuralMaterial, source, raw, config, command_line, preset, device,
                precision: str | None = None) -> dict:
    """The bundles (stored at ``precision`` where given: inshade/quantize.py), what the reference shader
    reads (sources.py ``write_files``), scene.json; returns each bundle's bytes."""
    from inshade.quantize import quantized

    out.mkdir(parents=True, exist_ok=True)
    provenance = {"command": command_line, "preset": preset, "material": source.name, **config,
                  "torch": torch.__version__, "device": str(device),
                  **recorded_at()}
    graphs = export_graphs(model.to("cpu"))
    sizes = {}
    for folder, _prefix in NETWORKS:
        bundle = graphs[folder].export(KIND, folder, provenance=provenance)
        if precision not in (None, "f32"):   # the values the fine-tune saw
            bundle = quantized(bundle, precision)
        if folder == "latents":   # fp16 texels (what RGBA16F holds) stored as F16: half the file, widened exactly at load
            bundle.tensors = {k: v.astype(np.float16) if v.dtype == np.float32 and ".level" in k else v
                              for k, v in bundle.tensors.items()}
        bundle.save(out / folder)
        sizes[folder] = int(sum(np.asarray(t).nbytes for t in bundle.tensors.values()))
    source.write_files(out, raw)
    atomic_write(out / "scene.json", json.dumps(source.scene(out), indent=2) + "\n")
    return sizes


def render_preview(out: Path, spp: int = 4) -> None:
    """preview.png (+ sidecar): the asset's scene, split view (left reference, right neural)."""
    from inshade.runtime.headless import render_scene, save_render

    image, info = render_scene(out, spp=spp, settings={"view": "split"})
    save_render(image, info, out / "preview.png")
    Path(f"{out / 'preview.png'}.json").unlink()   # a shipped picture: its sidecar would hold this machine's paths


def _folder(s: Settings) -> str:
    """The default asset folder's name: the layered material's, or the glTF file's (and the index
    when one is given)."""
    if s.gltf is not None:
        return f"neural_appearance_{Path(s.gltf).stem}" + ("" if s.material is None else f"_{s.material}")
    return f"neural_appearance_{Path(s.material or 'ceramic').stem}"


def _command_line(preset, out, settings: Settings, material: str) -> str:
    """The keyword form's command: the options that differ from the preset's."""
    parts = ["inshade", "train", "neural_appearance"]
    if settings.gltf is not None:
        parts += ["--gltf", str(settings.gltf)]
    parts += ["--material", str(material), "--preset", preset]
    if Path(out) != asset_folder.default(_folder(settings)):
        parts += ["--out", str(out)]
    preset_values = TRAINER.defaults(preset)
    for key in ("resolution", "steps1", "steps2", "seed"):
        if getattr(settings, key) != preset_values[key]:
            parts += [f"--{key.replace('_', '-')}", str(getattr(settings, key))]
    return shlex.join(parts)


# ---------------------------------------------------------------------------------------------
# command line

def extra_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--checkpoint-every", type=int, default=250,
                        help="steps between checkpoints, 0 for none (default: %(default)s)")
    parser.add_argument("--restart", action="store_true", help="ignore a checkpoint in the output folder")
    parser.add_argument("--no-preview", action="store_true", help="skip rendering preview.png")
    parser.add_argument("--render-spp", type=_positive, default=16,
                        help="with --gltf: samples per pixel of the metric renders and the preview (default "
                             "%(default)s)")
    parser.add_argument("--render-decoders", type=_decoders, default=(32,), metavar="16,32,64",
                        help="with --gltf: the decoders whose renders are measured against the reference (default "
                             "32, the scene's; llvmpipe compiles 3x64 for about a minute)")


def _positive(text: str) -> int:
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return int(text)


def _decoders(text: str) -> tuple[int, ...]:
    try:
        out = tuple(int(x) for x in text.split(","))
    except ValueError:
        out = ()
    if not out or any(d not in (16, 32, 64) for d in out):
        raise argparse.ArgumentTypeError(f"expected decoders among 16,32,64 separated by commas, got {text!r}")
    return out


def check(s: Settings) -> None:
    for name in ("steps1", "steps2", "batch", "finetune_steps"):
        if getattr(s, name) < 0:
            raise ValueError(f"--{name}: must be >= 0, got {getattr(s, name)}")
    if s.resolution < 4 or s.resolution & (s.resolution - 1):
        raise ValueError(f"--resolution: must be a power of two >= 4, got {s.resolution}")
    if s.gltf is not None:     # an unreadable file or material fails here, before a folder is claimed
        if Path(s.gltf).suffix.lower() not in GLTF_SUFFIXES:
            raise ValueError(f"--gltf: {s.gltf}: expected a .glb or .gltf file")
        open_source(s.material, s.gltf)


def build(run: Run) -> int:
    m = fit_material(run)
    steps = m["history"]["phase2"] or m["history"]["phase1"]
    last = steps[-1] if steps else {f"l1_{k}": v for k, v in m["history"]["holdout"]["level0"].items()}
    psnr = ", ".join(f"{k[5:]} {v} dB" for k, v in m.get("render", {}).items() if k.startswith("psnr_"))
    print(f"wrote {run.out}: L1(log) 3x64 {last['l1_3x64']:.4f}, 2x32 {last['l1_2x32']:.4f}, "
          f"2x16 {last['l1_2x16']:.4f} in {m['train_seconds']:.0f} s"
          + (f"; render PSNR vs the glTF reference: {psnr}" if psnr else ""))
    return 0


TRAINER = Trainer("neural_appearance", __doc__, Settings, PRESETS, build, folder=_folder,
                  folder_hint="neural_appearance_<material | glTF file>", default_preset="ship",
                  ship_assets=SHIP_ASSETS, extra_arguments=extra_arguments, check=check, errors=(ValueError,),
                  resume=(CHECKPOINT,))
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
