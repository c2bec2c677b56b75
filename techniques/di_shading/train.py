"""End-to-end optimised shading pipeline with Differentiable Indirection (Datta et al. 2023 §4.3.3,
supp. 1.5): the footprint-aware DI texture sampler (techniques/di_footprint; its graph and targets in
models/footprint_sampler.py) trained to be aware of the learned DI Disney BRDF (techniques/di_brdf,
the shipped trained/di_brdf_disney), on the PBR bricks set (models/pbr_lanes.py, as
techniques/di_pbr_set ships it: albedo, normal, roughness, AO; 8 lanes) on a lit ground plane seen
at grazing angles.

The pipeline, per pixel (passes/shading_plane.frag; torch twin model.py `shade_di` / `reference`):

    (fract uv, log2 footprint) -> DI footprint sampler (2D primary + 1D footprint primary -> 4D
        cascaded, 8 lanes, 8-bit arrays, no mip chain) -> lanes
    lanes -> unpack (lib/pbr_set: sRGB albedo, tangent-space normal, roughness, AO)
    roughness -> frozen DI Disney "brdf" bundle: the offline encoders' rows at the set's constant
        artist parameters (anisotropic = subsurface = 0, one 1D 64-cell lookup, 4 channels) and the
        five runtime decoders of trained/di_brdf_disney (16x16 ggx / smith / diff / coef, 16 gloss)
    -> lib/di_brdf glue, one point light (I / d^2) + an ambient term albedo * AO * ambient.

The set's other Disney parameters are constants: metallic 0, specular 0.5, specular_tint 0,
sheen 0, sheen_tint 0.5, clearcoat 0, clearcoat_gloss 1 (as techniques/di_pbr_set/render.py shades it).

Training (`train_sweep`): one (uv, footprint, light, view) data set drawn like the plane's pixels
(data.py `plane_samples`: random grazing fly cameras, pixels of a 512x256 view, uv derivatives by
differences between neighbouring pixels on 2x2 quads, as llvmpipe forms dFdx/dFdy; tested against
the pass's G-buffer), then for each lambda, the same sampler initialisation, the same batches, the
same steps and seed:

    loss = (1 - lambda) |sampler - proxy| + lambda |display(shade_di(sampler)) - display(reference)|

- proxy: models/footprint_sampler.py `emulated_trilinear` of the set (GL_LINEAR_MIPMAP_LINEAR, 8-bit box mips);
- reference ("appearance filtering", `reference`): 16 samples on a 4x4 grid over the pixel footprint
  uv + a duv/dx + b duv/dy (a, b in {-3/8, -1/8, 1/8, 3/8}: the pixel's parallelogram, first order),
  each prefiltered by the proxy trilinear sampler at a quarter of the footprint (log2 footprint - 2)
  and shaded with the ANALYTIC Disney BRDF (models/brdf.py), averaged. The paper assumes an
  axis-aligned footprint; the parallelogram is the pixel's own, so the training reference and
  the GLSL reference view (SHADING_VIEW reference) are the same formula;
- display(x) = sRGB(clamp(exposure x, 0, 1)), the domain the PSNR / FLIP are measured in;
- the decoder is frozen (requires_grad False; gradients flow through its lookups to the lanes);
- metallic-path clipping (`metal_clip`): the shaded term is split into its GGX lobe D_m G_m (the
  unbounded "metallic" component; its value is the glue's with the ggx decoder output as given
  minus the glue's with D_m -> 0) and the rest, and the gradient reaching the sampler's lanes
  through that lobe is clipped per sample to an L2 norm <= metal_clip / batch (a tensor hook);
- a sample whose shaded-term gradient is not finite (torch.where's backward through the glue's
  masked below-horizon branch) has it dropped, and is counted (metrics: nonfinite_gradient_samples);
- Adam, cosine schedule (lr to 5%), lambda = 0 is the independently trained sampler (baseline).

Command: ``inshade train di_shading --force -o trained/di_shading_bricks [--preset quick|ship] [--device
auto|cpu|cuda[:N]]``. ``--preset ship`` is exactly what built trained/di_shading_bricks; ``quick``
(the default) is a small run. ``--device`` (inshade/devices.py; auto: CUDA when torch sees one)
places the training: the mip chain, the data set's proxies and references, the samplers, the frozen
decoder, every step and the held-out evaluation run there. Random numbers are drawn on seeded CPU
generators (numpy for the views and pixels, torch for the batches and the initialisation), so every
device trains on the same data and batches; the samplers and the decoder come back to the CPU for
export. OUT/metrics.json records the preset, the resolved settings, the device and the lambda sweep.
"""
from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from inshade.files import atomic_write
from inshade.models import indirection as di
from inshade.models.graph import GraphModule
from inshade.models import footprint_sampler as fp
from inshade.scene.builder import (choice_setting, display_modes, float_setting, lut_filter_setting, network,
                                    point_light, requires, scene_json, texture, view_labels)
from inshade.trainer import Run, Trainer, batch_setting, lr_setting, seed_setting, setting, without_history
from inshade.provenance import recorded_at

from . import VIEWS
from .data import VIEW_SIZE, Samples, batches, material, plane_samples
from .model import (AMBIENT, DEFAULT_BRDF, EXPOSURE, LIGHT_INTENSITY, LIGHT_POSITION, ShadingError, decoder_graph,
                    display, shade_di, shade_di_clipped)

KIND = "di_shading"
DECODER_KIND = "di_shading_brdf"
PROGRAM = "passes/shading_plane.frag"
CHANNELS = 8
LAMBDAS = (0.0, 0.1, 0.25, 0.5)


@dataclass(frozen=True)
class Settings:
    """What a di_shading run is built from (metrics.json records it)."""
    size: int = setting(128, "bricks set size (power of two >= 32)")
    ratio: float = setting(6.0, "compression vs the 8-lane RGBA8 base level")
    n_cascaded: int = setting(4, "N_c (multiple of 4)")
    steps: int = setting(1500, "training steps per lambda")
    lr: float = lr_setting(1e-2)
    batch: int = batch_setting(4096)
    samples: int = setting(1 << 17, "training pixels")
    views: int = setting(12, "random grazing views the pixels come from")
    metal_clip: float = setting(1.0, "per-sample gradient-norm bound (x 1/batch) through the GGX (metallic) "
                                "lobe; 0: off")
    seed: int = seed_setting()
    lambdas: tuple[float, ...] = setting(LAMBDAS, "the sweep (must include 0)")


# "quick" is a small run; "ship" is exactly what built trained/di_shading_bricks.
PRESETS = {"quick": dict(size=64, steps=300, samples=1 << 15, views=4),
           "ship": dict(size=128, steps=1500, samples=1 << 17, views=12)}
SHIP_ASSETS = {"di_shading_bricks": {}}


def check(s: Settings) -> None:
    """The sweep's own limits (the set size and the BRDF asset are checked where they are read)."""
    for lam in s.lambdas:
        if not (0.0 <= float(lam) < 1.0):
            raise ShadingError(f"lambdas: {lam!r}: each lambda must be in [0, 1) (lambda = 1 is unstable)")
    if 0.0 not in [float(x) for x in s.lambdas]:
        raise ShadingError("lambdas: must include 0 (the independently trained baseline)")
    if s.steps < 0 or s.batch < 1 or s.samples < 1 or s.views < 1:
        raise ShadingError("steps >= 0, batch >= 1, samples >= 1 and views >= 1 are required")


def lambda_folder(lam: float) -> str:
    """Sub-folder of the asset holding the sampler trained with weight `lam` (lambda_000 .. lambda_050)."""
    return f"lambda_{int(round(lam * 100)):03d}"


# ---------------------------------------------------------------------------------------------
# training

@dataclass
class LambdaRun:
    """One sampler of the sweep: its lambda, float graph, 8-bit bundle, history and metrics."""
    lam: float
    graph: GraphModule       # trained float sampler core (outputs 8 lanes)
    bundle: object           # exported 8-bit bundle
    history: di.History
    metrics: dict = field(default_factory=dict)


def _finite_rows(counter: list):
    """Gradient hook: zero the rows (samples) whose gradient is not finite, counting them. The glue's
    masked branches (below-horizon 1 / (n.l + n.v), a ~0 normal's 1 / |n|) can give 0 x inf = NaN
    through torch.where's backward even where the value is fine. The count accumulates as a tensor
    on the gradient's device (no host sync per step); `int(counter[0])` reads it."""
    def hook(g):
        bad = ~torch.isfinite(g).all(-1, keepdim=True)
        counter[0] = counter[0] + bad.sum()
        return torch.where(bad, torch.zeros_like(g), g)
    return hook


def objective(lam: float, decoder: GraphModule, metal_clip: float | None, batch_size: int,
              nonfinite: list | None = None):
    """The sampler's loss for weight `lam` (module docstring). `nonfinite`: a one-item list counting
    the samples whose shaded-term gradient was dropped as non-finite."""
    bound = None if metal_clip is None else metal_clip / batch_size
    counter = nonfinite if nonfinite is not None else [0]

    def fn(core, b: Samples):
        lanes = core(b.x)
        loss = torch.mean(torch.abs(lanes - b.proxy))
        if lam == 0.0:
            return loss
        shaded_lanes = lanes.clone()
        if shaded_lanes.requires_grad:
            shaded_lanes.register_hook(_finite_rows(counter))
        shaded = torch.nan_to_num(display(shade_di_clipped(shaded_lanes, b.geo, decoder, bound)))
        with torch.no_grad():
            ref = display(b.ref)
        return (1.0 - lam) * loss + lam * torch.mean(torch.abs(shaded - ref))
    return fn


def evaluate(core: GraphModule, s: Samples, decoder: GraphModule) -> dict:
    """PSNR of the sampler's lanes vs the proxy, and of its DI-shaded display values vs the reference."""
    with torch.no_grad():
        lanes = core(s.x)
        shaded = display(shade_di(lanes, s.geo, decoder))
        ref = display(s.ref)
        proxy_shaded = display(shade_di(s.proxy, s.geo, decoder))
    return {"psnr_lanes_vs_proxy": round(di.psnr(lanes, s.proxy), 4),
            "psnr_shaded_vs_reference": round(di.psnr(shaded, ref), 4),
            "psnr_proxy_shaded_vs_reference": round(di.psnr(proxy_shaded, ref), 4)}


def train_sweep(settings: Settings = Settings(), brdf_folder=DEFAULT_BRDF, progress=None, name="di_shading",
                device=None):
    """Train one sampler per lambda (same init, data, batches, steps, seed) on `device` (default the
    CPU; module docstring). Returns (runs, decoder, image, data info), the runs' samplers and the
    decoder on the CPU."""
    s = settings
    check(s)
    metal_clip = s.metal_clip or None     # 0: no clipping
    device = torch.device("cpu") if device is None else torch.device(device)
    image = material(s.size)
    chain = fp.mip_chain(fp.texture_tensor(image).to(device))
    decoder = decoder_graph(brdf_folder).to(device)
    sizing = fp.plan(s.size, CHANNELS, s.ratio, s.n_cascaded)
    t0 = time.perf_counter()
    data = plane_samples(chain, s.samples, s.views, s.seed)
    held = plane_samples(chain, min(16384, s.samples), max(2, s.views // 2), s.seed + 1000)
    data_seconds = time.perf_counter() - t0
    runs = []
    for lam in s.lambdas:
        lam = float(lam)
        torch.manual_seed(s.seed)
        core = fp.sampler_graph(s.size, sizing, image.reshape(-1, CHANNELS).mean(0)).to(device)  # CPU init
        ev = held.index(torch.arange(min(4096, len(held.x)), device=device))

        def metric(c, ev=ev, lam=lam):
            m = evaluate(c, ev, decoder)
            return 0.0, m["psnr_shaded_vs_reference"]

        t1 = time.perf_counter()
        nonfinite = [0]
        hist = di.train_cascade(core, batches(data, s.batch, s.seed), s.steps, lr=s.lr, schedule="cosine",
                                seed=s.seed, objective=objective(lam, decoder, metal_clip, s.batch, nonfinite),
                                metric=metric,
                                progress=progress, desc=f"{name} lambda {lam:g}")
        seconds = time.perf_counter() - t1
        core = core.to("cpu")             # the result, on the CPU for export
        for p in core.parameters():
            p.requires_grad_(False)
        bundle = core.export(KIND, lambda_folder(lam), provenance={"lambda": lam})
        q = GraphModule.from_bundle(bundle).to(device)
        m = {"lambda": lam, "train_seconds": round(seconds, 2), **evaluate(q, held, decoder),
             "nonfinite_gradient_samples": int(nonfinite[0]),
             "history": [{"step": r["step"], "psnr_shaded": round(r["psnr"], 3)} for r in hist.records]}
        runs.append(LambdaRun(lam, core, bundle, hist, m))
    info = {"bytes": sizing.bytes, "n_primary": sizing.n_primary, "n_footprint": sizing.n_footprint,
            "n_cascaded": sizing.n_cascaded, "n_lod": sizing.n_lod,
            "ratio_vs_base": round(fp.texture_bytes(s.size, CHANNELS, False) / sizing.bytes, 4),
            "data_seconds": round(data_seconds, 2), "samples": len(data.x), "heldout": len(held.x)}
    return runs, decoder.to("cpu"), image, info


def best_run(runs):
    """The lambda > 0 run with the highest held-out shaded PSNR (8-bit sampler, DI decoder)."""
    cands = [r for r in runs if r.lam > 0] or runs
    return max(cands, key=lambda r: r.metrics["psnr_shaded_vs_reference"])


# ---------------------------------------------------------------------------------------------
# the asset

def scene_dict(name: str, title: str, e2e: str, size=VIEW_SIZE, view: str = "split") -> dict:
    views = ", ".join(f"{v} {k}" for k, v in VIEWS.items())
    return scene_json(
        name, title, PROGRAM, size,
        networks=[network(e2e, "e2e"), network(lambda_folder(0.0), "ind"), network("brdf", "brdf")],
        textures=[texture("u_set0", "set0.png", mipmaps=True, repeat=True),
                  texture("u_set1", "set1.png", mipmaps=True, repeat=True)],
        camera=fp.CAMERA,
        bookmarks={"grazing": fp.CAMERA,
                   "steeper": {**fp.CAMERA, "position": [0.0, 0.6, 0.0], "pitch": -25.0},
                   "horizon": {**fp.CAMERA, "position": [0.0, 0.15, 0.0], "pitch": -3.0}},
        lights=[point_light(LIGHT_POSITION, LIGHT_INTENSITY)],
        environment=None,
        display=display_modes("final", "network"),
        settings={
            "view": choice_setting(VIEWS[view], sorted(VIEWS.values()), "view: " + views, define="SHADING_VIEW"),
            "exposure": float_setting(EXPOSURE, 0.0, 8.0, "exposure", uniform="u_exposure"),
            "extent": float_setting(fp.EXTENT, 0.5, 1000.0, "plane half-size (world units)", uniform="u_extent"),
            "tile": float_setting(fp.TILE, 0.05, 20.0, "tile size (world units)", uniform="u_tile"),
            "light_x": float_setting(LIGHT_POSITION[0], -20.0, 20.0, "light x", uniform="u_light_x"),
            "light_y": float_setting(LIGHT_POSITION[1], 0.01, 20.0, "light height", uniform="u_light_y"),
            "light_z": float_setting(LIGHT_POSITION[2], -20.0, 20.0, "light z", uniform="u_light_z"),
            "intensity": float_setting(LIGHT_INTENSITY, 0.0, 200.0, "light intensity", uniform="u_light_intensity"),
            "ambient": float_setting(AMBIENT, 0.0, 2.0, "ambient", uniform="u_ambient"),
            "lut_filter": lut_filter_setting(),
        },
        requires=requires(),
        notes="--set view=N: " + views + "; split: independent (lambda 0) left | end-to-end right",
        labels=view_labels("independent (lambda 0)", "end-to-end", {"view": VIEWS["split"]}, [
            ("end-to-end", {"view": VIEWS["end_to_end"]}),
            ("independent (lambda 0)", {"view": VIEWS["independent"]}),
            ("reference (16 footprint samples, analytic Disney)", {"view": VIEWS["reference"]}),
            ("uncompressed + mips (GL trilinear), DI Disney", {"view": VIEWS["trilinear"]}),
            ("uncompressed + mips (GL trilinear), analytic Disney", {"view": VIEWS["analytic"]})]),
    )


def write_set_textures(out: Path, image: np.ndarray):
    """set0.png (lanes 0-3) and set1.png (lanes 4-7): the uncompressed set as two RGBA8 PNGs (image
    orientation, values as stored) for the reference view (GL mips, REPEAT)."""
    from PIL import Image

    from inshade.files import atomic_files

    data = np.rint(np.clip(image, 0, 1) * 255).astype(np.uint8)
    for i in range(2):
        with atomic_files(out / f"set{i}.png") as tmp:
            Image.fromarray(np.ascontiguousarray(data[..., 4 * i:4 * i + 4]), "RGBA").save(tmp, format="PNG")


def write_asset(out, runs, decoder, image, e2e: str, provenance: dict, preview_size=VIEW_SIZE) -> Path:
    from inshade.runtime.headless import render_scene
    from inshade.scene.image_io import write_png

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for r in runs:
        r.graph.export(KIND, lambda_folder(r.lam), provenance={**provenance, "lambda": r.lam},
                       metrics=without_history(r.metrics)).save(out / lambda_folder(r.lam))
    decoder.export(DECODER_KIND, "brdf", provenance={
        "source": "trained/di_brdf_disney decoders (frozen) + its encoders' rows at anisotropic = "
                  "subsurface = metallic = sheen = 0, clearcoat_gloss = 1"}).save(out / "brdf")
    write_set_textures(out, image)
    lam = next(r.lam for r in runs if lambda_folder(r.lam) == e2e)
    title = f"DI shading pipeline (bricks): independent | end-to-end (lambda {lam:g})"
    atomic_write(out / "scene.json", json.dumps(scene_dict(out.name, title, e2e, preview_size), indent=2) + "\n")
    image, _ = render_scene(out, width=preview_size[0], height=preview_size[1])
    write_png(out / "preview.png", image[..., :3])
    return out


# ---------------------------------------------------------------------------------------------
# command line

def extra_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--brdf", default=DEFAULT_BRDF, help="the frozen di_brdf_disney asset (default %(default)s)")


def train(run: Run) -> int:
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    runs, decoder, image, info = train_sweep(settings=run.settings, brdf_folder=run.args.brdf, name=run.out.name,
                                             device=run.device)
    best = best_run(runs)
    sweep = [without_history(r.metrics) for r in runs]
    base = next(r for r in runs if r.lam == 0.0).metrics["psnr_shaded_vs_reference"]
    metrics = {"device": str(run.device), **info,
               "lambda_best": best.lam, "sweep": sweep,
               "psnr_gain_best_vs_independent_db": round(best.metrics["psnr_shaded_vs_reference"] - base, 4),
               "psnr_gain_best_vs_independent_percent": round(
                   100.0 * (best.metrics["psnr_shaded_vs_reference"] / base - 1.0), 3),
               "train_seconds_total": round(time.perf_counter() - t0, 2),
               "note": "psnr_*: torch, 8-bit samplers, held-out plane pixels, display domain sRGB(clamp(x)); "
                       "the GLSL-rendered numbers are inshade bench di_shading's"}
    prov = {"command": run.command, "torch": torch.__version__, "device": str(run.device),
            **recorded_at(),
            "technique": "Differentiable Indirection end-to-end shading (Datta et al. 2023 supp. 1.5): "
                         "footprint sampler trained through the frozen DI Disney decoder"}
    out = write_asset(run.out, runs, decoder, image, lambda_folder(best.lam), prov)
    run.write_metrics(metrics)
    rows = ", ".join(f"lambda {r.lam:g}: {r.metrics['psnr_shaded_vs_reference']:.2f} dB" for r in runs)
    print(f"wrote {out}: shaded PSNR vs the 16-sample reference (held-out pixels, torch) {rows}; "
          f"best lambda {best.lam:g} ({metrics['psnr_gain_best_vs_independent_db']:+.2f} dB), "
          f"{metrics['train_seconds_total']:.0f} s")
    return 0


TRAINER = Trainer("di_shading", __doc__, Settings, PRESETS, train, folder=lambda s: "di_shading_bricks",
                  folder_hint="di_shading_bricks",
                  ship_assets=SHIP_ASSETS, extra_arguments=extra_arguments, check=check,
                  errors=(ShadingError, fp.FootprintError))
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
