"""Neural image: a 2D field uv -> linear RGB fitted to one photograph.

The first shipped asset (``trained/neural_image``) and the smallest end-to-end example of the
data flow: torch training here, ``codegen.network.generate`` for the GLSL, and
``shaders/passes/field2d.frag`` + ``runtime/headless.py`` to render it without torch.

Orientation (decided once; the shader and the torch preview both follow it): ``uv`` is the GL
texture convention, ``(0, 0)`` the *bottom-left* corner of the picture and ``(1, 1)`` the
top-right, so ``v`` grows upwards. Pixel ``(column c, row r)`` of an image-oriented array
(row 0 = top) is sampled at its centre, ``uv = ((c + 0.5) / W, (H - 1 - r + 0.5) / H)``; that is
``gl_FragCoord.xy / size`` for the GL pixel the read-back (``render.read_rgba``) puts at row r.

Colour: the target is the sRGB photograph decoded to linear light (sRGB EOTF); the network
outputs linear RGB and the loss is MSE in linear light. PSNR is reported both in linear light
and after sRGB encoding.

Architectures (``--arch``): ``multires`` (the shipped one: a multiresolution set of 2D lookup
arrays of uv, concatenated into a small ReLU MLP: an Instant-NGP-style dense feature pyramid made
of existing components), ``frequency_relu`` (NeRF frequency encoding + ReLU MLP) and ``siren``.

Command: ``inshade train neural_image [--preset quick|ship] [--device auto|cpu|cuda[:N]]
[--out DIR] [--force] [--steps N] [--image NAME] [--seed S] [--size N] [--arch A] [--levels R:C,...]``. ``--preset ship`` (the
default) is exactly what built ``trained/neural_image``; ``--preset quick`` is the same network
trained for fewer steps; any option given explicitly overrides the preset's value.
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass

import numpy as np
import torch

from inshade.components.elementwise import torch_twin as _act
from inshade.components.encodings import torch_twin as _enc
from inshade.components.lookup_array.torch_twin import LookupArray
from inshade.files import atomic_write
from inshade.metrics import mse, psnr, psnr_from_mse, srgb_eotf, srgb_oetf
from inshade.models.graph import GraphModule
from inshade.pixels import pixel_uvs
from inshade.provenance import recorded_at
from inshade.quantize import quantized
from inshade.trainer import Run, Trainer, finetune_setting, precision_setting, seed_setting, setting

IMAGES = ("astronaut", "chelsea", "coffee", "camera", "rocket")  # skimage.data names (RGB or grey)
ARCHES = ("multires", "siren", "frequency_relu")
OUTPUT_ACTIVATIONS = ("identity", "sigmoid")

# Before the multires arch (kept for comparison, astronaut 256x256, 800 steps, batch 4096, shared
# 2-core CPU): frequency(8)+relu 64x3, identity out, lr 2e-3: 22.95 dB linear in 105 s; SIREN 64x3
# omega0=30, lr 3e-4: 23.03 dB in 174 s; the 1500-step frequency_relu asset reached 24.79 dB linear
# (21.85 dB sRGB 8-bit): visibly blurry.
#
# The shipped settings (``--preset ship``): SHIP_NOTE below records how they were chosen.
SHIP_NOTE = (
    "multires levels chosen on astronaut 256x256, full-image batches, 1 thread of a shared 2-core CPU, "
    "width 32 x depth 2 MLP, 8-bit arrays (dB linear / sRGB): 32:4,64:4,128:4 (87k params, 300 steps) "
    "32.4 / 28.3; 16:4,32:4,64:4,128:2 (56k, 600 steps) 33.5 / 31.0; 16,32,64,128,256 x 2 channels "
    "(176k, 300 steps) 41.3 / 33.6; 32:4,64:4,128:2,256:1 (120k, 600 steps) 44.4 / 36.9; "
    "32:4,64:4,256:1 (87k, 600 steps) 41.2 / 34.6: shipped, trained 1000 steps. The one-channel "
    "full-resolution level carries the detail, the coarse four-channel ones the colour.")
SHIP = dict(arch="multires", levels="32:4,64:4,256:1", width=32, depth=2, steps=1000, batch=65536, grid_bits=8,
            output_activation="identity")
PRESETS = {"ship": SHIP, "quick": {**SHIP, "steps": 300}}     # quick: the same network, fewer steps
RENDER_PROGRAM = "passes/field2d.frag"
ASSET = "neural_image"


class NeuralImageError(ValueError):
    """A setting the neural image cannot be trained with."""


@dataclass(frozen=True)
class Settings:
    """What a neural_image run is built from; metrics.json records those its architecture uses (recorded())."""
    image: str = setting("astronaut", "skimage.data photograph", choices=IMAGES)
    size: int = setting(256, "target resolution, square")
    steps: int = setting(SHIP["steps"], "optimizer steps")
    seed: int = seed_setting()
    arch: str = setting(SHIP["arch"], "network", choices=ARCHES)
    width: int = setting(SHIP["width"], "hidden width")
    depth: int = setting(SHIP["depth"], "hidden layers")
    n_freqs: int = setting(8, "frequency encoding octaves, frequency_relu only")
    omega0: float = setting(30.0, "SIREN omega0, siren only")
    output_activation: str = setting(SHIP["output_activation"], "output activation", choices=OUTPUT_ACTIVATIONS)
    lr: float | None = setting(None, "Adam learning rate of the dense layers (None: 3e-4 for siren, 2e-3 otherwise)")
    batch: int = setting(SHIP["batch"], "pixels per step")
    levels: str = setting(SHIP["levels"], "multires lookup arrays, RES:CHANNELS,...")
    grid_bits: int = setting(SHIP["grid_bits"], "multires lookup-array storage bits", choices=(8, 16, 32))
    grid_lr: float = setting(1e-2, "multires lookup-array learning rate")
    precision: str = precision_setting()
    finetune_steps: int = finetune_setting()


def recorded(s: Settings) -> dict:
    """The settings metrics.json records: those the architecture uses, lr resolved as fit() does."""
    multires = s.arch == "multires"
    r = dict(image=s.image, size=s.size, steps=s.steps, seed=s.seed, arch=s.arch, width=s.width, depth=s.depth,
             n_freqs=s.n_freqs if s.arch == "frequency_relu" else None, omega0=s.omega0 if s.arch == "siren" else None,
             output_activation=s.output_activation,
             lr=s.lr if s.lr is not None else (3e-4 if s.arch == "siren" else 2e-3), batch=s.batch,
             levels=s.levels if multires else None, grid_bits=s.grid_bits if multires else None,
             grid_lr=s.grid_lr if multires else None, precision=s.precision if s.precision != "f32" else None,
             finetune_steps=s.finetune_steps if s.precision != "f32" else None)
    return {k: v for k, v in r.items() if v is not None}


def preset_settings(preset: str, asset: str | None = None) -> dict:
    """What metrics.json records for ``--preset PRESET`` with no other option: the trainer's
    resolution, kept to the settings the architecture uses (recorded())."""
    return recorded(Settings(**TRAINER.preset_settings(preset, asset)))


# ---------------------------------------------------------------------------------------------
# data

def load_target(image: str = "astronaut", size: int = 256) -> np.ndarray:
    """A ``skimage.data`` photograph as linear RGB float32 ``[size, size, 3]`` (row 0 = top).

    Centre-cropped to a square, decoded to linear light, then area-resampled to ``size`` in
    linear light (averaging is only physically right there).
    """
    try:
        import skimage.data
        import skimage.transform
    except ImportError as e:  # pragma: no cover - depends on the [train] extra
        raise SystemExit("scikit-image is needed for training: pip install 'inshade[train]'") from e
    if image not in IMAGES:
        raise ValueError(f"unknown image {image!r} (choose from {', '.join(IMAGES)})")
    pixels = getattr(skimage.data, image)()
    if pixels.ndim == 2:
        pixels = np.repeat(pixels[..., None], 3, axis=2)
    pixels = pixels[..., :3].astype(np.float64) / 255.0
    h, w = pixels.shape[:2]
    s = min(h, w)
    top, left = (h - s) // 2, (w - s) // 2
    linear = srgb_eotf(pixels[top:top + s, left:left + s])
    if s != size:
        linear = skimage.transform.resize(linear, (size, size), order=1, anti_aliasing=s > size,
                                          mode="edge")
    return np.clip(linear, 0.0, 1.0).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# model

def parse_levels(levels: str) -> list[tuple[int, int]]:
    """``"32:4,64:4,128:2"`` -> ``[(32, 4), (64, 4), (128, 2)]`` (resolution : channels)."""
    out = []
    for part in str(levels).split(","):
        res, _, ch = part.strip().partition(":")
        out.append((int(res), int(ch or 4)))
    if not out or any(r < 2 or not 1 <= c <= 4 for r, c in out):
        raise NeuralImageError(f"bad --levels {levels!r}: RES:CHANNELS,... with RES >= 2, 1 <= CHANNELS <= 4")
    return out


def build(arch: str = Settings.arch, width: int = Settings.width, depth: int = Settings.depth,
          n_freqs: int = 8, omega0: float = 30.0, output_activation: str = "identity",
          levels: str = Settings.levels, grid_bits: int = Settings.grid_bits) -> GraphModule:
    """uv[2] -> rgb[3] network as a bundle graph.

    - ``multires``: one 2D ``lookup_array`` of uv per level (``levels`` = resolution:channels,
      cells initialised uniform in [-0.1, 0.1], exported at ``grid_bits``), all concatenated into
      (dense -> relu) * depth -> dense.

    - ``siren``: (dense -> sin(omega0 x)) * depth -> dense, with SIREN's initialisation.
    - ``frequency_relu``: NeRF frequency encoding (n_freqs, raw input kept) ->
      (dense -> relu) * depth -> dense.
    """
    if arch not in ARCHES:
        raise ValueError(f"unknown arch {arch!r} (choose from {', '.join(ARCHES)})")
    if output_activation not in OUTPUT_ACTIVATIONS:
        raise ValueError(f"unknown output activation {output_activation!r}")
    g = GraphModule([("uv", 2, "uv")])
    src = "uv"
    if arch == "frequency_relu":
        src = g.add("enc", _enc.Frequency(n_freqs, include_input=True), src)
    elif arch == "multires":
        src = []
        for i, (res, ch) in enumerate(parse_levels(levels)):
            cells = (torch.rand(res, res, ch) * 2.0 - 1.0) * 0.1
            src.append(g.add(f"grid{i}", LookupArray([res, res], ch, bits=grid_bits, init=cells), "uv"))
    for i in range(depth):
        src = g.dense(f"l{i}", src, width)
        layer = g.nodes[src].linear
        if arch == "siren":
            fan_in = layer.in_features
            bound = 1.0 / fan_in if i == 0 else math.sqrt(6.0 / fan_in) / omega0
            with torch.no_grad():
                layer.weight.uniform_(-bound, bound)
                layer.bias.uniform_(-1.0 / math.sqrt(fan_in), 1.0 / math.sqrt(fan_in))
            src = g.add(f"a{i}", _act.Sin(omega0), src)
        else:
            src = g.add(f"a{i}", _act.ReLU(), src)
    src = g.dense(f"l{depth}", src, 3)
    if arch == "siren":
        layer = g.nodes[src].linear
        bound = math.sqrt(6.0 / layer.in_features) / omega0
        with torch.no_grad():
            layer.weight.uniform_(-bound, bound)
            layer.bias.fill_(0.5 if output_activation == "identity" else 0.0)
    if output_activation == "sigmoid":
        src = g.add("out_act", _act.Sigmoid(), src)
    g.output("rgb", src, "linear_rgb")
    return g


def predict(model: torch.nn.Module, width: int, height: int, chunk: int = 65536) -> np.ndarray:
    """Linear RGB ``[H, W, 3]`` float32 at the pixel centres (image orientation), evaluated on the
    model's device and returned on the CPU."""
    device = next(model.parameters()).device
    uv = torch.from_numpy(pixel_uvs(width, height).reshape(-1, 2)).to(device)
    with torch.no_grad():
        out = torch.cat([model(uv[i:i + chunk]) for i in range(0, uv.shape[0], chunk)], 0)
    return out.reshape(height, width, -1).cpu().numpy().astype(np.float32)


def metrics_of(prediction: np.ndarray, target: np.ndarray) -> dict:
    """Quality of a linear prediction against the linear target (clipped to [0, 1] as shown)."""
    shown = np.clip(prediction, 0.0, 1.0)
    return {
        "psnr_linear": round(psnr(shown, target), 4),
        "psnr_srgb": round(psnr(srgb_oetf(shown), srgb_oetf(target)), 4),
        "mse_linear": mse(shown, target),
    }


# ---------------------------------------------------------------------------------------------
# training

def fit(model: GraphModule, target: np.ndarray, *, steps: int, seed: int = 0, lr: float | None = None,
        batch: int = 16384, arch: str = "frequency_relu", progress: bool | None = None,
        grid_lr: float = Settings.grid_lr) -> dict:
    """Adam on random pixel batches (full image when ``batch`` >= pixels), cosine-decayed lr;
    lookup-array cells (multires) at ``grid_lr``, Adam eps 1e-15 as Instant NGP.
    Runs on the model's device; batch indices are drawn on a CPU generator and then moved, so a
    seed draws the same batches on every device. Deterministic for a given seed on a given torch
    build and device. Returns timing and the loss curve."""
    h, w = target.shape[:2]
    device = next(model.parameters()).device
    uv = torch.from_numpy(pixel_uvs(w, h).reshape(-1, 2)).to(device)
    rgb = torch.from_numpy(target.reshape(-1, 3)).to(device)
    n = uv.shape[0]
    lr = lr if lr is not None else (3e-4 if arch == "siren" else 2e-3)
    from inshade.models.fit_loop import adam, cosine, fit as fit_steps

    cells = [p for name, p in model.named_parameters() if name.endswith(".cells")]
    if cells:
        rest = [p for name, p in model.named_parameters() if not name.endswith(".cells")]
        opt = adam([{"params": cells, "lr": grid_lr}, {"params": rest, "lr": lr}], eps=1e-15)
    else:
        opt = adam(model.parameters(), lr=lr)
    gen = torch.Generator().manual_seed(seed)
    losses = []
    start = time.perf_counter()

    def step_loss(step):
        if batch >= n:
            xb, yb = uv, rgb
        else:
            idx = torch.randint(0, n, (batch,), generator=gen).to(device)
            xb, yb = uv[idx], rgb[idx]
        return torch.mean((model(xb) - yb) ** 2)

    def after(step, loss, bar):
        if step % 50 == 0 or step == steps - 1:
            value = float(loss.detach())
            losses.append((step, value))
            bar.set_postfix(psnr=f"{psnr_from_mse(max(value, 1e-12)):.2f}")

    fit_steps(opt, step_loss, steps, lr_factor=cosine(steps), after_step=after, desc="neural_image", progress=progress)
    return {"seconds": time.perf_counter() - start, "losses": losses, "lr": lr}


def finetune(model: GraphModule, target: np.ndarray, s: Settings, log: dict) -> float:
    """The quantization-aware fine-tune (precision below f32): ``finetune_steps`` more steps at a tenth of
    the rates with the dense weights seen at ``precision`` (models/quantize_aware.py). Returns the linear
    PSNR the quantized network had before it, for the record."""
    from inshade.models.quantize_aware import quantizer_in_loop

    with quantizer_in_loop(model, s.precision):
        before = metrics_of(predict(model, s.size, s.size), target)["psnr_linear"]
        fit(model, target, steps=s.finetune_steps, seed=s.seed + 1, lr=log["lr"] / 10, batch=s.batch, arch=s.arch,
            grid_lr=s.grid_lr / 10)
    return before


def train(run: Run) -> int:
    """Trains on the run's device and writes the bundle (+ preview.png, reference.png) into the run's
    folder. Metrics and the preview come from the *exported* bundle (lookup arrays quantised to
    ``grid_bits``), i.e. what the shader draws."""
    s, device = run.settings, run.device
    torch.manual_seed(s.seed)
    target = load_target(s.image, s.size)
    multires = s.arch == "multires"
    # initialised on the CPU generator, then moved: the same start on every device
    model = build(s.arch, s.width, s.depth, s.n_freqs, s.omega0, s.output_activation, s.levels,
                  s.grid_bits).to(device)
    start_metrics = metrics_of(predict(model, s.size, s.size), target)
    log = fit(model, target, steps=s.steps, seed=s.seed, lr=s.lr, batch=s.batch, arch=s.arch, grid_lr=s.grid_lr)
    float_metrics = metrics_of(predict(model, s.size, s.size), target)
    before = finetune(model, target, s, log) if s.precision != "f32" else None
    provenance = {
        "command": run.command,
        "preset": run.preset,
        "preset_note": SHIP_NOTE if run.preset == "ship" else None,
        "image": f"skimage.data.{s.image}",
        "image_preprocessing": f"centre square crop, sRGB EOTF to linear, resized to {s.size}x{s.size}",
        "uv_convention": "uv (0,0) = bottom-left of the picture, (1,1) = top-right; pixel centres",
        "steps": s.steps, "seed": s.seed, "arch": s.arch, "width": s.width, "depth": s.depth,
        "n_freqs": s.n_freqs if s.arch == "frequency_relu" else None,
        "omega0": s.omega0 if s.arch == "siren" else None,
        "levels": s.levels if multires else None,
        "grid_bits": s.grid_bits if multires else None,
        "grid_lr": s.grid_lr if multires else None,
        "output_activation": s.output_activation, "lr": log["lr"], "batch": s.batch,
        "optimizer": "adam, cosine decay to 5%" + (", eps 1e-15" if multires else ""),
        "loss": "mse, linear rgb",
        "device": str(device),
        "torch": torch.__version__,
        **recorded_at(),
    }
    provenance = {k: v for k, v in provenance.items() if v is not None}
    render = {"program": RENDER_PROGRAM, "width": s.size, "height": s.size, "input": "uv", "output": "rgb"}
    bundle = model.export("neural_image", "neural_image", provenance=provenance, render=render)
    if s.precision != "f32":   # the values the fine-tune saw
        bundle = quantized(bundle, s.precision)
    # What the shader draws: the exported (quantised) bundle, read back through torch.
    shipped = GraphModule.from_bundle(bundle).eval()
    prediction = predict(shipped, s.size, s.size)
    metrics = metrics_of(prediction, target)
    metrics.update({
        "psnr_linear_step0": start_metrics["psnr_linear"],
        "psnr_srgb_step0": start_metrics["psnr_srgb"],
        "psnr_linear_float": float_metrics["psnr_linear"],
        "psnr_srgb_float": float_metrics["psnr_srgb"],
        **({"psnr_linear_quantized_without_finetune": before} if before is not None else {}),
        "params": int(sum(p.numel() for p in model.parameters())),
        "weight_bytes": int(sum(np.asarray(t).nbytes for t in bundle.tensors.values())),
        "train_seconds": round(log["seconds"], 2),
        "train_threads": torch.get_num_threads(),
        "device": str(device),
    })
    bundle.meta["metrics"] = metrics
    bundle.save(run.out)
    # metrics.json as run.write_metrics writes it, with the settings the architecture uses
    atomic_write(run.out / "metrics.json",
                 json.dumps({**run.record(), "settings": recorded(s), **metrics}, indent=1) + "\n")
    from inshade.scene.image_io import write_png

    write_png(run.out / "preview.png", prediction)
    write_png(run.out / "reference.png", target)
    print(f"wrote {bundle.path}: PSNR {metrics['psnr_linear']:.2f} dB linear, {metrics['psnr_srgb']:.2f} dB sRGB "
          f"({metrics['params']} params, {metrics['weight_bytes']} weight bytes, {metrics['train_seconds']:.1f} s)")
    return 0


# ---------------------------------------------------------------------------------------------
# command line

def check(s: Settings) -> None:
    if s.steps < 0 or s.size < 1:
        raise NeuralImageError("--steps must be >= 0 and --size >= 1")
    if s.arch == "multires":
        parse_levels(s.levels)


TRAINER = Trainer(ASSET, __doc__, Settings, PRESETS, train, folder=lambda s: f"neural_image_{s.image}",
                  folder_hint="neural_image_<image>",
                  default_preset="ship", ship_assets={ASSET: {}}, check=check, errors=(NeuralImageError,))
add_arguments, main = TRAINER.add_arguments, TRAINER.main
