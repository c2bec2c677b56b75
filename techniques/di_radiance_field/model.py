"""The torch side: the uncompressed-grid graph, the multi-head DI graph (paper Fig. 4c), sizing by
compression ratio and rho (paper supp. Table 6), and training one head against its target grid.

Both graphs take x in [0, 1]^3 (the field's box, a world position) and output the same lanes:
colour (12: coefficient-major degree-1 SH logits, field.py) then density (1: sigma / SIGMA_SCALE, unit
scale like the logits; the march multiplies by the bundle's render.sigma_scale), so the march
reads either through one signature (``<prefix>_eval``):

    grid:  x -> "colour" 3D N^3 x 12 ; x -> "density" 3D N^3 x 1            (trilinear lookups)
    DI:    x -> "colour_primary" 3D Np^3 x 3 (ramp, triangle F, 8-bit) -> "colour_cascaded" 3D Nc^3 x 12 (f32)
           x -> "density_primary" 3D Np^3 x 3 (ramp, triangle F, 8-bit) -> "density_cascaded" 3D Nc^3 x 1 (f32)

Only the primaries are quantised (8-bit, after F, as the paper does for NeRF); the cascaded arrays
stay float32 (``bits`` 32: fp32 texels).

Sizes count cells only (indirection.array_bytes): a field's uncompressed bytes are N^3 x C x 4
(float32, the paper's DVGO grids), a head's compressed bytes Np^3 x 3 x 1 + Nc^3 x C x 4; a ratio r
sets the budget uncompressed / r, filled near the paper's rho (``plan``).

Training one head (Datta et al. 2023, §4.4): targets are trilinear samples of the target grid at
DVGO-like points -- ``shell_fraction`` of each batch jittered inside voxels of the soft surface shell
(field.shell_mask: where rays see colour and the density's edge), the rest uniform in the box; MAE,
Adam with a cosine schedule, the primary's half-cell gradient clip; the cascaded array starts as the
target grid box-filtered to Nc^3 (indirection INITS["downsample"], corner-aligned like the grid:
the paper's "carefully aligned" init). Density is sigma / SIGMA_SCALE throughout (unit scale, as the
colour's logits are).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch

from inshade.components.lookup_array.torch_twin import LookupArray
from inshade.models import indirection as di
from inshade.models.graph import GraphModule
from inshade.models.lookup_array import multilinear

from . import field

KIND = "di_radiance_field"
HEADS = {"colour": field.COLOUR_CHANNELS, "density": 1}
# paper supp. Table 6: optimal rho per compression ratio
RHO = {"density": {5: 3.57, 10: 3.8, 25: 2.69, 50: 1.97, 75: 2.82, 100: 2.51},
       "colour": {5: 5.05, 10: 3.42, 25: 4.14, 50: 4.53, 75: 3.58, 100: 5.74}}
PRIMARY_BITS, CASCADED_BITS = 8, 32


class RadianceFieldError(ValueError):
    """A ratio, grid or setting the compression cannot use; the message names the option."""


def uncompressed_bytes(n: int, head: str) -> int:
    return n ** 3 * HEADS[head] * 4


def rho_for(head: str, ratio: float) -> float:
    table = RHO[head]
    if ratio in table:
        return table[ratio]
    keys = sorted(table)
    return float(np.interp(ratio, keys, [table[k] for k in keys]))


RHO_TOLERANCE = 1.15   # N_p / N_c may deviate from the paper's rho by this factor to fill the budget


def plan(n: int, head: str, ratio: float) -> di.Sizing:
    """The cascade for N^3 x C x 4 / ratio bytes near the paper's rho (module docstring).

    The paper's 1-D search (``indirection.size_cascade``: N_c a multiple of 4, N_p the multiple of 8
    nearest rho N_c) lands far under the budget on a 128^3 field (colour 10x: N_c 36, N_p 120, 13.6x),
    since one step of N_c changes the bytes by ~40%. Here, for every N_c, N_p is the largest
    multiple of 8 that fits the rest of the budget with N_p / N_c within RHO_TOLERANCE of rho; the
    pair with the most bytes (then the rho nearest the paper's) wins (colour 10x: N_c 40, N_p 128,
    10.75x). Falls back to the paper's search (and its error) when no pair qualifies."""
    if head not in HEADS:
        raise RadianceFieldError(f"head: unknown head {head!r} (known: {', '.join(HEADS)})")
    if isinstance(ratio, bool) or not isinstance(ratio, (int, float)) or not ratio > 1:
        raise RadianceFieldError(f"--{head}-ratio: must be > 1, got {ratio!r}")
    channels = HEADS[head]
    budget = int(uncompressed_bytes(n, head) / ratio)
    rho = rho_for(head, ratio)
    best = None
    n_c = 4
    while True:
        cascaded = di.array_bytes(n_c, 3, channels, CASCADED_BITS)
        if cascaded + di.array_bytes(8, 3, 3, PRIMARY_BITS) > budget:
            break
        n_p = 8 * int(((budget - cascaded) / 3) ** (1.0 / 3.0) / 8 + 1e-9)
        while n_p >= 8 and di.array_bytes(n_p, 3, 3, PRIMARY_BITS) + cascaded > budget:
            n_p -= 8
        n_p = min(n_p, 8 * int(rho * RHO_TOLERANCE * n_c / 8))
        if n_p >= 8 and n_p / n_c >= rho / RHO_TOLERANCE:
            total = di.array_bytes(n_p, 3, 3, PRIMARY_BITS) + cascaded
            key = (total, -abs(n_p / n_c - rho))
            if best is None or key > best[0]:
                best = (key, n_p, n_c, total)
        n_c += 4
    if best is not None:
        _, n_p, n_c, total = best
        return di.Sizing(n_p, n_c, total, budget, n_p / n_c)
    try:
        return di.size_cascade(budget, rho, primary_dims=3, primary_channels=3, cascaded_dims=3,
                               cascaded_channels=channels, primary_bits=PRIMARY_BITS, cascaded_bits=CASCADED_BITS)
    except ValueError as e:
        raise RadianceFieldError(f"--{head}-ratio {ratio:g} on a {n}^3 grid: {e}") from None


# ---------------------------------------------------------------------------------------------
# graphs

def grid_graph(density: np.ndarray, colour: np.ndarray, bits: int = 32) -> GraphModule:
    """The uncompressed field as a bundle graph (two trilinear lookups; ``bits`` 8/16 quantises)."""
    n = density.shape[0]
    g = GraphModule([("x", 3, "position")])
    g.add("colour", LookupArray([n] * 3, field.COLOUR_CHANNELS, bits, init=torch.from_numpy(colour)), "x")
    g.add("density", LookupArray([n] * 3, 1, bits, init=torch.from_numpy(density[..., None] / field.SIGMA_SCALE)),
          "x")
    g.output("colour", "colour", "sh_logits")
    g.output("density", "density", "density")
    for p in g.parameters():
        p.requires_grad_(False)
    return g


def di_graph(heads: dict) -> GraphModule:
    """The multi-head DI graph from trained heads {"colour": (primary, cascaded), "density": ...}."""
    g = GraphModule([("x", 3, "position")])
    for head in ("colour", "density"):
        primary, cascaded = heads[head]
        g.add(f"{head}_primary", primary, "x")
        g.add(f"{head}_cascaded", cascaded, f"{head}_primary")
    g.output("colour", "colour_cascaded", "sh_logits")
    g.output("density", "density_cascaded", "density")
    for p in g.parameters():
        p.requires_grad_(False)
    return g


# ---------------------------------------------------------------------------------------------
# data

def head_target(head: str, density: np.ndarray, colour: np.ndarray) -> torch.Tensor:
    """[N, N, N, C] float32 target table of a head (density scaled to unit range)."""
    if head == "density":
        return torch.from_numpy(np.ascontiguousarray(density[..., None] / field.SIGMA_SCALE, np.float32))
    return torch.from_numpy(np.ascontiguousarray(colour, np.float32))


def sampler(target: torch.Tensor, shell: np.ndarray, batch: int, shell_fraction: float, seed: int):
    """Endless (x [B, 3], trilinear target [B, C]) batches (module docstring)."""
    n = target.shape[0]
    gen = torch.Generator().manual_seed(seed)
    cells = torch.from_numpy(np.argwhere(shell)[:, ::-1].copy()).float()   # (x, y, z) voxel corners
    n_shell = int(round(batch * shell_fraction)) if len(cells) else 0
    step = 1.0 / (n - 1)
    while True:
        parts = [torch.rand(batch - n_shell, 3, generator=gen)]
        if n_shell:
            pick = torch.randint(0, len(cells), (n_shell,), generator=gen)
            parts.append(((cells[pick] + torch.rand(n_shell, 3, generator=gen)) * step).clamp(0.0, 1.0))
        x = torch.cat(parts)
        with torch.no_grad():
            y = multilinear(target, x)
        yield x, y


def eval_set(target: torch.Tensor, shell: np.ndarray, count: int, seed: int):
    """A fixed held-out set from the same recipe (another seed)."""
    return next(sampler(target, shell, count, 0.75, seed + 1000))


# ---------------------------------------------------------------------------------------------
# training

@dataclass
class Head:
    head: str
    ratio: float
    sizing: di.Sizing
    primary: LookupArray
    cascaded: LookupArray
    history: di.History
    seconds: float

    def metrics(self) -> dict:
        n = self.sizing
        return {"ratio": self.ratio, "n_primary": n.n_primary, "n_cascaded": n.n_cascaded, "rho": round(n.rho, 4),
                "bytes": n.bytes, "budget_bytes": n.budget, "train_seconds": round(self.seconds, 2),
                "heldout_psnr": round(self.history.final["psnr"], 3), "steps": self.history.final["step"]}


def train_head(head: str, ratio: float, density: np.ndarray, colour: np.ndarray, *, steps: int, batch: int,
               lr: float, shell_fraction: float = 0.75, seed: int = 0, device="cpu", progress=None) -> Head:
    """Fit one head (module docstring). The returned arrays are on the CPU."""
    n = density.shape[0]
    sizing = plan(n, head, ratio)
    target = head_target(head, density, colour)
    shell = field.shell_mask(density)
    torch.manual_seed(seed)
    g = di.cascade(3, HEADS[head], sizing.n_primary, sizing.n_cascaded, primary_bits=PRIMARY_BITS,
                   cascaded_bits=CASCADED_BITS, cascaded_init="downsample",
                   cascaded_init_args={"target": target.numpy()}).to(device)
    x_eval, y_eval = eval_set(target, shell, 16384, seed)
    batches = ((x.to(device), y.to(device)) for x, y in sampler(target, shell, batch, shell_fraction, seed))
    t0 = time.perf_counter()
    history = di.train_cascade(g, batches, steps, lr=lr, schedule="cosine", seed=seed,
                               eval_set=(x_eval.to(device), y_eval.to(device)), clip_primary="auto",
                               progress=progress, desc=f"{head} {ratio:g}x")
    seconds = time.perf_counter() - t0
    g.cpu()
    primary, cascaded = g.nodes["primary"], g.nodes["cascaded"]
    return Head(head, float(ratio), sizing, primary, cascaded, history, seconds)


def di_bytes(graph_or_bundle) -> int:
    """Cells' bytes of a graph's lookup arrays at their bits (what the ratios count)."""
    g = graph_or_bundle
    return int(sum(di.array_bytes(a.resolution[0], 3, a.channels, a.bits) for a in g.nodes.values()
                   if isinstance(a, LookupArray)))
