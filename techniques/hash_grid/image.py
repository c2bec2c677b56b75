"""The image application: uv -> sRGB colour of a 2048x2048 photograph collage (mosaic.py), a hash
grid + MLP drawn by the shared passes/field2d.frag exactly as neural_image is.

Colour: the network fits the 8-bit sRGB values (/255) with MSE, as image codecs and instant-NGP's
image example do; its output port has semantic ``srgb``, so field2d decodes it to linear light
(FIELD_OUT_SRGB). PSNR is reported on sRGB values (what a codec reports) and in linear light (the
other house trainers' first number), on the output clipped to [0, 1] as shown.

Orientation: uv (0, 0) is the bottom-left of the picture (inshade/pixels.py), every pixel sampled at
its centre. Batches are random pixels drawn on a CPU generator (the same on every device).
"""
from __future__ import annotations

import io
import json
import time

import numpy as np
import torch

from inshade.metrics import psnr, psnr_from_mse, srgb_eotf
from inshade.models.graph import GraphModule
from inshade.pixels import pixel_uvs
from inshade.provenance import recorded_at
from inshade.quantize import quantized
from inshade.scene.builder import (choice_setting, display_modes, exposure_setting, float_setting, network,
                                    plane2d, reference, requires, scene_json)

from . import mosaic
from .network import add_frequency_mlp, add_hash_grid, add_mlp, grid_shape, network_bytes, optimizer

KIND = "hash_grid_image"
RENDER_PROGRAM = "passes/field2d.frag"
CHUNK = 65536
PREVIEW = (872, 500, 512)    # preview.png: (top row, left column, side) of the target at native resolution


def load_target(size: int) -> np.ndarray:
    """The collage as sRGB float32 [size, size, 3] in [0, 1] (row 0 = top): the 8-bit pixels / 255,
    block-averaged when ``size`` is below the collage's 2048 (a divisor of it: quick runs)."""
    pixels = mosaic.mosaic().astype(np.float32) / np.float32(255.0)
    if size == mosaic.SIZE:
        return pixels
    if size < 1 or mosaic.SIZE % size:
        from .network import HashGridError

        raise HashGridError(f"--size {size}: must divide {mosaic.SIZE}")
    f = mosaic.SIZE // size
    return pixels.reshape(size, f, size, f, 3).mean((1, 3)).astype(np.float32)


def build(s, seed: int = 0) -> GraphModule:
    """uv[2] -> rgb[3] (sRGB) for the settings ``s``: the hash grid + MLP, or (``arch`` mlp) the
    frequency-encoded MLP of the hash grid's bytes."""
    g = GraphModule([("uv", 2, "uv")])
    shape = image_grid_shape(s)
    if s.arch == "mlp":
        out = add_frequency_mlp(g, "uv", s.n_freqs, s.baseline_depth, 3, network_bytes(hash_grid_of(s, shape)))
    else:
        out = add_mlp(g, add_hash_grid(g, "uv", shape, seed), s.width, s.depth, 3)
    g.output("rgb", out, "srgb")
    return g


def image_grid_shape(s):
    return grid_shape(2, levels=s.levels, features=s.features, base_resolution=s.base_resolution,
                      finest=s.finest or s.size, budget_bytes=int(s.budget_kb * 1024), width=s.width,
                      depth=s.depth, out_dim=3, log2_table_size=s.log2_table_size)


def hash_grid_of(s, shape) -> GraphModule:
    """The hash-grid network of the settings (for its byte count)."""
    g = GraphModule([("uv", 2, "uv")])
    g.output("rgb", add_mlp(g, add_hash_grid(g, "uv", shape), s.width, s.depth, 3), "srgb")
    return g


def predict(model: torch.nn.Module, width: int, height: int) -> np.ndarray:
    """The network at every pixel centre, [H, W, 3] float32 (image orientation), on the CPU."""
    device = next(model.parameters()).device
    uv = torch.from_numpy(pixel_uvs(width, height).reshape(-1, 2))
    with torch.no_grad():
        out = torch.cat([model(uv[i:i + CHUNK].to(device)).cpu() for i in range(0, uv.shape[0], CHUNK)], 0)
    return out.reshape(height, width, -1).numpy().astype(np.float32)


def quality(prediction: np.ndarray, target: np.ndarray) -> dict:
    """PSNR of the prediction clipped to [0, 1] (as shown) against the target, sRGB and linear."""
    shown = np.clip(prediction, 0.0, 1.0)
    return {"psnr_srgb": round(psnr(shown, target), 4),
            "psnr_linear": round(psnr(srgb_eotf(shown), srgb_eotf(target)), 4)}


def fit(g: GraphModule, target: np.ndarray, *, steps: int, batch: int, seed: int, lrs: dict,
        desc: str = "hash_grid image") -> dict:
    """Adam (network.optimizer) on MSE of random pixel batches, cosine-decayed; on the graph's device."""
    from inshade.models.fit_loop import cosine, fit as fit_steps

    h, w = target.shape[:2]
    device = next(g.parameters()).device
    uv = torch.from_numpy(pixel_uvs(w, h).reshape(-1, 2)).to(device)
    rgb = torch.from_numpy(target.reshape(-1, 3)).to(device)
    opt = optimizer(g, **lrs)
    gen = torch.Generator().manual_seed(seed)
    losses, start = [], time.perf_counter()

    def step_loss(step):
        idx = torch.randint(0, uv.shape[0], (batch,), generator=gen).to(device)
        return torch.mean((g(uv[idx]) - rgb[idx]) ** 2)

    def after(step, loss, bar):
        if step % 100 == 0 or step == steps - 1:
            losses.append((step, round(psnr_from_mse(max(float(loss.detach()), 1e-12)), 3)))
            bar.set_postfix(psnr=f"{losses[-1][1]:.2f}")

    fit_steps(opt, step_loss, steps, lr_factor=cosine(steps), after_step=after, desc=desc)
    return {"seconds": time.perf_counter() - start, "psnr_batches": losses}


def finetune(g: GraphModule, target: np.ndarray, s) -> float:
    """The quantization-aware fine-tune (precision below f32): ``finetune_steps`` more steps at a tenth of
    the rates with the dense weights (and, at i8, the grid's u8 codes) seen at ``precision``
    (models/quantize_aware.py); returns the sRGB
    PSNR the quantized network had before it."""
    from inshade.models.quantize_aware import quantizer_in_loop

    lrs = {k: v / 10 if k.endswith("_lr") else v for k, v in learning_rates(s).items()}
    with quantizer_in_loop(g, s.precision):
        before = quality(predict(g, s.size, s.size), target)["psnr_srgb"]
        fit(g, target, steps=s.finetune_steps, batch=s.batch, seed=s.seed + 1, lrs=lrs,
            desc=f"quantization-aware fine-tune ({s.precision})")
    return before


def train(run) -> int:
    """Fit, export, measure the exported bundle, write the asset folder."""
    s = run.settings
    torch.manual_seed(s.seed)
    target = load_target(s.size)
    g = build(s, s.seed).to(run.device)
    log = fit(g, target, steps=s.steps, batch=s.batch, seed=s.seed, lrs=learning_rates(s))
    before = finetune(g, target, s) if s.precision not in (None, "f32") else None
    g = g.cpu()
    shape = image_grid_shape(s)
    provenance = {
        "command": run.command, "preset": run.preset, "settings": run.record()["settings"],
        "image": f"a {mosaic.SIZE}x{mosaic.SIZE} collage of skimage.data photographs at native resolution"
                 + ("" if s.size == mosaic.SIZE else f", block-averaged to {s.size}x{s.size}"),
        "sources": mosaic.sources(),
        "colour": "the network fits 8-bit sRGB values / 255 (MSE); output semantic srgb",
        "uv_convention": "uv (0,0) = bottom-left of the picture, (1,1) = top-right; pixel centres",
        "optimizer": "adam betas (0.9, 0.99), tables and MLP in separate groups, cosine decay to 5%",
        "device": str(run.device), "torch": torch.__version__,
        **recorded_at(),
    }
    render = {"program": RENDER_PROGRAM, "width": s.size, "height": s.size, "input": "uv", "output": "rgb"}
    bundle = g.export(KIND, run.out.name, provenance=provenance, render=render)
    if before is not None:   # the values the fine-tune saw
        bundle = quantized(bundle, s.precision)
    shipped = GraphModule.from_bundle(bundle).eval()     # what the shader draws: fp16 tables as exported
    prediction = predict(shipped, s.size, s.size)
    metrics = {**quality(prediction, target),
               "bytes": network_bytes(g), "bytes_file": None,
               "params": int(sum(p.numel() for p in g.parameters())),
               "encoding": None if s.arch == "mlp" else {
                   "levels": shape.levels, "features": shape.features, "log2_table_size": shape.log2_table_size,
                   "base_resolution": shape.base_resolution, "per_level_scale": shape.per_level_scale,
                   "finest_resolution": shape.finest_resolution(), "table_rows": shape.rows(),
                   "table_bytes_fp16": shape.table_bytes()},
               **({"psnr_srgb_quantized_without_finetune": before} if before is not None else {}),
               "train_seconds": round(log["seconds"], 1), "psnr_batches": log["psnr_batches"],
               "train_threads": torch.get_num_threads(), "device": str(run.device)}
    if s.arch != "mlp" and s.baseline_steps > 0:
        metrics["mlp_baseline"] = baseline(s, target, network_bytes(g), run.device)
    bundle.meta["metrics"] = {k: v for k, v in metrics.items() if k != "psnr_batches"}
    save_fp16(bundle, run.out)
    metrics["bytes_file"] = bundle.meta["metrics"]["bytes_file"] = bundle_file_bytes(run.out)
    save_fp16(bundle, run.out)
    write_scene(run.out, s, metrics)
    from inshade.scene.image_io import write_png

    top, left, side = PREVIEW if s.size == mosaic.SIZE else (0, 0, s.size)
    write_png(run.out / "preview.png", srgb_eotf(np.clip(prediction[top:top + side, left:left + side], 0, 1)))
    write_reference(run.out / "reference.jpg", target)
    run.write_metrics(metrics)
    base = metrics.get("mlp_baseline")
    print(f"wrote {run.out}: PSNR {metrics['psnr_srgb']:.2f} dB sRGB, {metrics['psnr_linear']:.2f} dB linear, "
          f"{metrics['bytes']} bytes, {metrics['train_seconds']:.0f} s"
          + (f"; MLP-only at {base['bytes']} bytes: {base['psnr_srgb']:.2f} dB sRGB" if base else ""))
    return 0


def learning_rates(s) -> dict:
    return dict(grid_lr=s.grid_lr, mlp_lr=s.mlp_lr, grid_eps=s.grid_eps, mlp_eps=s.mlp_eps, mlp_l2=s.mlp_l2)


def baseline(s, target: np.ndarray, budget_bytes: int, device) -> dict:
    """The MLP-only network of the hash grid's bytes (frequency encoding + ReLU MLP), trained on
    the same pixels with the same optimiser for ``baseline_steps`` steps of ``baseline_batch``."""
    torch.manual_seed(s.seed)
    g = GraphModule([("uv", 2, "uv")])
    g.output("rgb", add_frequency_mlp(g, "uv", s.n_freqs, s.baseline_depth, 3, budget_bytes), "srgb")
    g = g.to(device)
    log = fit(g, target, steps=s.baseline_steps, batch=s.baseline_batch, seed=s.seed,
              lrs={**learning_rates(s), "mlp_lr": s.baseline_lr}, desc="mlp baseline")
    g = g.cpu().eval()
    widths = [m.linear.out_features for m in g.nodes.values() if m.type == "dense"]
    return {**quality(predict(g, s.size, s.size), target), "bytes": network_bytes(g),
            "network": f"frequency({s.n_freqs}) -> " + " -> ".join(f"dense {w}" for w in widths),
            "steps": s.baseline_steps, "batch": s.baseline_batch, "lr": s.baseline_lr,
            "train_seconds": round(log["seconds"], 1)}


def save_fp16(bundle, out) -> None:
    """The bundle with its fp16 tables stored as F16 (half the file; widened exactly at load; u8 codes as
    they are)."""
    tensors = bundle.tensors
    bundle.tensors = {k: (v.astype(np.float16) if k.endswith(".table") and v.dtype.kind == "f" else v)
                      for k, v in tensors.items()}
    try:
        bundle.save(out)
    finally:
        bundle.tensors = tensors


def bundle_file_bytes(out) -> int:
    return sum((out / n).stat().st_size for n in ("bundle.json", "weights.safetensors"))


def write_reference(path, target: np.ndarray) -> None:
    """The target as a JPEG (quality 95, no chroma subsampling): the scene's reference for the
    viewer's reference / error / split views. Metrics are measured against the exact target."""
    from PIL import Image

    from inshade.files import atomic_write

    buf = io.BytesIO()
    Image.fromarray(np.round(np.clip(target, 0, 1) * 255).astype(np.uint8)).save(
        buf, format="JPEG", quality=95, subsampling=0)
    atomic_write(path, buf.getvalue())


def write_scene(out, s, metrics: dict) -> None:
    from inshade.files import atomic_write

    side = min(s.size, 1024)
    native = s.size / side    # zoom at which one screen pixel is one image pixel
    scene = scene_json(
        out.name, f"Hash grid image: {s.size}x{s.size} photograph collage, {metrics['bytes'] / 1024:.0f} KiB, "
                  f"{metrics['psnr_srgb']:.1f} dB sRGB",
        RENDER_PROGRAM, (side, side),
        networks=[network(".", "net", output="rgb")],
        reference=reference("reference.jpg", "srgb", "field"),
        camera=plane2d(),
        bookmarks={"whole picture": plane2d(),
                   "astronaut, native pixels": plane2d((0.487, 0.452), native),
                   "galaxies, 4x": plane2d((0.2, 0.8), 4 * native),
                   "retina vessels, 4x": plane2d((0.56, 0.86), 4 * native)},
        lights=[], environment=None,
        display=display_modes("final", "network", "reference", "error", "split"),
        settings={
            "exposure": exposure_setting(),
            "error_scale": float_setting(4.0, 1.0, 64.0, "error x", uniform="u_error_scale"),
            "storage": choice_setting("auto", ["auto", "inline", "ubo", "texture"], "weight storage",
                                      codegen="storage"),
        },
        requires=requires(),
    )
    atomic_write(out / "scene.json", json.dumps(scene, indent=1) + "\n")


def psnr_of_bundle(bundle, size: int | None = None) -> dict:
    """The shipped bundle's PSNR recomputed by the torch twin against the target."""
    s = size or bundle.meta["render"]["width"]
    return quality(predict(GraphModule.from_bundle(bundle).eval(), s, s), load_target(s))

