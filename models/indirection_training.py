"""Training Differentiable Indirection cascades (Datta et al. 2023): the stability tools (primary
gradient clipping, the soft-monotonicity regulariser), the schedules and losses, `train_cascade` and
`finish_lbfgs`. `models/indirection.py` builds the cascades, samples the data and re-exports these names.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Iterable

import numpy as np
import torch

from inshade import metrics
from inshade.components.lookup_array.torch_twin import LookupArray

from . import fit_loop
from .graph import GraphModule

# ---------------------------------------------------------------------------------------------
# stability tools (notes §4)

def lookup_nodes(g: GraphModule) -> list[str]:
    return [k for k, c in g.nodes.items() if isinstance(c, LookupArray)]


def primary_nodes(g: GraphModule) -> list[str]:
    """Lookup arrays whose output is (part of) another lookup array's coordinate."""
    luts = set(lookup_nodes(g))
    fed = {s for k in luts for s in g.wiring[k]}
    return [k for k in g.nodes if k in luts and k in fed]


def cell_diagonal(array: LookupArray) -> float:
    """Length of one cell's diagonal in coordinate space, sqrt(sum_k 1/(N_k - 1)^2)."""
    return math.sqrt(sum(1.0 / (n - 1) ** 2 for n in array.resolution if n > 1))


def auto_clip_bound(array: LookupArray, lr: float) -> float:
    """The paper's bound (§4.3): a plain gradient step lr * g should move a cell by at most half a
    cell diagonal, so |g| <= diag / (2 lr); for 1D that is (N lr)^-1 / 2 as in the paper (up to
    N vs N - 1, our corner-aligned spacing)."""
    return cell_diagonal(array) / (2.0 * lr)


def _clip_cells(array: LookupArray, bound: float):
    """Per cell: scale each cell's gradient vector (its channels) to L2 norm <= bound."""
    g = array.cells.grad
    if g is not None:
        norms = g.norm(dim=-1, keepdim=True)
        g.mul_((bound / norms.clamp_min(1e-30)).clamp(max=1.0))


def _clip_global(array: LookupArray, bound: float):
    """The whole array's gradient to L2 norm <= bound (torch's clip_grad_norm_)."""
    torch.nn.utils.clip_grad_norm_([array.cells], bound)


CLIPPERS: dict[str, Callable[[LookupArray, float], None]] = {"cell": _clip_cells, "global": _clip_global}


def clip_primary_gradients(g: GraphModule, bound: float | str, lr: float, mode: str = "cell",
                           primaries: list[str] | None = None):
    """Clip the primary arrays' gradients in place (`bound` a number or "auto")."""
    for name in primaries if primaries is not None else primary_nodes(g):
        arr = g.nodes[name]
        CLIPPERS[mode](arr, auto_clip_bound(arr, lr) if bound == "auto" else float(bound))


def monotonicity_penalty(array: LookupArray, kappa: float = 1.0, eps: float | None = None,
                         eps_scale: float = 0.5, axes: list[int] | None = None,
                         central: bool = False) -> torch.Tensor:
    """Soft-monotonicity regulariser (paper supp. §2, notes §4.5):

        R = (κ / N) Σ_c Σ_i ReLU(ε_c + F(c)[i] - sg(F(c)[i + 1]))

    over every cell i and channel c, the difference taken along the axis that channel ramps
    along (`axes[c]`, default c % d as in the (u, v, u, v) ramp), N the number of cells, sg a
    stop-gradient copy padded with its border value (so the last cell compares with itself,
    giving ReLU(ε) = 0). ε ≤ 0 tolerates small decreases: by default ε_c = -eps_scale / (N_a - 1),
    half the identity ramp's step. It is zero on any non-decreasing table and positive where a
    channel falls by more than |ε| between neighbours (a fold). `central=True` adds the mirrored
    term ReLU(ε + sg(F(c)[i - 1]) - F(c)[i]), so both cells of a fold are pushed apart."""
    t = array.table()
    res, d = array.resolution, len(array.resolution)
    axes = axes if axes is not None else [c % d for c in range(array.channels)]
    total = t.new_zeros(())
    for c, k in enumerate(axes):
        n = res[k]
        if n < 2:
            continue
        dim = d - 1 - k  # cells are stored [N_{d-1}, ..., N_0, C]
        e = eps if eps is not None else -eps_scale / (n - 1)
        tc = t[..., c]
        sg = tc.detach()
        # indices on the table's device (index_select refuses a CPU index for a CUDA table)
        nxt = sg.index_select(dim, torch.arange(1, n + 1, device=sg.device).clamp(max=n - 1))
        total = total + torch.relu(e + tc - nxt).sum()
        if central:
            prv = sg.index_select(dim, torch.arange(-1, n - 1, device=sg.device).clamp(min=0))
            total = total + torch.relu(e + prv - tc).sum()
    return kappa * total / float(np.prod(res))


# ---------------------------------------------------------------------------------------------
# training

# A schedule: (opt, steps, patience) -> (the fit loop's per-step lr factor or None, what each evaluation's
# mean training loss is handed to).
def _cosine(opt, steps, patience):
    """Cosine decay from lr to 5% of it over `steps` (stepped every iteration)."""
    return fit_loop.cosine(steps), (lambda loss: None)


def _plateau(opt, steps, patience):
    """The authors' choice: ReduceLROnPlateau (halve after `patience` evals without a 1e-3
    relative improvement of the interval's mean training loss; floor at 1% of lr)."""
    floor = [g["lr"] * 1e-2 for g in opt.param_groups]
    s = torch.optim.lr_scheduler.ReduceLROnPlateau(opt, factor=0.5, patience=patience, threshold=1e-3,
                                                   min_lr=floor)
    return None, (lambda loss: s.step(loss))


def _constant_lr(opt, steps, patience):
    return None, (lambda loss: None)


SCHEDULES = {"cosine": _cosine, "plateau": _plateau, "constant": _constant_lr}
# Training losses: the paper's MAE, or the squared error that PSNR measures.
LOSSES = {"l1": lambda d: torch.mean(torch.abs(d)), "mse": lambda d: torch.mean(d * d)}


def psnr(pred: torch.Tensor, target: torch.Tensor, peak: float = 1.0) -> float:
    """`inshade.metrics.psnr` (float64 difference, torch mean) of two tensors."""
    return metrics.psnr(pred, target, peak)


@dataclass
class History:
    """One record per evaluation: step (steps done), loss (mean training loss since the last
    record; the first record, at step 0, has the eval set's), psnr (on the eval set, else
    on the last batch), lr, seconds."""

    records: list[dict] = field(default_factory=list)

    def column(self, key):
        return [r[key] for r in self.records]

    @property
    def loss(self):
        return self.column("loss")

    @property
    def psnr(self):
        return self.column("psnr")

    @property
    def final(self) -> dict:
        return self.records[-1]


def train_cascade(cascade: GraphModule, sampler: Iterable, steps: int, *, lr: float = 1e-3,
                  schedule: str = "cosine", seed: int = 0, eval_set=None, eval_every: int | None = None,
                  clip_primary: float | str | None = None, clip_mode: str = "cell",
                  bounds: dict[str, tuple[float, float]] | None = None,
                  monotonicity: float = 0.0, monotonicity_args: dict | None = None,
                  primaries: list[str] | None = None, peak: float = 1.0, loss: str = "l1",
                  finish: tuple[int, Iterable, str] | None = None,
                  objective: Callable[[GraphModule, object], torch.Tensor] | None = None,
                  metric: Callable[[GraphModule], tuple[float, float]] | None = None,
                  progress: bool | None = None, desc: str = "cascade") -> History:
    """Fit `cascade` (any GraphModule of lookup arrays) to `sampler`'s (x, target) batches.

    Loss: `LOSSES[loss]` of cascade(x) - target (default L1, the paper's MAE) + `monotonicity` (κ) times
    `monotonicity_penalty` of each primary array. Adam at `lr` (paper: 1e-3) with
    `SCHEDULES[schedule]`: "cosine" (default; decays to 5% over `steps`, which suits the short
    CPU budgets here), "plateau" (the authors' ReduceLROnPlateau, on the mean training loss at
    each eval) or "constant". `clip_primary` (a bound, or "auto" for the paper's half-cell
    bound) clips the primary arrays' gradients per cell (`clip_mode="cell"`) or as a whole
    ("global") before each step. Primaries default to the lookup arrays that feed another one.
    `bounds` {node: (lo, hi)} keeps those arrays' cells within [lo, hi] after every step (a
    projection: e.g. an 8-bit cascaded array whose range stays near its outputs' range).

    `finish` = (step, sampler, loss): from that step on, batches come from the second sampler and
    the loss is `LOSSES[loss]`, under the same optimiser and schedule (texture compression trains
    the paper's way first, then finishes on texel centres with the squared error PSNR measures).

    For losses that are not a distance to targets (e.g. the GGX balls' display-space error):
    `objective(cascade, batch)` returns the loss of a sampler batch, and `metric(cascade)` the
    (loss, PSNR) each history record holds, in place of `eval_set`.

    Deterministic for a seed: global torch RNG is seeded (and restored afterwards); samplers
    should carry their own seeded generator, as `image_sampler` does. Progress on stderr: a bar
    on a TTY, a line every ~30 s off it (`progress=False`: silent). Evaluates every `eval_every`
    steps (default steps / 20) and at the end; returns the History.
    """
    _check_options(schedule, clip_mode, objective, finish, loss)
    prim = primaries if primaries is not None else primary_nodes(cascade)
    history = History()
    batches = iter(sampler)

    with fit_loop.seeded(seed):
        opt = fit_loop.adam(cascade.parameters(), lr=lr)
        lr_factor, on_eval = SCHEDULES[schedule](opt, steps, 3)
        run = _CascadeRun(cascade, opt, history, batches, LOSSES[loss], finish, objective=objective, primaries=prim,
                          monotonicity=monotonicity, monotonicity_args=monotonicity_args, bounds=bounds,
                          metric=metric, eval_set=eval_set, peak=peak)
        run.first_record(held_out=eval_set is not None or metric is not None)
        clip = None if clip_primary is None else (
            lambda: clip_primary_gradients(cascade, clip_primary, lr, clip_mode, prim))
        fit_loop.fit(opt, run.loss, steps, lr_factor=lr_factor, before_step=clip,
                     after_step=run.after_step(steps, eval_every or max(1, steps // 20), on_eval),
                     desc=desc, progress=progress)
    return history


def _check_options(schedule: str, clip_mode: str, objective, finish, loss: str) -> None:
    """`train_cascade`'s named choices are known ones, and a custom objective has no finish phase."""
    if schedule not in SCHEDULES:
        raise ValueError(f"unknown schedule {schedule!r}; known: {', '.join(SCHEDULES)}")
    if clip_mode not in CLIPPERS:
        raise ValueError(f"unknown clip mode {clip_mode!r}; known: {', '.join(CLIPPERS)}")
    if objective is not None and finish is not None:
        raise ValueError("a custom objective has no finish phase")
    for name in (loss, finish[2] if finish else loss):
        if name not in LOSSES:
            raise ValueError(f"unknown loss {name!r}; known: {', '.join(LOSSES)}")


class _CascadeRun:
    """`train_cascade`'s batches, losses and records: each step's batch and loss (from `finish`'s step
    on, its sampler and loss), the `bounds` projection after each update, and a History record at
    step 0, every `eval_every` steps and at the end (its loss the interval's mean training loss,
    which the schedule sees)."""

    def __init__(self, cascade: GraphModule, opt, history: History, batches, loss_fn, finish, *, objective,
                 primaries: list[str], monotonicity: float, monotonicity_args: dict | None, bounds, metric,
                 eval_set, peak: float):
        self.cascade, self.opt, self.history, self.batches, self.loss_fn = cascade, opt, history, batches, loss_fn
        self.finish, self.objective, self.primaries, self.bounds = finish, objective, primaries, bounds
        self.monotonicity, self.monotonicity_args = monotonicity, monotonicity_args
        self.metric, self.eval_set, self.peak = metric, eval_set, peak
        self.pending, self.acc, self.count, self.start = None, 0.0, 0, time.perf_counter()

    def first_record(self, held_out: bool) -> None:
        """The step-0 record: on the eval set (`held_out`), else on the first batch (step 1's too)."""
        self.start = time.perf_counter()
        self.pending = None if held_out else next(self.batches)
        self._evaluate(0, None, self.pending)

    def loss(self, index: int):
        """(loss plus the primaries' monotonicity penalty, the batch's loss, the batch) of step index + 1."""
        if self.finish is not None and index == self.finish[0]:
            self.batches, self.loss_fn, self.pending = iter(self.finish[1]), LOSSES[self.finish[2]], None
        batch = self.pending if self.pending is not None else next(self.batches)
        self.pending = None
        value = (self.objective(self.cascade, batch) if self.objective is not None
                 else self.loss_fn(self.cascade(batch[0]) - batch[1]))
        total = value
        if self.monotonicity:
            for name in self.primaries:
                total = total + monotonicity_penalty(self.cascade.nodes[name], self.monotonicity,
                                                     **(self.monotonicity_args or {}))
        return total, value, batch

    def after_step(self, steps: int, eval_every: int, on_eval):
        """The fit loop's hook after each update: projection, the interval's loss, the records."""
        def after(index, returned, bar):
            _, value, batch = returned
            step = index + 1
            if self.bounds:
                with torch.no_grad():
                    for name, (lo, hi) in self.bounds.items():
                        self.cascade.nodes[name].cells.clamp_(lo, hi)
            self.acc, self.count = self.acc + float(value.detach()), self.count + 1
            if step % eval_every == 0 or step == steps:
                rec = self._evaluate(step, self.acc / self.count, batch)
                on_eval(rec["loss"])
                bar.set_postfix(loss=f"{rec['loss']:.4f}", psnr=f"{rec['psnr']:.2f}")
                self.acc, self.count = 0.0, 0
        return after

    def _evaluate(self, step: int, interval_loss, last_batch) -> dict:
        """Append one History record and return it: loss and PSNR from `metric`, else on the eval set (or the
        last batch); the loss is `interval_loss` when there is one."""
        with torch.no_grad():
            if self.metric is not None:
                eval_loss, eval_psnr = self.metric(self.cascade)
            else:
                x, y = self.eval_set if self.eval_set is not None else last_batch
                pred = self.cascade(x)
                eval_loss, eval_psnr = float(self.loss_fn(pred - y)), psnr(pred, y, self.peak)
            rec = {"step": step, "loss": eval_loss if interval_loss is None else interval_loss,
                   "psnr": eval_psnr, "lr": self.opt.param_groups[0]["lr"],
                   "seconds": time.perf_counter() - self.start}
        self.history.records.append(rec)
        return rec


def finish_lbfgs(cascade: GraphModule, data, evaluations: int, *, history: History | None = None,
                 history_size: int = 20, peak: float = 1.0, eval_every: int | None = None,
                 first_step: int = 0) -> History:
    """Refine `cascade` by full-batch L-BFGS (strong-Wolfe line search) on the mean squared error
    over `data` = (x, target), for at most `evaluations` loss/gradient evaluations.

    Why: on texel centres the finish is a deterministic least-squares problem (65K residuals,
    ~32K cells at 256^2 / 6x); minibatch Adam spends its steps on gradient noise, while the
    full batch with a quasi-Newton direction and a line search needs no learning rate and gets
    further per second (astronaut 256^2 / 6x, 6000 steps: +0.1 / +0.5 dB over the minibatch Adam
    finish for seeds 0 / 1, in less time). Appends records to `history` (or a new one) every `eval_every` evaluations
    (default evaluations / 10) and at the end, with step = `first_step` + evaluations so far."""
    x, y = data
    history = history if history is not None else History()
    eval_every = eval_every or max(1, evaluations // 10)
    params = [p for p in cascade.parameters() if p.requires_grad]
    start = time.perf_counter()
    offset = history.records[-1]["seconds"] if history.records else 0.0   # continue a train_cascade clock

    def record(count, loss):
        history.records.append({"step": first_step + count, "loss": loss,
                                "psnr": metrics.psnr_from_mse(max(loss, 1e-30), peak),
                                "lr": 1.0, "seconds": offset + time.perf_counter() - start})

    def on_evaluation(count, loss):
        if count % eval_every == 0:
            record(count, float(loss.detach()))

    # tolerances ~0: at ~33 dB the loss changes by < 1e-9 per iteration while still improving
    count = fit_loop.lbfgs(params, lambda: LOSSES["mse"](cascade(x) - y), evaluations, on_evaluation=on_evaluation,
                           lr=1.0, history_size=history_size, tolerance_grad=1e-12, tolerance_change=1e-15,
                           line_search_fn="strong_wolfe")
    if count and history.records and history.records[-1]["step"] == first_step + count:
        history.records.pop()       # the last evaluation was recorded before the final step
    with torch.no_grad():
        record(count, float(LOSSES["mse"](cascade(x) - y)))
    return history
