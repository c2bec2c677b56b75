"""A few Adam steps of mean-squared regression on the CPU: what a "the component learns" test runs
before it checks that the loss fell."""
from __future__ import annotations


def fit_losses(module, x, target, steps: int, lr: float) -> list[float]:
    """Trains ``module`` on ``(x, target)`` for ``steps`` Adam steps; the loss before each step."""
    import torch

    opt = torch.optim.Adam(module.parameters(), lr=lr)
    losses = []
    for _ in range(steps):
        opt.zero_grad()
        loss = (module(x) - target).square().mean()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    return losses
