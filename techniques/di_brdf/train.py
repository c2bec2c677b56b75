"""Differentiable Indirection BRDFs (Datta et al. 2023 §4.3, supp. 1.1-1.2).

GGX. A 16x16 primary (2 channels, identity uv ramp, triangle F, 8-bit) queried with (alpha_h, h_z)
-> an 8x8 cascaded array (1 channel, no F, 8-bit; initialised to D clamped at 2 rather than the
paper's constant 0.5, see GGX_INIT_CAP) approximating
D = a^4 / (pi (1 + (a^4 - 1) h_z^2)^2) (models/brdf.py `ggx_d`). Samples: h_z of a
cosine-hemisphere direction, alpha_h exponential-like (biased to glossy) for the paper's L1 on D.
Here the loss is in the domain the Fig. 6 balls are judged in (`ggx_loss`): MSE of the clamped,
sRGB-encoded ball radiance on samples distributed like the ball pixels (alpha_h uniform over the
ball row's range, points over the ball, the scene's lights), plus a small tone-mapped L1 on D
over the paper's sampling; Adam, cosine schedule. L1 on raw D spends the 8x8 cells on peaks
that saturate to white (pooled ball PSNR 39.3 dB, worst ball 34.1 at 1500 steps), the display
loss on the dim highlights the balls show (47.5 / 41.7 dB at 8000 steps, ~75 s on one core).

Disney. Albedo factored out (paper Eq. 3; exact, models/brdf.py `disney_pq`), then five runtime
lookups (decoders) and ~70 FLOPs of glue (shaders/lib/di_brdf.glsl, torch models/disney_glue.py):

| decoder | array | queried with | holds |
|---|---|---|---|
| ggx   | 16x16 x3 | z_m = E_m(roughness, anisotropic) | d0, d1, d2: D_m = 1 / (d0 hx^2 + d1 hy^2 + d2 nh^2)^2 |
| smith | 16x16 x1 | z_m | k of a Schlick-Smith G1 = n.w / (n.w (1 - k) + k) |
| diff  | 16x16 x4 | z_d = E_d(roughness, subsurface) | f_0..f_3 of f_d = n.l sum f_i g_i (g_i analytic, K = 4) |
| coef  | 16x16 x4 | z_c = E_c(metallic, sheen) | 1 - metallic, metallic, (1 - metallic) sheen, clearcoat k |
| gloss | 16 x2    | z_g = E_g(clearcoat_gloss) | e0, e1: D_c = 1 / (e0 (1 - nh^2) + e1) |

The denominators of D_m and D_c are learned, not D (paper: "we learn the reciprocal of the output
which has bounded range"). The encoders E_* are DI primary arrays (64x64 / 64, 2 or 1 channels,
sinusoid F as the paper uses for Disney) run offline: they turn artist-parameter textures into
latent textures (`DisneyDI.encode`). Three scalars per texel need no lookup and are stored in the latent
textures as the analytic pre-computation (0.04 specular specular_tint, 0.04 specular
(1 - specular_tint), clearcoat / 4, and sheen_tint): the paper leaves this part open.

Training (`train_disney`): decoders start at the exact targets at their cells (identity encoders),
then encoders + decoders are trained end to end with L1 on the tone-mapped radiance x / (1 + x) of
random (l, v, material) samples (uniform hemispheres, exponential-like roughness and clearcoat
roughness, uniform other parameters and albedo), Adam, cosine schedule.

Quality (the paper's Fig. 6 / Fig. 11 protocol, render.py `sweep_psnr`): material balls rendered with the
learned and the analytic BRDF (techniques/di_brdf/material_balls.py, the lights of the shipped scene), PSNR
over the ball pixels in the display domain -- linear radiance clamped to [0, 1], sRGB-encoded,
peak 1; for Disney one row per artist parameter swept 0 -> 1 with the others at brdf.DEFAULTS, and
the minimum over the row is reported. For GGX the row sweeps alpha_h.

    inshade train di_brdf ggx --force -o trained/di_brdf_ggx --preset ship
    inshade train di_brdf disney --force -o trained/di_brdf_disney --preset ship

``--preset ship`` (the default) is exactly what built the shipped assets (PRESETS; Disney: 300 steps at
batch 2048); ``quick`` is a short run. Options given explicitly override the preset; OUT/metrics.json
records the preset and the resolved settings.

The cascades, the Disney module and the asset's graph are in model.py; the samples, the ball-row
terms and the sweep grid in data.py; the ball renders and their PSNRs (torch and GLSL) in render.py;
this module trains, writes the asset folder and is the command line.
"""
from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from inshade.files import atomic_files, atomic_write
from inshade.models import brdf
from inshade.models import indirection as di
from inshade.models.fit_loop import history_rows
from inshade.techniques.di_brdf import material_balls as mb
from inshade.models.graph import GraphModule
from inshade.scene.builder import (display_modes, exposure_setting, int_setting, lut_filter_setting, network,
                                    plane2d, point_light, requires, scene_json, view_labels)
from inshade.trainer import (Run, Trainer, batch_setting, lr_setting, seed_setting, setting, steps_setting,
                             without_history)
from inshade.provenance import recorded_at

from .data import (GGX_ALPHA_RANGE, SWEEP_COLUMNS, disney_samples, ggx_ball_display, ggx_ball_sampler, ggx_sampler,
                   sweep_grid)
from .model import ENCODERS, GGX_INIT_CAP, DisneyDI, analytic_d, disney_graph, ggx_cascade, learned_d
from . import MODELS, VIEWS
from .render import disney_render, ggx_metrics, ggx_shade, glsl_psnr, sweep_psnr

PROGRAM = "passes/material_balls.frag"
GGX_KIND, DISNEY_KIND = "di_brdf_ggx", "di_brdf_disney"
# lr 2e-2 vs 1e-2 (clamped init, 8000 steps, seeds 0/1/2): pooled ball PSNR 49.1/48.9/47.6 vs
# 47.2/50.9/47.8 dB, worst ball 44.2/46.4/42.2 vs 41.4/46.0/41.9; 16000 steps added ~0.5 dB.
GGX_DEFAULTS = dict(steps=8000, batch=4096, lr=2e-2, schedule="cosine", seed=0)
# Weight of the function-domain term of `ggx_loss` next to the display-domain ball MSE: enough to
# keep D tracking the analytic one off the balls' domain (measured with the constant init, 8000
# steps: tone-mapped function PSNR 35.9 dB, -3.9 dB without the term), small enough not to pull
# the balls (1e-2 cost ~1.4 dB pooled).
GGX_FUNCTION_WEIGHT = 1e-3
DISNEY_DEFAULTS = dict(steps=400, batch=4096, lr=3e-3, schedule="cosine", seed=0, samples=1 << 17)
# --preset, per BRDF: "ship" is what built trained/di_brdf_<which> (GGX: GGX_DEFAULTS; Disney: 300
# steps at batch 2048, not DISNEY_DEFAULTS' 400 x 4096); "quick" a short run. The default is "ship".
PRESETS = {"ship": {"ggx": dict(steps=8000, batch=4096, lr=2e-2, seed=0),
                    "disney": dict(steps=300, batch=2048, lr=3e-3, samples=1 << 17, seed=0)},
           "quick": {"ggx": dict(steps=500, batch=4096, lr=2e-2, seed=0),
                     "disney": dict(steps=60, batch=2048, lr=3e-3, samples=1 << 15, seed=0)}}


# The input of each shipped asset (WHICH beside --preset ship).
SHIP_ASSETS = {"di_brdf_ggx": dict(which="ggx"), "di_brdf_disney": dict(which="disney")}


class BrdfTrainingError(ValueError):
    """A setting the BRDF trainer cannot use."""


@dataclass(frozen=True)
class Settings:
    """What a di_brdf run is built from (metrics.json records it); every preset sets the training
    lengths per BRDF (PRESETS)."""
    which: str = setting(None, "which learned BRDF to build: ggx or disney", choices=("ggx", "disney"),
                         positional="WHICH")
    steps: int = steps_setting(None)
    batch: int = batch_setting(None)
    lr: float = lr_setting(None)
    samples: int | None = setting(None, "training samples drawn once", only={"which": ("disney",)})
    seed: int = seed_setting()


# training
def _tonemap(x):
    return x / (1.0 + x.abs())


def ggx_loss(g: GraphModule, ball, fn):
    """MSE of the display-domain ball samples (what the ball PSNR measures: radiance clamped and
    sRGB-encoded, so D's peaks above white cost nothing and dim highlights count) + GGX_FUNCTION_WEIGHT
    x L1 of x / (1 + |x|) tone-mapped D on the paper's sampling (`ggx_sampler`), which keeps D sane
    where no ball pixel looks (alpha_h < 0.1, n.h no light reaches)."""
    with torch.no_grad():
        ref = ggx_ball_display(analytic_d, *ball)
    err = ggx_ball_display(learned_d(g), *ball) - ref
    x, y = fn
    return torch.mean(err * err) + GGX_FUNCTION_WEIGHT * torch.mean(torch.abs(_tonemap(g(x)) - _tonemap(y)))


def train_ggx(steps=GGX_DEFAULTS["steps"], batch=GGX_DEFAULTS["batch"], lr=GGX_DEFAULTS["lr"],
              schedule=GGX_DEFAULTS["schedule"], seed=GGX_DEFAULTS["seed"], progress=None, device=None):
    """Adam on `ggx_loss` (batch ball samples + batch / 4 function samples a step) with an
    `indirection.SCHEDULES` schedule (`indirection.train_cascade` with this objective). History:
    step, loss (mean training loss since the last record), psnr (display domain, float cascade, on
    16384 fixed ball samples), lr, seconds. Trains on `device` (default the CPU); the cascade comes
    back on the CPU."""
    torch.manual_seed(seed)
    g = ggx_cascade().to(device)
    samples = zip(ggx_ball_sampler(batch, seed, device), ggx_sampler(max(batch // 4, 1), seed + 1, device))
    ev = next(ggx_ball_sampler(1 << 14, seed + 2, device))
    with torch.no_grad():
        ev_ref = ggx_ball_display(analytic_d, *ev)

    def metric(cascade):
        got = ggx_ball_display(learned_d(cascade), *ev)
        return float(torch.mean((got - ev_ref) ** 2)), di.psnr(got, ev_ref)

    t0 = time.perf_counter()
    hist = di.train_cascade(g, samples, steps, lr=lr, schedule=schedule, seed=seed,
                            objective=lambda cascade, b: ggx_loss(cascade, *b), metric=metric,
                            progress=progress, desc="di_brdf_ggx")
    return g.to("cpu"), hist, time.perf_counter() - t0


def train_disney(steps=DISNEY_DEFAULTS["steps"], batch=DISNEY_DEFAULTS["batch"], lr=DISNEY_DEFAULTS["lr"],
                 samples=DISNEY_DEFAULTS["samples"], seed=DISNEY_DEFAULTS["seed"], exposure: float = 1.5,
                 progress=None, device=None):
    """End-to-end L1 on tone-mapped radiance (exposure ~ the scene's E / r^2); returns (model, history, seconds).
    Trains on `device` (default the CPU); the model comes back on the CPU."""
    from inshade.models.fit_loop import adam, cosine, fit

    torch.manual_seed(seed)
    model = DisneyDI().to(device)
    data = disney_samples(samples, seed, device)
    history = []
    t0 = time.perf_counter()
    opt = adam(model.parameters(), lr=lr)
    gen = torch.Generator().manual_seed(seed + 1)

    def step_loss(index):
        idx = torch.randint(0, samples, (batch,), generator=gen).to(device)
        l, v, base, params, target = (t[idx] for t in data)
        pred = model(l, v, base, params)
        loss = torch.mean(torch.abs(_tonemap(exposure * pred) - _tonemap(exposure * target)))
        return loss if torch.isfinite(loss) else None   # a degenerate sample (denominator ~ 0): no step

    def after(index, loss, bar):
        step = index + 1
        if step % max(1, steps // 10) == 0 or step == steps:
            history.append({"step": step, "loss": float(loss.detach()), "seconds": round(time.perf_counter() - t0, 2)})
            bar.set_postfix(loss=f"{history[-1]['loss']:.4f}")

    fit(opt, step_loss, steps, lr_factor=cosine(steps), after_step=after, seed=seed, desc="di_brdf_disney",
        progress=progress)
    for p in model.parameters():
        p.requires_grad_(False)
    return model.to("cpu"), history, time.perf_counter() - t0


# assets
def scene_dict(name: str, title: str, model: str, size, cols: int, rows: int, ball_px: int) -> dict:
    return scene_json(
        name, title, PROGRAM, size,
        networks=[network(".", "net")],
        camera=plane2d(aspect=size[0] / size[1]),
        lights=[point_light(light[:3], light[3]) for light in mb.LIGHTS],
        environment=None,
        display=display_modes("network"),
        settings={
            "exposure": exposure_setting(),
            "lights": int_setting(2, 1, mb.MAX_LIGHTS, "point lights", uniform="u_light_count"),
            "view": int_setting(VIEWS["split"], 0, 3, "0 analytic, 1 learned, 2 side by side, 3 diffuse baseline",
                                define="BRDF_VIEW"),
            "model": int_setting(MODELS[model], MODELS[model], MODELS[model], "1 GGX, 2 Disney", define="BRDF_MODEL"),
            "cols": int_setting(cols, cols, cols, "grid columns", define="BALL_COLS"),
            "rows": int_setting(rows, rows, rows, "grid rows", define="BALL_ROWS"),
            "lut_filter": lut_filter_setting(),
        },
        requires=requires(),
        notes=f"material balls, {ball_px} px each; left half analytic, right half learned (view 2)",
        labels=view_labels("analytic", "learned", {"view": VIEWS["split"]},
                           [("analytic", {"view": VIEWS["analytic"]}), ("learned", {"view": VIEWS["learned"]}),
                            ("diffuse baseline", {"view": VIEWS["diffuse"]})]),
    )


def _provenance(command, extra):
    return {"command": command, "torch": torch.__version__,
            **recorded_at(), **extra}


def _write_scene(out: Path, scene: dict, preview: np.ndarray):
    from inshade.scene.image_io import write_png

    atomic_write(out / "scene.json", json.dumps(scene, indent=2) + "\n")
    write_png(out / "preview.png", preview)


def build_ggx(out, steps=GGX_DEFAULTS["steps"], batch=GGX_DEFAULTS["batch"], lr=GGX_DEFAULTS["lr"],
              seed=GGX_DEFAULTS["seed"], command: str = "", progress=None, ball_px: int = 64,
              gl_metrics: bool = True, device=None) -> dict:
    device = torch.device("cpu") if device is None else torch.device(device)
    g, hist, seconds = train_ggx(steps, batch, lr, seed=seed, progress=progress, device=device)
    for p in g.parameters():
        p.requires_grad_(False)
    metrics = {"train_seconds": round(seconds, 2), "steps": steps, "batch": batch, "lr": lr,
               "history": history_rows(hist.records, "psnr", 3)}
    prov = _provenance(command, {
        "technique": "Differentiable Indirection isotropic GGX (Datta et al. 2023): 16x16x2 primary "
                     "(uv ramp, triangle F, 8-bit) -> 8x8x1 cascaded (init D clamped to "
                     f"{GGX_INIT_CAP:g} at the cells, no F, 8-bit)",
        "training": f"display-domain MSE on ball samples (alpha_h uniform {GGX_ALPHA_RANGE}, points over "
                    f"the ball, 1-{mb.MAX_LIGHTS} scene lights) + {GGX_FUNCTION_WEIGHT:g} x L1 on x/(1+x) "
                    f"tone-mapped D (alpha_h exponential-like, h_z cosine-hemisphere), Adam lr {lr:g} "
                    f"cosine, batch {batch} (+{max(batch // 4, 1)} function samples), {steps} steps, seed {seed}",
        "psnr_domain": "Fig. 6 ball row: radiance clamped to [0,1], sRGB-encoded, over ball pixels, peak 1",
        "device": str(device)})
    return write_ggx_asset(g, out, metrics, prov, ball_px, gl_metrics)


def write_ggx_asset(g: GraphModule, out, metrics: dict, prov: dict, ball_px: int = 64,
                    gl_metrics: bool = True) -> dict:
    """Bundle (8-bit) + scene.json + preview.png (torch, analytic | learned) + quality metrics."""
    metrics = {**metrics, "bytes": 16 * 16 * 2 + 8 * 8, **ggx_metrics(g)}
    out = Path(out)
    bundle = g.export(GGX_KIND, out.name, provenance=prov, metrics=metrics)
    bundle.save(out)
    cols = SWEEP_COLUMNS
    scene = scene_dict(out.name, "DI GGX: analytic | learned, alpha_h 0.1 -> 1", "ggx",
                       (2 * cols * ball_px, ball_px), cols, 1, ball_px)
    shade_a, shade_l = ggx_shade(analytic_d), ggx_shade(learned_d(GraphModule.from_bundle(bundle)))
    shade_a.cols = shade_l.cols = cols

    def split(sel, l, v, k):
        return torch.where((sel["side"] == 1)[..., None], shade_l(sel, l, v, k), shade_a(sel, l, v, k))
    preview = mb.render(2 * cols * ball_px, ball_px, cols, 1, split, 2, 2)
    _write_scene(out, scene, preview)
    if gl_metrics:
        metrics["glsl"] = {f: glsl_psnr(out, "ggx", f, ball_px) for f in ("exact", "fast")}
        g.export(GGX_KIND, out.name, provenance=prov, metrics=metrics).save(out)
    return metrics


def build_disney(out, steps=DISNEY_DEFAULTS["steps"], batch=DISNEY_DEFAULTS["batch"], lr=DISNEY_DEFAULTS["lr"],
                 samples=DISNEY_DEFAULTS["samples"], seed=DISNEY_DEFAULTS["seed"], command: str = "",
                 progress=None, ball_px: int = 32, gl_metrics: bool = True, device=None) -> dict:
    device = torch.device("cpu") if device is None else torch.device(device)
    model, hist, seconds = train_disney(steps, batch, lr, samples, seed, progress=progress, device=device)
    cols, rows = SWEEP_COLUMNS, len(brdf.PARAMS)
    base, params = sweep_grid(cols)
    g = disney_graph(model, base, params)
    sweep = sweep_psnr(g, cols, rows, size=ball_px)
    metrics = {"train_seconds": round(seconds, 2), "steps": steps, "batch": batch, "lr": lr,
               "decoder_bytes_fp32": 4 * (16 * 16 * (3 + 1 + 4 + 4) + 16 * 2),
               "sweep_min_psnr": min(v["min"] for v in sweep.values()), "sweep": sweep, "history": hist}
    prov = _provenance(command, {
        "technique": "Differentiable Indirection Disney BRDF (Datta et al. 2023 supp. 1.2) after Li 2022 "
                     "(no glass): albedo factored out, 5 decoders (16x16x3, 16x16x1, 16x16x4, 16x16x4, 16x2) "
                     "+ glue (shaders/lib/di_brdf.glsl); encoders 64^2 sinusoid primaries run offline into "
                     "the latent textures lat_*; par* are the artist textures for the analytic shader",
        "training": f"end-to-end L1 on x/(1+x) tone-mapped radiance, Adam lr {lr:g} cosine, batch {batch}, "
                    f"{steps} steps over {samples} samples, seed {seed}",
        "psnr_domain": "Fig. 11: ball pixels, radiance clamped to [0,1], sRGB-encoded, peak 1; min per row",
        "device": str(device)})
    out = Path(out)
    bundle = g.export(DISNEY_KIND, out.name, provenance=prov, metrics=metrics)
    bundle.save(out)
    _save_encoders(model, out / "encoders.safetensors")
    scene = scene_dict(out.name, "DI Disney: analytic | learned, one artist parameter per row, 0 -> 1",
                       "disney", (2 * cols * ball_px, rows * ball_px), cols, rows, ball_px)
    preview = disney_render(GraphModule.from_bundle(bundle), "split", cols, rows, ball_px, 2)
    _write_scene(out, scene, preview)
    if gl_metrics:
        metrics["glsl"] = {f: glsl_psnr(out, "disney", f, ball_px) for f in ("exact", "fast")}
        g.export(DISNEY_KIND, out.name, provenance=prov, metrics=metrics).save(out)
    return metrics


def _save_encoders(model: DisneyDI, path: Path):
    """The offline encoders (F baked, float32), for encoding other artist textures: safetensors,
    tensors "E_<m|d|c|g>.cells" with the lookup-array cell layout; inputs per ENCODERS."""
    from safetensors.numpy import save_file

    tensors = {f"E_{k}.cells": np.ascontiguousarray(e.table().detach().numpy(), dtype=np.float32)
               for k, e in model.encoders.items()}
    with atomic_files(path) as tmp:
        save_file(tensors, str(tmp), metadata={"inputs": json.dumps(ENCODERS)})


# command line
def extra_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--no-gl", action="store_true", help="skip the shader-rendered PSNR (no GL context)")


def check(s: Settings) -> None:
    if s.steps < 0 or s.batch < 1 or not s.lr > 0:
        raise BrdfTrainingError("--steps must be >= 0, --batch >= 1 and --lr > 0")


def train(run: Run) -> int:
    s, gl_metrics = run.settings, not run.args.no_gl
    if s.which == "ggx":
        m = build_ggx(run.out, s.steps, s.batch, s.lr, s.seed, command=run.command, gl_metrics=gl_metrics,
                      device=run.device)
    else:
        m = build_disney(run.out, s.steps, s.batch, s.lr, s.samples, s.seed, command=run.command,
                         gl_metrics=gl_metrics, device=run.device)
    run.write_metrics(without_history(m))
    if s.which == "ggx":
        print(f"wrote {run.out}: GGX ball PSNR all pixels {m['psnr_balls_all_pixels']:.2f} dB, "
              f"mean {m['psnr_balls_mean']:.2f} dB (min {m['psnr_balls_min']:.2f}), "
              f"function (tone-mapped) {m['psnr_function_tonemapped']:.2f} dB, {m['train_seconds']:.1f} s")
    else:
        rows = ", ".join(f"{k} {v['min']:.1f}" for k, v in m["sweep"].items())
        print(f"wrote {run.out}: Disney sweep min PSNR {m['sweep_min_psnr']:.2f} dB ({rows}), "
              f"{m['train_seconds']:.1f} s")
    return 0


TRAINER = Trainer("di_brdf", __doc__, Settings, PRESETS, train, folder=lambda s: f"di_brdf_{s.which}",
                  folder_hint="di_brdf_<model>",
                  default_preset="ship", ship_assets=SHIP_ASSETS, extra_arguments=extra_arguments, check=check,
                  errors=(BrdfTrainingError,), preset_by="which")
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
