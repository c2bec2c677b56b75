"""Texture compression with Differentiable Indirection (Datta et al. 2023 §4.2.1).

A texture (k <= 8 channels, 8-bit) becomes a 2D primary array (4 channels,
triangle F) looked up at uv, whose output indexes a 4D cascaded array holding the
k channels. Both arrays are exported at 8 bits; the byte budget is the uncompressed size
(W * H * k bytes) divided by the ratio, solved by `indirection.size_cascade` (N_p a multiple of
8, N_c a multiple of 4; the cascaded side by models/texture_cascade.py CASCADE_SIDES). Training (see
models/texture_cascade.py DEFAULTS, where the measurements are): both arrays start from the image's
principal colour axes (`init="pca"`: the cascade an affine map along them, the primary the image's
coordinates on them; the paper's uv ramp is `init="ramp"`), then Adam with a cosine schedule on the
squared error over batches that are half texel centres -- the points PSNR (ours and the block
codecs') scores -- and half stratified points with bilinear targets, which filtering reads between
texels (`finish` = 1, the fraction of the steps on those batches; the rest runs first on the paper's
stratified L1; `finish_optimizer="lbfgs"` runs that part as full-batch L-BFGS on the texel centres).
`finish=0 --init ramp` is the paper's protocol.

Colour: the arrays hold the sRGB-*encoded* values (what an RGB8 texture, ASTC and BC compress),
so 8-bit cells lose no more than the source's own precision. The bundle then decodes to linear
light, as the renderer expects (passes/field2d.frag shows linear output; PNGs are sRGB-encoded
on write): for colour textures (k = 1 or 3) each channel is picked by a one-hot dense node and
passed through a fixed 256-entry float32 1D lookup of the sRGB EOTF (piecewise-linear; at most
6e-6 from the exact curve, far below one 8-bit step) -- the job an SRGB8 texture format does in
hardware. These decode tables are the same for every texture and are not counted in the
compressed bytes (reported as `decode_table_bytes`).

Orientation follows inshade/pixels.py: uv (0, 0) is the bottom-left of the picture.

    from inshade.models.texture_cascade import compress, load_image
    image, notes, source = load_image("skimage:astronaut", size=256)
    result = compress(image, ratio=6)
    result.bundle.save("/tmp/di_texture_astronaut")

Command: ``inshade train di_texture IMAGE --ratio 6 [--preset quick|ship] --force -o trained/di_texture_<name>``
(IMAGE a file or ``skimage:NAME``; ``inshade compress`` is the same command). ``--preset ship`` with a
shipped asset's IMAGE, ``--size`` and ``--ratio`` (SHIP_ASSETS) is exactly what built it; OUT/metrics.json
records the preset and the resolved settings.
"""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.files import atomic_write
from inshade.trainer import (Run, Trainer, batch_setting, check_fit, lr_setting, print_notes, seed_setting, setting,
                             steps_setting)
from inshade.metrics import psnr, srgb_eotf
from inshade.models import indirection as di
from inshade.scene.builder import (display_modes, exposure_setting, float_setting, lut_filter_setting, network,
                                    plane2d, reference, requires, scene_json)
from inshade.models.texture_cascade import (DEFAULTS as CASCADE_DEFAULTS, FIELD_PROGRAM, FINISH_OPTIMIZERS,
                                            INITS, CompressionError, Result, compress, load_image, to_srgb8,
                                            torch_decode)

RENDER_PROGRAM = FIELD_PROGRAM


@dataclass(frozen=True)
class Settings:
    """What a di_texture run is built from (metrics.json records it)."""
    image: str = setting(None, "image file (PNG/JPEG/...) or skimage:NAME (e.g. skimage:astronaut)",
                         positional="IMAGE")
    size: int | None = setting(None, "centre-crop to a square and resize to SIZE x SIZE first")
    ratio: float = setting(CASCADE_DEFAULTS["ratio"], "compression ratio vs 8-bit")
    rho: float | None = setting(CASCADE_DEFAULTS["rho"],
                                "N_p / N_c (None: the cascaded side CASCADE_SIDES chooses, the largest primary "
                                "next to it)")
    steps: int = steps_setting(1500)
    lr: float = lr_setting(CASCADE_DEFAULTS["lr"])
    batch: int = batch_setting(CASCADE_DEFAULTS["batch"])
    schedule: str = setting(CASCADE_DEFAULTS["schedule"], "learning-rate schedule", choices=sorted(di.SCHEDULES))
    finish: float = setting(CASCADE_DEFAULTS["finish"], "fraction of the steps trained last with the squared error "
                            "on texel centres and stratified points (0: the paper's stratified L1 throughout)")
    finish_optimizer: str = setting(CASCADE_DEFAULTS["finish_optimizer"], "finish phase: minibatch Adam under "
                                    "the same schedule, or full-batch L-BFGS on all texel centres with the same "
                                    "sample budget", choices=FINISH_OPTIMIZERS)
    init: str = setting(CASCADE_DEFAULTS["init"], "starting point: the image's principal colour axes (pca) or "
                        "the paper's uv ramp with a mean-colour cascade (ramp)", choices=INITS)
    seed: int = seed_setting(CASCADE_DEFAULTS["seed"])


# Training lengths: "quick" runs in well under a minute at 256^2 on one CPU thread; "ship" is what the
# trained/ assets use (12000 steps: 3-4 min a texture at 256^2 or 1K on one thread of the quiet 2-core machine).
PRESETS = {"quick": {}, "ship": dict(steps=12000)}
# The inputs of each shipped asset (IMAGE, --size, --ratio beside --preset ship).
SHIP_ASSETS = {"di_texture_astronaut": dict(image="skimage:astronaut", size=256, ratio=6.0),
               "di_texture_astronaut_12x": dict(image="skimage:astronaut", size=256, ratio=12.0),
               "di_texture_chelsea": dict(image="skimage:chelsea", size=256, ratio=6.0),
               "di_texture_coffee": dict(image="skimage:coffee", size=256, ratio=6.0)}


def decoded_metrics(bundle, image: np.ndarray, linear: bool, filters=("exact", "fast"), progress=None) -> dict:
    """PSNR (sRGB 8-bit) of the GLSL-decoded texture per LUT path, and the exact path's max
    difference from torch on the same (quantised) bundle."""
    from inshade.runtime.context import gl_info, shared_context
    from inshade.runtime.network import evaluate_on_pixels

    if progress is not False:
        print(f"{bundle.name}: decoding through the GLSL (exact and fast lookups) for its PSNR", file=sys.stderr,
              flush=True)
    size = image.shape[0]
    ref8 = to_srgb8(image, False)
    ctx = shared_context()
    out = {"gl_renderer": gl_info(ctx)["renderer"]}
    ref_torch = torch_decode(bundle, size)
    out["psnr_srgb8_torch"] = round(psnr(to_srgb8(ref_torch, linear), ref8, 255.0), 4)
    for f in filters:
        dec = evaluate_on_pixels(bundle, size, f, ctx)
        out[f"psnr_srgb8_glsl_{f}"] = round(psnr(to_srgb8(dec, linear), ref8, 255.0), 4)
        out[f"max_abs_diff_glsl_{f}_vs_torch"] = float(np.max(np.abs(dec.astype(np.float64) - ref_torch)))
    return out


# ---------------------------------------------------------------------------------------------
# asset folder

def scene_dict(name: str, title: str, size: int, output: str, lut_filter: str = "exact") -> dict:
    return scene_json(
        name, title, RENDER_PROGRAM, (size, size),
        networks=[network(".", "net", output=output)],
        reference=reference("reference.png", "srgb", "field"),
        camera=plane2d(),
        bookmarks={"whole picture": plane2d(), "detail 4x": plane2d((0.45, 0.6), 4.0)},
        lights=[], environment=None,
        display=display_modes("final", "network", "reference", "error", "split"),
        settings={
            "exposure": exposure_setting(),
            "error_scale": float_setting(4.0, 1.0, 64.0, "error x", uniform="u_error_scale"),
            "lut_filter": lut_filter_setting(lut_filter),
        },
        requires=requires(),
    )


def write_asset(result: Result, out, title: str, lut_filter: str = "exact") -> Path:
    """bundle.json + weights.safetensors + scene.json + preview.png (torch decode of the quantised
    bundle, linear) + reference.png (the 8-bit original)."""
    from inshade.scene.image_io import write_png

    out = Path(out)
    result.bundle.save(out)
    size = result.image.shape[0]
    output = result.graph.outputs[0][0]
    if result.bundle.meta.get("render"):
        atomic_write(out / "scene.json", json.dumps(scene_dict(out.name, title, size, output, lut_filter),
                                                   indent=2) + "\n")
        preview = torch_decode(result.bundle, size)
        ref = srgb_eotf(result.image)
        if preview.shape[-1] == 1:
            preview, ref = np.repeat(preview, 3, -1), np.repeat(ref, 3, -1)
        write_png(out / "preview.png", preview)
        write_png(out / "reference.png", ref)
    return out


# ---------------------------------------------------------------------------------------------
# command line

def extra_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--lut-filter", choices=("exact", "fast"), default="exact",
                   help="the scene's default LUT path (default %(default)s)")
    p.add_argument("--title", help="scene title")
    p.add_argument("--no-gl", action="store_true", help="skip the GLSL-decoded metrics (no GL context)")


def train(run: Run) -> int:
    s, args = run.settings, run.args
    image, notes, source = load_image(s.image, s.size)
    print_notes(notes)
    result = compress(image, s.ratio, rho=s.rho, steps=s.steps, lr=s.lr, batch=s.batch, schedule=s.schedule,
                      seed=s.seed, finish=s.finish, finish_optimizer=s.finish_optimizer, init=s.init,
                      measure=None if args.no_gl else decoded_metrics, name=run.out.name, device=run.device,
                      provenance={"command": run.command, "image": source, "image_notes": notes})
    title = args.title or f"DI texture: {source}, {result.metrics['ratio']:.2f}x"
    out = write_asset(result, run.out, title, args.lut_filter)
    m = result.metrics
    gl = (f", GLSL exact {m['psnr_srgb8_glsl_exact']:.2f} dB / fast {m['psnr_srgb8_glsl_fast']:.2f} dB"
          if "psnr_srgb8_glsl_exact" in m else "")
    return run.finish(out, m, f"{m['ratio']:.2f}x ({m['bytes']} bytes, N_p {m['n_primary']}, N_c {m['n_cascaded']}), "
                              f"PSNR sRGB8 torch "
                              f"{m['psnr_srgb8_torch'] if 'psnr_srgb8_torch' in m else m['psnr_quantised']:.2f} dB"
                              f"{gl}, {m['train_seconds']:.1f} s")


TRAINER = Trainer("di_texture", __doc__, Settings, PRESETS, train,
                  folder=lambda s: f"di_texture_{Path(s.image.removeprefix('skimage:')).stem}",
                  folder_hint="di_texture_<image>",
                  ship_assets=SHIP_ASSETS, extra_arguments=extra_arguments,
                  check=lambda s: check_fit(s, CompressionError), errors=(CompressionError,))
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
