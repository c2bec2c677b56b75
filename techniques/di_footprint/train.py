"""Footprint-aware texture sampler with Differentiable Indirection, no mip chain stored
(Differentiable Indirection, Datta et al. 2023 §4.2.2 and supp. 1.4).

Graph (the bundle, kind ``di_footprint``): inputs ``uv`` (2, in [0, 1], the fract of a tiled
uv) and ``log2_footprint`` (1: log2 of the pixel footprint in uv units, see below).

    uv             -> primary      2D N_p0^2, 3 channels, (u, v, u) ramp, triangle F
    log2_footprint -> lod          dense 1 -> 1, fixed: x_f = (log2_footprint + log2 N) / L
                   -> lod_primary  1D N_p1 = 4 N_lod, 1 channel, identity ramp, triangle F
    [primary, lod_primary] -> cascaded  4D N_c x N_c x N_c x N_lod, k channels (LOD is axis 3,
                   the slice-block axis of the packed 3D texture: two fetches and a mix, the
                   analogue of trilinear's lerp between two mip levels)
    cascaded -> sRGB decode (models/texture_cascade.py decode_nodes) -> ``rgb`` (linear)

Footprint convention (one formula for training, the emulated sampler and the shader):
``log2_footprint = log2(max(|duv/dx|, |duv/dy|))``, the isotropic max-axis rule of GL's
trilinear LOD (GL 4.6 §8.14.1, rho = max of the two scaled derivative lengths), so the GL
mip level is ``lambda = log2_footprint + log2 N`` for an N x N base texture. The fixed ``lod``
node divides lambda by L = log2 N (the coarsest level), so x_f = 0 is the base level and 1 the
1x1 level; the lookup clamps x_f to [0, 1] exactly as GL clamps lambda to [0, L] (magnification
= level 0). The paper takes |duv/dx x duv/dy| (an area); the max-axis length is what the
emulated GL sampler uses, so the network and its target agree on what "footprint" means.
Keeping N inside the bundle makes the shader texture-size agnostic.

N_lod = L + 1: with the identity ramp in lod_primary each cascaded LOD slice starts exactly on
one mip level (paper: N_lod ~ log2 N_base, then tuned).

Training data (paper supp. 1.4): uv stratified (one jittered sample per texel, per epoch); the
linear footprint x = u^n, u ~ U(0, 1), n = log_p(1 / N) with p = 0.5 (half the samples in LOD 0),
i.e. log2_footprint = n log2 u. Target: ``emulated_trilinear`` -- the box-filtered mip chain
(2x2 means, each level rounded to 8 bits like an RGB8 texture's), bilinear in two levels
(GL_REPEAT wrap, texel centres at (i + 0.5) / n) mixed by the fractional LOD, i.e.
GL_LINEAR_MIPMAP_LINEAR. Colour as models/texture_cascade.py: arrays hold sRGB-encoded
values (filtering happens on the encoded values, as for an RGB8 texture); the graph decodes.

    from inshade.techniques.di_footprint import train as fp
    image, notes, source = fp.load_texture("skimage:astronaut", 256)
    result = fp.train_sampler(image, ratio=6)
    fp.write_asset(result, "/tmp/di_assets/di_footprint")

Command: ``inshade train di_footprint --out DIR [--preset quick|ship]``. ``--preset ship`` is exactly
what built trained/di_footprint (3000 steps); ``quick`` (the default) trains 1500; DIR/metrics.json
records the preset and the resolved settings.
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
from inshade.trainer import (Run, Trainer, batch_setting, check_fit, lr_setting, print_notes, seed_setting, setting,
                             steps_setting)
from inshade.metrics import srgb_eotf
from inshade.models import indirection as di
from inshade.models import texture_cascade as tc
from inshade.models.fit_loop import history_rows
from inshade.models.footprint_sampler import (CAMERA, EXTENT, N_CASCADED, PRIMARY_CHANNELS, TILE, FootprintError,
                                              Sizing, footprint_sampler, held_out_set, lod_sets, mip_chain,
                                              plan, sampler_graph, texture_bytes, texture_tensor)
from inshade.models.graph import GraphModule
from inshade.scene.builder import (choice_setting, display_modes, exposure_setting, float_setting,
                                    lut_filter_setting, network, requires, scene_json, text_label, texture)
from inshade.techniques.di_footprint import MODES
from inshade.provenance import recorded_at

KIND = "di_footprint"
RENDER_PROGRAM = "passes/footprint_plane.frag"


@dataclass(frozen=True)
class Settings:
    """What a di_footprint run is built from (metrics.json records it)."""
    image: str = setting("skimage:astronaut", "image file or skimage:NAME")
    size: int = setting(256, "centre-crop and resize to SIZE^2, a power of two")
    ratio: float = setting(6.0, "compression vs the RGB8 base level")
    n_cascaded: int = setting(N_CASCADED, "N_c (multiple of 4)")
    steps: int = steps_setting(1500)
    lr: float = lr_setting(1e-2)
    batch: int = batch_setting(16384)
    schedule: str = setting("cosine", "learning-rate schedule", choices=sorted(di.SCHEDULES))
    seed: int = seed_setting()


# --preset: "ship" is what built trained/di_footprint; "quick" keeps the 1500-step default.
PRESETS = {"quick": {}, "ship": dict(steps=3000)}
# One thread: on the shared 2-core machines torch's intra-op threads spin against each other and
# against other processes; one thread measured ~10x faster per step (0.045 s vs 0.46 s at load 4).
THREADS = 1


def export_graph(core: GraphModule, channels: int) -> GraphModule:
    """The bundle graph: the trained arrays, then the sRGB decode to linear (k = 1 or 3)."""
    g = GraphModule(core.inputs)
    for name in ("primary", "lod", "lod_primary", "cascaded"):
        g.add(name, core.nodes[name], core.wiring[name])
    out = tc.decode_nodes(g, "cascaded", channels)
    g.output("rgb" if channels == 3 else "grey", out, "linear_rgb" if channels == 3 else "linear")
    for p in g.parameters():
        p.requires_grad_(False)
    return g


# ---------------------------------------------------------------------------------------------
# input

def load_texture(spec: str, size: int | None = Settings.size):
    """(image float32 [N, N, k] sRGB-encoded, row 0 = top; notes; source) from a file or
    skimage:NAME, centre-cropped and resized to `size` (a power of two) when given."""
    image, notes, source = tc.load_image(spec, size)
    if image.shape[2] not in (1, 3):
        raise FootprintError(f"{spec}: {image.shape[2]} channels; the footprint sampler decodes colour "
                             "(1 grey or 3 RGB channels)")
    n = image.shape[0]
    if n & (n - 1):
        raise FootprintError(f"{spec}: {n}x{n} is not a power of two (a full mip chain halves to 1x1); "
                             "pass --size 256")
    return image, notes, source


# ---------------------------------------------------------------------------------------------
# train

@dataclass
class Result:
    graph: GraphModule          # bundle graph
    bundle: object              # inshade.bundle.Bundle (8-bit arrays)
    history: di.History
    image: np.ndarray           # [N, N, k] sRGB-encoded, row 0 = top
    sizing: Sizing
    metrics: dict = field(default_factory=dict)


def quantised_metrics(bundle, image: np.ndarray) -> dict:
    """PSNR (encoded values, peak 1) of the exported (8-bit) sampler vs the emulated trilinear
    sampler: on held-out samples of the training distribution and at each integer LOD."""
    tex = texture_tensor(image)
    chain = mip_chain(tex)
    g = GraphModule.from_bundle(bundle)
    core = _encoded_output(g)
    x, y = held_out_set(tex, chain=chain)
    with torch.no_grad():
        out = {"psnr_heldout": round(di.psnr(core(x), y), 4)}
        per = {}
        for level, (xl, yl) in lod_sets(tex, chain=chain).items():
            per[str(level)] = round(di.psnr(core(xl), yl), 3)
    out["psnr_per_lod"] = per
    return out


def _encoded_output(g: GraphModule) -> GraphModule:
    """A view of a bundle graph that stops at the cascaded array (sRGB-encoded values)."""
    core = GraphModule(g.inputs)
    for name in ("primary", "lod", "lod_primary", "cascaded"):
        core.add(name, g.nodes[name], g.wiring[name])
    core.output("values", "cascaded")
    return core


def train_sampler(image: np.ndarray, ratio: float = Settings.ratio, *,
                  n_cascaded: int = Settings.n_cascaded, steps: int = Settings.steps,
                  lr: float = Settings.lr, batch: int = Settings.batch,
                  schedule: str = Settings.schedule, seed: int = Settings.seed,
                  threads: int | None = THREADS, provenance: dict | None = None, name: str = KIND,
                  progress: bool | None = None, device=None) -> Result:
    """Train the footprint sampler on `image` ([N, N, k] sRGB-encoded in [0, 1], N a power of
    two, k 1 or 3) against the emulated trilinear sampler; export at 8 bits. `threads`: torch
    intra-op threads while training (None: leave as is). `device` (default the CPU): where the
    training and its data (mip chain, targets) live; the export and its metrics are on the CPU."""
    device = torch.device("cpu") if device is None else torch.device(device)
    prev = torch.get_num_threads()
    if threads:
        torch.set_num_threads(int(threads))
    try:
        return _train(image, ratio, n_cascaded, steps, lr, batch, schedule, seed, provenance, name, progress, device)
    finally:
        torch.set_num_threads(prev)


def _train(image, ratio, n_cascaded, steps, lr, batch, schedule, seed, provenance, name, progress,
           device) -> Result:
    image = np.asarray(image, np.float32)
    if image.ndim != 3 or image.shape[0] != image.shape[1] or image.shape[2] not in (1, 3):
        raise FootprintError(f"image: expected [N, N, 1 or 3], got shape {image.shape}")
    size, k = image.shape[0], image.shape[2]
    sizing = plan(size, k, ratio, n_cascaded)
    tex = texture_tensor(image).to(device)
    chain = mip_chain(tex)
    torch.manual_seed(seed)
    core = sampler_graph(size, sizing, image.reshape(-1, k).mean(0)).to(device)
    eval_set = held_out_set(tex, 16384, seed=seed + 1, chain=chain)
    t0 = time.perf_counter()
    history = di.train_cascade(core, footprint_sampler(tex, batch, seed, chain), steps, lr=lr,
                               schedule=schedule, seed=seed, eval_set=eval_set, progress=progress, desc=name)
    seconds = time.perf_counter() - t0
    core = core.to("cpu")       # export and metrics on the CPU
    graph = export_graph(core, k)
    prov = {
        "technique": "Differentiable Indirection footprint-aware texture sampler (Datta et al. 2023, "
                     "supp. 1.4): 2D primary (3 ch, (u,v,u) ramp) + 1D footprint primary (4 N_lod) -> "
                     "4D cascaded N_c^3 x N_lod; triangle F; 8-bit arrays; no mip chain stored",
        "footprint": "input log2_footprint = log2(max(|duv/dx|, |duv/dy|)) in uv units (GL's isotropic "
                     "max-axis LOD rule); node 'lod' maps it to (log2_footprint + log2 N) / log2 N",
        "training": f"stratified uv, footprint x = u^n (n = log2 N, half the samples in LOD 0), targets "
                    f"from the emulated GL trilinear sampler (box mip chain rounded to 8 bits, GL_REPEAT); "
                    f"L1, Adam lr {lr:g}, {schedule}, batch {batch}, {steps} steps, seed {seed}",
        "colour": "arrays hold sRGB-encoded values; the graph decodes to linear (sRGB EOTF tables)",
        "uv_convention": "uv (0,0) = bottom-left of the picture; the shader passes fract(tiled uv)",
        "torch": torch.__version__, "device": str(device),
        **recorded_at(),
    }
    prov.update(provenance or {})
    metrics = {
        "size": size, "channels": k, "ratio_requested": float(ratio),
        "bytes": sizing.bytes, "bytes_with_headers": sizing.bytes + 8 * (PRIMARY_CHANNELS + 1 + k),
        "texture_bytes_base": texture_bytes(size, k, False), "texture_bytes_mips": texture_bytes(size, k, True),
        "ratio_vs_base": round(texture_bytes(size, k, False) / sizing.bytes, 4),
        "ratio_vs_mip_chain": round(texture_bytes(size, k, True) / sizing.bytes, 4),
        "n_primary": sizing.n_primary, "n_footprint": sizing.n_footprint, "n_cascaded": sizing.n_cascaded,
        "n_lod": sizing.n_lod, "rho": round(sizing.rho, 4),
        "train_seconds": round(seconds, 2), "steps": steps,
        "psnr_step0": round(history.records[0]["psnr"], 4), "psnr_float": round(history.final["psnr"], 4),
        "history": history_rows(history.records, "psnr", 3),
    }
    bundle = graph.export(KIND, name, provenance=prov, metrics=metrics)
    metrics.update(quantised_metrics(bundle, image))
    bundle = graph.export(KIND, name, provenance=prov, metrics=metrics)
    return Result(graph, bundle, history, image, sizing, metrics)


# ---------------------------------------------------------------------------------------------
# asset folder



def scene_dict(name: str, title: str, output: str, size=(512, 256), gl_modes: bool = False) -> dict:
    """The asset's scene. `gl_modes` adds the GL comparison modes (a FOOTPRINT_MODE define and the
    uncompressed texture bound as u_texture / u_texture_aniso): it needs scene.json "textures"
    support in scene/description.py + runtime/renderer.py, which the shipped renderer lacks (the report
    of this module's author carries the diff); without it the scene shows the DI sampler only."""
    settings = {
        "exposure": exposure_setting(),
        "extent": float_setting(EXTENT, 0.5, 1000.0, "plane half-size (world units)", uniform="u_extent"),
        "tile": float_setting(TILE, 0.05, 20.0, "tile size (world units)", uniform="u_tile"),
        "lut_filter": lut_filter_setting(),
    }
    notes = ("DI footprint sampler only: the GL trilinear / anisotropic / no-mip comparison modes of "
             "the same pass need the uncompressed texture bound (inshade bench di_footprint renders them)")
    gl = {}
    if gl_modes:
        modes = ", ".join(f"{v} {k}" for k, v in MODES.items())
        settings["mode"] = choice_setting(MODES["di"], sorted(MODES.values()), "sampler: " + modes,
                                          define="FOOTPRINT_MODE")
        notes = "--set mode=N: " + modes
        names = {"di": "DI footprint sampler", "trilinear": "GL trilinear (mip chain)",
                 "anisotropic": "GL anisotropic 16x", "bilinear": "GL bilinear (no mips)",
                 "explicit_lod": "GL explicit LOD"}
        gl = {"textures": [texture("u_texture", "texture.png", mipmaps=True),
                           texture("u_texture_aniso", "texture.png", mipmaps=True, anisotropy=16.0)],
              "labels": [text_label(names.get(k, k), (0.02, 0.95), {"mode": v}, align="left")
                         for k, v in MODES.items()]}
    return scene_json(
        name, title, RENDER_PROGRAM, size,
        networks=[network(".", "net", output=output)],
        camera=CAMERA,
        bookmarks={
            "grazing": CAMERA,
            "steeper": {**CAMERA, "position": [0.0, 0.6, 0.0], "pitch": -25.0},
            "horizon": {**CAMERA, "position": [0.0, 0.15, 0.0], "pitch": -3.0},
        },
        lights=[], environment=None,
        display=display_modes("final", "network"),
        settings=settings,
        requires=requires(),
        notes=notes,
        **gl,
    )


def write_asset(result: Result, out, title: str | None = None, preview_size=(512, 256),
                gl_modes: bool = False) -> Path:
    """bundle.json + weights.safetensors + scene.json + texture.png (the 8-bit source) +
    preview.png (the scene rendered through the GL driver, DI mode)."""
    from inshade.runtime.headless import render_scene
    from inshade.scene.image_io import write_png

    out = Path(out)
    result.bundle.save(out)
    output = result.graph.outputs[0][0]
    title = title or f"DI footprint sampler, {result.metrics['ratio_vs_base']:.1f}x vs RGB8 (no mip chain)"
    atomic_write(out / "scene.json", json.dumps(scene_dict(out.name, title, output, preview_size, gl_modes), indent=2) + "\n")
    src = result.image if result.image.shape[2] == 3 else np.repeat(result.image, 3, -1)
    write_png(out / "texture.png", srgb_eotf(src))
    image, _ = render_scene(out, width=preview_size[0], height=preview_size[1])
    write_png(out / "preview.png", image[..., :3])
    return out


# ---------------------------------------------------------------------------------------------
# command line

def extra_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--threads", type=int, default=THREADS, help="torch threads while training (0: torch's default)")
    p.add_argument("--title", help="scene title")


def train(run: Run) -> int:
    s, args = run.settings, run.args
    image, notes, source = load_texture(s.image, s.size)
    print_notes(notes)
    result = train_sampler(image, s.ratio, n_cascaded=s.n_cascaded, steps=s.steps, lr=s.lr, batch=s.batch,
                           schedule=s.schedule, seed=s.seed, threads=args.threads or None, name=run.out.name,
                           device=run.device,
                           provenance={"command": run.command, "image": source, "image_notes": notes})
    out = write_asset(result, run.out, args.title)
    m = result.metrics
    return run.finish(out, m, f"{m['bytes']} bytes ({m['ratio_vs_base']:.2f}x vs RGB8, {m['ratio_vs_mip_chain']:.2f}x "
                              f"vs RGB8 + mips; N_p0 {m['n_primary']}, N_p1 {m['n_footprint']}, N_c {m['n_cascaded']}, "
                              f"N_lod {m['n_lod']}), held-out PSNR vs emulated trilinear {m['psnr_heldout']:.2f} dB "
                              f"(8-bit arrays), {m['train_seconds']:.1f} s")


TRAINER = Trainer(KIND, __doc__, Settings, PRESETS, train, folder=lambda s: KIND,
                  folder_hint=KIND, ship_assets={KIND: {}},
                  extra_arguments=extra_arguments, check=lambda s: check_fit(s, FootprintError),
                  errors=(FootprintError, tc.CompressionError))
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
