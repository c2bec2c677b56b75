"""What the learned BRDFs are trained and measured on.

GGX: (alpha_h, n.h) samples of D (`ggx_sampler`, `ggx_eval_set`: h_z of a cosine-hemisphere
direction, alpha_h exponential-like) and the Fig. 6 ball row -- per ball pixel n.h and the light
weights (`ggx_ball_terms`), samples distributed like the ball pixels (`ggx_ball_sampler`) and their
display-domain value (`ggx_ball_display`). Disney: (l, v, material) samples with the analytic
target (`disney_samples`) and the Fig. 11 sweep grid (`sweep_grid`). Random numbers come from
seeded CPU generators, so every device sees the same samples.
"""
from __future__ import annotations

import math

import torch

from inshade.models import brdf
from inshade.models.display import srgb_display
from inshade.techniques.di_brdf import material_balls as mb

# Fig. 6-style GGX balls: f = n.l (GGX_KD base / pi + GGX_KS D), alpha_h swept over the columns.
GGX_KD, GGX_KS = 0.5, 0.25
GGX_ALPHA_RANGE = (0.1, 1.0)
SWEEP_COLUMNS = 8


# GGX
def ggx_sampler(batch: int, seed: int = 0, device=None):
    """Endless ((alpha_h, h_z), D) batches: h_z of a cosine-hemisphere direction, alpha_h exponential-like.
    Drawn on a seeded CPU generator (the same numbers on every device), D computed on `device`."""
    gen = torch.Generator().manual_seed(seed)
    while True:
        a = brdf.exponential_like(batch, gen, 3.0).to(device)
        hz = brdf.cosine_hemisphere(batch, gen)[:, 2].to(device)
        yield torch.stack([a, hz], -1), brdf.ggx_d(hz, a)[:, None]


def ggx_eval_set(n: int = 1 << 15, seed: int = 1234):
    gen = torch.Generator().manual_seed(seed)
    a = brdf.exponential_like(n, gen, 3.0)
    hz = brdf.cosine_hemisphere(n, gen)[:, 2]
    return torch.stack([a, hz], -1), brdf.ggx_d(hz, a)[:, None]


def ggx_ball_terms(P: torch.Tensor, lights: int = mb.MAX_LIGHTS):
    """Per ball point P [B, 3] (cell units, ball at the origin, viewer along +z as in
    `material_balls.render`): n.h [B, lights] and the light weights w [B, lights] =
    n.l * intensity / dist^2 (0 where n.l <= 0 or n.v <= 0), so that a ball pixel's linear radiance
    is sum_k w_k (GGX_KD / (2 pi) + GGX_KS D(alpha_h, n.h_k)) -- `ggx_shade` summed over the lights."""
    n = P / mb.BALL_RADIUS
    lt = torch.tensor(mb.LIGHTS[:lights], dtype=torch.float32, device=P.device)
    d = lt[None, :, :3] - P[:, None]
    dist2 = (d * d).sum(-1)
    l = d * torch.rsqrt(dist2)[..., None]
    h = l + torch.tensor([0.0, 0.0, 1.0], device=P.device)
    h = h * torch.rsqrt((h * h).sum(-1))[..., None]
    nl = (n[:, None] * l).sum(-1)
    lit = (nl > 0.0) & (n[:, None, 2] > 0.0)
    w = torch.where(lit, nl * lt[None, :, 3] / dist2, torch.zeros_like(nl))
    return (n[:, None] * h).sum(-1).clamp(0.0, 1.0), w


def ggx_ball_sampler(batch: int, seed: int = 0, device=None):
    """Endless (alpha_h [B], n.h [B, L], w [B, L]) batches distributed like the Fig. 6 ball pixels:
    alpha_h uniform over GGX_ALPHA_RANGE (continuous, not just the 8 columns), a point uniform over
    the ball's disk, the first 1..MAX_LIGHTS scene lights (the viewer's light-count setting).
    Drawn on a seeded CPU generator (the same numbers on every device), computed on `device`."""
    gen = torch.Generator().manual_seed(seed)
    lo, hi = GGX_ALPHA_RANGE
    r2 = mb.BALL_RADIUS * mb.BALL_RADIUS
    while True:
        u_a, u_rho, u_phi = (torch.rand(batch, generator=gen).to(device) for _ in range(3))
        count = torch.randint(1, mb.MAX_LIGHTS + 1, (batch, 1), generator=gen).to(device)
        a = lo + (hi - lo) * u_a
        rho = torch.sqrt(r2 * u_rho)
        phi = 2.0 * math.pi * u_phi
        x, y = rho * torch.cos(phi), rho * torch.sin(phi)
        P = torch.stack([x, y, torch.sqrt((r2 - x * x - y * y).clamp_min(0.0))], -1)
        nh, w = ggx_ball_terms(P)
        yield a, nh, w * (torch.arange(mb.MAX_LIGHTS, device=device)[None] < count)


def ggx_ball_display(d_fn, a, nh, w) -> torch.Tensor:
    """Display-domain value (`srgb_display`) of ball samples, D given by `d_fn(alpha_h, n.h)`."""
    d = d_fn(a[:, None].expand_as(nh), nh)
    return srgb_display((w * (GGX_KD * 0.5 * brdf.INV_PI + GGX_KS * d)).sum(-1))


# Disney
def disney_samples(n: int, seed: int = 0, device=None):
    """(l, v, base_color, params, target rgb): the paper's distributions (supp. 1.2), drawn on a
    seeded CPU generator (the same numbers on every device); all on `device`, the target computed there."""
    gen = torch.Generator().manual_seed(seed)
    l = brdf.uniform_hemisphere(n, gen, 0.01)
    v = brdf.uniform_hemisphere(n, gen, 0.01)
    base = torch.rand(n, 3, generator=gen)
    params = torch.rand(n, len(brdf.PARAMS), generator=gen)
    params[:, brdf.PARAMS.index("roughness")] = brdf.exponential_like(n, gen, 2.0)
    params[:, brdf.PARAMS.index("clearcoat_gloss")] = 1.0 - brdf.exponential_like(n, gen, 2.0)
    l, v, base, params = (t.to(device) for t in (l, v, base, params))
    with torch.no_grad():
        target = brdf.disney(l, v, base, params)
    return l, v, base, params, target


def sweep_grid(cols: int = SWEEP_COLUMNS, base_color=brdf.DEFAULT_BASE_COLOR):
    """Fig. 11 grid: row i sweeps PARAMS[i] over linspace(0, 1, cols), the others at DEFAULTS.
    Returns (base [rows, cols, 3], params [rows, cols, 10]); row 0 is drawn at the bottom."""
    rows = len(brdf.PARAMS)
    base, params = brdf.material(batch=(rows, cols), base_color=base_color)
    vals = torch.linspace(0, 1, cols)
    for i in range(rows):
        params[i, :, i] = vals
    return base, params
