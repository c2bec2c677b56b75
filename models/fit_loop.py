"""The fit loop every trainer runs: the optimiser it builds (``adam``), the learning-rate schedule
(``cosine``: a factor of each group's starting rate per step), and ``fit``, the steps themselves:

    opt = adam(model.parameters(), lr=1e-3)
    fit(opt, lambda step: loss_of(model, draw(step)), steps, lr_factor=cosine(steps), desc="my fit")

Each step clears the gradients, backpropagates what the loss function returns and steps the
optimiser; the schedule then sets every group's rate for the next step, as torch's ``LambdaLR``
does (so a run's numbers match one stepped by that scheduler). Resuming is ``start``: the steps
already done (their optimiser state restored by the caller), so the schedule and the progress bar
go on where they stopped. ``checkpoint`` saves every ``checkpoint_every`` steps. ``seed``: the loop
runs on torch's global generator seeded so, restored afterwards.

``lbfgs`` is the full-batch quasi-Newton alternative (closure form), for least-squares finishes.
Nothing here draws random numbers; the loss function owns its batches and their generators.
"""
from __future__ import annotations

import contextlib
import math
from collections.abc import Callable

import torch


def adam(params, **options) -> torch.optim.Adam:
    """torch's Adam on ``params`` (tensors or param-group dicts) with ``options`` (lr, betas, eps, ...)."""
    return torch.optim.Adam(params, **options)


def cosine(steps: int, floor: float = 0.05) -> Callable[[int], float]:
    """The factor of a half-cosine decay from 1 to ``floor`` over ``steps`` (held at ``floor`` after)."""
    return lambda step: floor + (1 - floor) * 0.5 * (1 + math.cos(math.pi * min(step / max(steps, 1), 1.0)))


def learning_rates(opt: torch.optim.Optimizer) -> list[float]:
    """Each param group's learning rate now: the base a schedule's factors multiply."""
    return [g["lr"] for g in opt.param_groups]


def seeded(seed: int | None):
    """Run on torch's global generator seeded with ``seed`` (None: as it is), restored afterwards."""
    if seed is None:
        return contextlib.nullcontext()
    stack = contextlib.ExitStack()
    stack.enter_context(torch.random.fork_rng(devices=[]))
    torch.manual_seed(seed)
    return stack


def fit(opt: torch.optim.Optimizer, loss_fn: Callable, steps: int, *, start: int = 0, stop: int | None = None,
        lr_factor: Callable[[int], float] | None = None, base_lrs: list[float] | None = None,
        before_step: Callable[[], None] | None = None, after_step: Callable | None = None,
        checkpoint: Callable[[int], None] | None = None, checkpoint_every: int | None = None,
        checkpoint_last: bool = True, seed: int | None = None, desc: str = "", progress: bool | None = None) -> int:
    """Run steps ``start`` .. ``stop`` (default ``steps``) of ``steps``; returns the optimiser steps done.

    ``loss_fn(step)`` returns the loss to minimise, or a tuple whose first item it is (the rest is the
    caller's: terms to log), or None to skip the step (a degenerate batch: no update, the schedule
    waits). ``lr_factor(n)``: each group's rate is its ``base_lrs`` (default: the rates the optimiser
    holds now) times the factor at n optimiser steps done; None leaves the rates alone (a schedule
    of the caller's, such as one reacting to evaluations). ``before_step()`` runs between the
    backward pass and the update (gradient clipping); ``after_step(step, returned, bar)`` after it
    (projections, history, the bar's postfix). ``checkpoint(done)`` runs every ``checkpoint_every``
    steps before the last, and after the last one when ``checkpoint_last``.
    """
    from inshade.progress import progress as progress_bar

    stop = steps if stop is None else stop
    base = list(base_lrs) if base_lrs is not None else learning_rates(opt)
    done = start

    def schedule():
        if lr_factor is not None:
            factor = lr_factor(done)
            for g, lr0 in zip(opt.param_groups, base):
                g["lr"] = lr0 * factor

    with seeded(seed):
        schedule()
        bar = progress_bar(range(start, stop), desc=desc, enabled=progress, initial=start, total=steps)
        for step in bar:
            returned = loss_fn(step)
            if returned is None:
                continue
            loss = returned[0] if isinstance(returned, tuple) else returned
            opt.zero_grad(set_to_none=True)
            loss.backward()
            if before_step is not None:
                before_step()
            opt.step()
            done += 1
            schedule()
            if after_step is not None:
                after_step(step, returned, bar)
            last = step + 1 == stop
            if checkpoint is not None and checkpoint_every and (
                    last and checkpoint_last or not last and (step + 1) % checkpoint_every == 0):
                checkpoint(step + 1)
    return done


def history_rows(records: list[dict], key: str, digits: int) -> list[dict]:
    """A fit's evaluation records as its metrics keep them: the step, ``key`` rounded to ``digits``
    and the seconds so far."""
    return [{"step": r["step"], key: round(r[key], digits), "seconds": round(r["seconds"], 2)} for r in records]


def lbfgs(params, loss_fn: Callable[[], torch.Tensor], evaluations: int, *,
          on_evaluation: Callable[[int, torch.Tensor], None] | None = None, **options) -> int:
    """Full-batch L-BFGS on ``params`` for at most ``evaluations`` loss/gradient evaluations of
    ``loss_fn()`` (``options``: torch's LBFGS options besides the evaluation limits);
    ``on_evaluation(count, loss)`` after each. Returns the evaluations made."""
    opt = torch.optim.LBFGS(params, max_iter=evaluations, max_eval=evaluations, **options)
    count = 0

    def closure():
        nonlocal count
        opt.zero_grad(set_to_none=True)
        loss = loss_fn()
        loss.backward()
        count += 1
        if on_evaluation is not None:
            on_evaluation(count, loss)
        return loss

    if evaluations > 0:
        opt.step(closure)
    return count
