"""Training of the learnt-transfer network (techniques/prt/transfer_model.py) on ground-truth transfer
data (techniques/prt/transfer.py ``build_dataset``), and its held-out evaluation.

Output range: with the tanh output the targets are divided by TANH_SCALE = 1.25, so the largest
transfer value that exists (the unoccluded band-1 lobe along n, 2pi/3 * sqrt(3/4pi) ~ 1.023;
every |T_k| is at most that) maps to 0.82, where tanh still has slope 0.33. The scale is fixed,
not fitted to the data, so bundles of different scenes read alike.

Held-out metrics (on points never trained on): transfer L1 (mean over the 16 lanes), transfer
PSNR (peak 1), and diffuse PSNR: the radiance a white Lambertian surface shows under the noon sky,
sum_k T_k L_k / pi per RGB channel (peak 1, what the PRT pass displays at albedo 1 and exposure 1).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import torch

from inshade.metrics import psnr_from_mse

from inshade.models.checkpoint import read_checkpoint, write_checkpoint
from inshade.models.fit_loop import adam, cosine, fit
from inshade.techniques.prt.transfer_model import TransferFrame, transfer_graph

TANH_SCALE = 1.25
EVAL_SKY = "noon"
# Defaults chosen on trained/sdf_creature (k=64, 40000 x 128-ray samples, held-out diffuse PSNR
# against 1024-ray references, one thread on the shared 2-core machine): more, smaller steps win
# per second: batch 4096 x 4000 steps lr 5e-3: 45.6 dB / 247 s; 1024 x 8000, 5e-3: 47.8 dB / 218 s;
# 1024 x 8000, 1e-2: 48.7 dB / 230 s; 512 x 16000, 5e-3: 49.1 dB / 270 s; 512 x 16000, 1e-2:
# 49.4 dB / 206 s (8 position octaves instead of 6: 48.9 dB). The estimator's own noise at 128
# rays is ~46 dB diffuse per sample; the network averages it out over neighbouring samples.
DEFAULTS = dict(width=64, layers=4, points=40000, dirs=128, steps=16000, batch=512, lr=1e-2,
                pos_freqs=6, normal_freqs=4, output="tanh", holdout=0.05, seed=0, threads=1)


def _psnr(err_sq_mean: float, peak: float = 1.0) -> float:
    return 99.0 if err_sq_mean <= 1e-10 * peak * peak else psnr_from_mse(err_sq_mean, peak)


def diffuse_radiance(transfer: torch.Tensor, sky: str = EVAL_SKY) -> torch.Tensor:
    """sum_k T_k L_k / pi [N, 3]: a white Lambertian surface's radiance under procedural ``sky``."""
    from inshade.codegen.sdf import environment_sh

    coeffs = torch.from_numpy(environment_sh(sky, 0.0, int(round(math.sqrt(transfer.shape[1])))))
    return (transfer.double() @ coeffs.double()) * (1.0 / math.pi)


def transfer_metrics(pred: torch.Tensor, target: torch.Tensor, sky: str = EVAL_SKY) -> dict:
    """L1 / PSNR of transfer vectors and PSNR of the diffuse shading they give under ``sky``."""
    pred, target = pred.double(), target.double()
    diff = diffuse_radiance(pred, sky) - diffuse_radiance(target, sky)
    return {"l1": float((pred - target).abs().mean()),
            "psnr": _psnr(float(((pred - target) ** 2).mean())),
            "diffuse_psnr": _psnr(float((diff ** 2).mean())),
            "diffuse_mae": float(diff.abs().mean())}


def split(n: int, holdout: float, seed: int):
    """(train, held-out) index tensors: a seeded permutation, the last ``holdout`` fraction held out."""
    perm = torch.randperm(n, generator=torch.Generator().manual_seed(int(seed) + 7919))
    k = min(n - 1, max(1, int(round(n * holdout))))
    return perm[: n - k], perm[n - k:]


def training_config(width, layers, pos_freqs, normal_freqs, output, steps, batch, lr, seed,
                    drop_enclosed=False) -> dict:
    """The settings a checkpoint is keyed and checked by."""
    config = {"width": width, "layers": layers, "pos_freqs": pos_freqs, "normal_freqs": normal_freqs,
              "output": output, "steps": steps, "batch": batch, "lr": lr, "seed": seed}
    if drop_enclosed:
        config["drop_enclosed"] = True
    return config


def _save_checkpoint(path: Path, net, opt, step: int, config: dict) -> None:
    tensors = {f"net.{k}": v for k, v in net.state_dict().items()}
    for i, p in enumerate(opt.param_groups[0]["params"]):
        st = opt.state.get(p, {})
        for name in ("exp_avg", "exp_avg_sq"):
            if name in st:
                tensors[f"adam.{i}.{name}"] = st[name]
        if "step" in st:
            tensors[f"adam.{i}.step"] = torch.as_tensor(st["step"], dtype=torch.float32).reshape(1)
    write_checkpoint(path, "transfer", tensors, config, step=step)


def _load_checkpoint(path: Path, net, opt, config: dict) -> int:
    """Restores net + Adam state; returns the steps done. ValueError if the file is not a
    checkpoint of this configuration (resuming another run's weights would be silent garbage)."""
    tensors, header = read_checkpoint(path, "transfer", config, "use another --checkpoint or delete it")
    net.load_state_dict({k[4:]: v for k, v in tensors.items() if k.startswith("net.")})
    for i, p in enumerate(opt.param_groups[0]["params"]):
        if f"adam.{i}.exp_avg" in tensors:   # moments beside their parameter (any device); step stays on the CPU
            opt.state[p] = {"step": tensors[f"adam.{i}.step"].reshape(()).clone(),
                            "exp_avg": tensors[f"adam.{i}.exp_avg"].to(p.device, copy=True),
                            "exp_avg_sq": tensors[f"adam.{i}.exp_avg_sq"].to(p.device, copy=True)}
    return int(header["step"])


def _check_dataset(dataset) -> None:
    if not isinstance(dataset, dict):
        raise ValueError(f"dataset: expected the dict of models.transfer.build_dataset, got {type(dataset).__name__}")
    for k, width in (("position", 3), ("normal", 3), ("transfer", None)):
        t = dataset.get(k)
        if not isinstance(t, torch.Tensor) or t.ndim != 2 or (width and t.shape[1] != width):
            raise ValueError(f"dataset: {k}: expected a [N, {width or 'K'}] tensor")
        if not torch.isfinite(t).all():
            raise ValueError(f"dataset: {k}: contains NaN/inf")
    n = dataset["position"].shape[0]
    if dataset["normal"].shape[0] != n or dataset["transfer"].shape[0] != n or n < 2:
        raise ValueError("dataset: position/normal/transfer must have the same N >= 2 rows")
    if "center" not in dataset or "radius" not in dataset:
        raise ValueError("dataset: center/radius: missing (the bound the positions are normalised by)")


def _without_enclosed(dataset: dict) -> dict:
    """Drop samples whose every visibility ray is blocked (band-0 transfer exactly 0): surfaces
    enclosed inside the geometry, e.g. the internal shells an MLP SDF grows. No camera outside
    can see them, and near a visible crease they teach the network a false black."""
    out = dict(dataset)
    for prefix in ("", "heldout_"):
        if prefix + "transfer" not in dataset:
            continue
        keep = dataset[prefix + "transfer"][:, 0] > 0
        for k in ("position", "normal", "transfer"):
            out[prefix + k] = dataset[prefix + k][keep]
    return out


def _finetune(net, precision: str, steps: int, lr: float, step_loss, heldout, progress) -> tuple[dict, dict]:
    """The quantization-aware fine-tune (models/quantize_aware.py): the held-out metrics of the network
    seen at ``precision`` before and after ``steps`` more steps at ``lr``."""
    from inshade.models.quantize_aware import quantizer_in_loop

    with quantizer_in_loop(net, precision):
        before = heldout()
        fit(adam(net.parameters(), lr=lr), step_loss, steps, lr_factor=cosine(steps),
            desc=f"quantization-aware fine-tune ({precision})", progress=progress)
        return before, heldout()


def train_transfer(dataset: dict, width: int = 64, layers: int = 4, steps: int = DEFAULTS["steps"],
                   batch: int = DEFAULTS["batch"], lr: float = DEFAULTS["lr"], seed: int = 0,
                   checkpoint=None, progress: bool | None = True, pos_freqs: int = DEFAULTS["pos_freqs"],
                   normal_freqs: int = DEFAULTS["normal_freqs"], output: str = DEFAULTS["output"],
                   holdout: float = DEFAULTS["holdout"], checkpoint_every: int | None = None,
                   until: int | None = None, drop_enclosed: bool = False, device="cpu", precision: str = "f32",
                   finetune_steps: int = 0):
    """Fits ``transfer_graph`` to a dataset (techniques/prt/transfer.py ``build_dataset``).

    L1 loss on transfer / scale, Adam at ``lr`` with a cosine decay to 5%, ``batch`` random
    training points a step (drawn from a generator seeded by (seed, step), so a resumed run
    draws the same batches as an uninterrupted one). ``checkpoint``: a safetensors path, written
    every ``checkpoint_every`` steps (default steps/10) and at the end; if it exists the run
    resumes from it. Held out: the dataset's ``heldout_*`` samples when it has them (build_dataset
    casts them with many rays), else a seeded ``holdout`` fraction of its points. ``until``: stop once that many steps are done (a time-boxed run; call again
    with the same checkpoint to go on). Returns (GraphModule, TransferFrame, metrics) with held-out metrics
    (``heldout_*``, see ``transfer_metrics``) before and after training.

    ``device`` (a torch.device or its name): where the network, the data and the steps live. The
    initial weights and the batch indices are drawn on CPU generators and moved, so a seed starts
    and samples alike on every device; metrics are computed on the CPU and the returned network
    is on the CPU.

    ``precision`` f16 / i8: once the fit is done, ``finetune_steps`` more at a tenth of the rate with the
    dense weights seen at that precision (models/quantize_aware.py); the held-out metrics before it are
    kept as ``heldout_*_quantized_without_finetune``.
    """
    device = torch.device(device)
    _check_dataset(dataset)
    degree = int(round(math.sqrt(dataset["transfer"].shape[1])))
    scale = TANH_SCALE if output == "tanh" else 1.0
    frame = TransferFrame(tuple(float(c) for c in dataset["center"]), float(dataset["radius"]), scale, degree)
    config = training_config(width, layers, pos_freqs, normal_freqs, output, steps, batch, lr, seed, drop_enclosed)
    if drop_enclosed:
        dataset = _without_enclosed(dataset)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        net = transfer_graph(width, layers, pos_freqs, normal_freqs, degree, output)
    net.to(device)
    x = torch.cat([frame.normalise(dataset["position"]), dataset["normal"].float()], -1)
    y = dataset["transfer"].float() * (1.0 / scale)
    if "heldout_transfer" in dataset:      # separate samples with a many-ray reference
        x_tr, y_tr = x, y
        x_ho = torch.cat([frame.normalise(dataset["heldout_position"]), dataset["heldout_normal"].float()], -1)
        t_ho = dataset["heldout_transfer"].float()
    else:
        tr, ho = split(x.shape[0], holdout, seed)
        x_tr, y_tr, x_ho = x[tr], y[tr], x[ho]
        t_ho = dataset["transfer"][ho].float()
    x_tr, y_tr, x_ho = x_tr.to(device), y_tr.to(device), x_ho.to(device)

    def heldout():
        with torch.no_grad():
            return transfer_metrics((net(x_ho) * scale).cpu(), t_ho)

    opt = adam(net.parameters(), lr=lr)
    start_step = 0
    ckpt = Path(checkpoint) if checkpoint is not None else None
    before = heldout()
    if ckpt is not None and ckpt.is_file():
        start_step = _load_checkpoint(ckpt, net, opt, config)
    stop = steps if until is None else max(start_step, min(int(until), steps))
    start = time.perf_counter()
    interval = {"acc": 0.0, "count": 0, "train_l1": float("nan")}
    n_tr = x_tr.shape[0]

    def step_loss(step):
        gen = torch.Generator().manual_seed(int(seed) * 1_000_003 + step)
        idx = torch.randint(0, n_tr, (min(batch, n_tr),), generator=gen).to(device)
        return (net(x_tr[idx]) - y_tr[idx]).abs().mean()

    def after(step, loss, bar):
        interval["acc"], interval["count"] = interval["acc"] + float(loss.detach()), interval["count"] + 1
        if (step + 1) % 100 == 0 or step + 1 == stop:
            interval["train_l1"] = interval["acc"] / interval["count"] * scale
            bar.set_postfix(l1=f"{interval['train_l1']:.4f}")
            interval["acc"], interval["count"] = 0.0, 0

    save = None if ckpt is None else (lambda done: _save_checkpoint(ckpt, net, opt, done, config))
    fit(opt, step_loss, steps, start=start_step, stop=stop, lr_factor=cosine(steps), base_lrs=[lr], after_step=after,
        checkpoint=save, checkpoint_every=checkpoint_every or max(1, steps // 10), desc=f"transfer k={width}",
        progress=progress)
    seconds = time.perf_counter() - start
    train_l1 = interval["train_l1"]
    tuned = precision != "f32" and stop == steps   # the fine-tune follows a finished fit
    quantized_before, after = (_finetune(net, precision, finetune_steps, lr / 10, lambda k: step_loss(steps + k),
                                         heldout, progress) if tuned else (None, heldout()))
    metrics = {f"heldout_{k}": round(v, 6) for k, v in after.items()}
    metrics.update({f"heldout_{k}_step0": round(v, 6) for k, v in before.items()})
    if tuned:
        metrics.update({f"heldout_{k}_quantized_without_finetune": round(v, 6) for k, v in quantized_before.items()},
                       finetune_steps=finetune_steps)
    metrics.update({"train_l1": round(train_l1, 6) if math.isfinite(train_l1) else None,
                    "train_seconds": round(seconds, 2), "steps": stop, "resumed_from": start_step,
                    "params": int(sum(p.numel() for p in net.parameters())),
                    "n_train": int(n_tr), "n_heldout": int(x_ho.shape[0]), "eval_sky": EVAL_SKY,
                    "device": str(device)})
    net.cpu().eval()
    return net, frame, {k: v for k, v in metrics.items() if v is not None}
