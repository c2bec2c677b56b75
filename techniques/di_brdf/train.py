"""Differentiable Indirection BRDFs (Datta et al. 2023 §4.3, supp. 1.1-1.2).

GGX. A 16x16 primary (2 channels, identity uv ramp, triangle F, 8-bit) queried with (alpha_h, h_z)
-> an 8x8 cascaded array (1 channel, no F, 8-bit; initialised to D clamped at 2 rather than the
paper's constant 0.5, see GGX_INIT_CAP) approximating
D = a^4 / (pi (1 + (a^4 - 1) h_z^2)^2) (models/brdf.py `ggx_d`). Samples: h_z of a
cosine-hemisphere direction, alpha_h exponential-like (biased to glossy) for the paper's L1 on D.
Here the loss is in the domain the Fig. 6 balls are judged in (`ggx_loss`): MSE of the clamped,
sRGB-encoded ball radiance on samples distributed like the ball pixels (alpha_h uniform over the
ball row's range, points over the ball, the scene's lights), plus a small tone-mapped L1 on D
over the paper's sampling; Adam, cosine schedule. L1 on raw D spends the 8x8 cells on peaks
that saturate to white (pooled ball PSNR 39.3 dB, worst ball 34.1 at 1500 steps), the display
loss on the dim highlights the balls show (47.5 / 41.7 dB at 8000 steps, ~75 s on one core).

Disney. Albedo factored out (paper Eq. 3; exact, models/brdf.py `disney_pq`), then five runtime
lookups (decoders) and ~70 FLOPs of glue (shaders/lib/di_brdf.glsl, torch models/disney_glue.py):

| decoder | array | queried with | holds |
|---|---|---|---|
| ggx   | 16x16 x3 | z_m = E_m(roughness, anisotropic) | d0, d1, d2: D_m = 1 / (d0 hx^2 + d1 hy^2 + d2 nh^2)^2 |
| smith | 16x16 x1 | z_m | k of a Schlick-Smith G1 = n.w / (n.w (1 - k) + k) |
| diff  | 16x16 x4 | z_d = E_d(roughness, subsurface) | f_0..f_3 of f_d = n.l sum f_i g_i (g_i analytic, K = 4) |
| coef  | 16x16 x4 | z_c = E_c(metallic, sheen) | 1 - metallic, metallic, (1 - metallic) sheen, clearcoat k |
| gloss | 16 x2    | z_g = E_g(clearcoat_gloss) | e0, e1: D_c = 1 / (e0 (1 - nh^2) + e1) |

The denominators of D_m and D_c are learned, not D (paper: "we learn the reciprocal of the output
which has bounded range"). The encoders E_* are DI primary arrays (64x64 / 64, 2 or 1 channels,
sinusoid F as the paper uses for Disney) run offline: they turn artist-parameter textures into
latent textures (`encode`). Three scalars per texel need no lookup and are stored in the latent
textures as the analytic pre-computation (0.04 specular specular_tint, 0.04 specular
(1 - specular_tint), clearcoat / 4, and sheen_tint): the paper leaves this part open.

Training (`train_disney`): decoders start at the exact targets at their cells (identity encoders),
then encoders + decoders are trained end to end with L1 on the tone-mapped radiance x / (1 + x) of
random (l, v, material) samples (uniform hemispheres, exponential-like roughness and clearcoat
roughness, uniform other parameters and albedo), Adam, cosine schedule.

Quality (the paper's Fig. 6 / Fig. 11 protocol, `sweep_psnr`): material balls rendered with the
learned and the analytic BRDF (techniques/di_brdf/material_balls.py, the lights of the shipped scene), PSNR
over the ball pixels in the display domain -- linear radiance clamped to [0, 1], sRGB-encoded,
peak 1; for Disney one row per artist parameter swept 0 -> 1 with the others at brdf.DEFAULTS, and
the minimum over the row is reported. For GGX the row sweeps alpha_h.

    inshade train di_brdf ggx --force -o trained/di_brdf_ggx --preset ship
    inshade train di_brdf disney --force -o trained/di_brdf_disney --preset ship

``--preset ship`` (the default) is exactly what built the shipped assets (PRESETS; Disney: 300 steps at
batch 2048); ``quick`` is a short run. Options given explicitly override the preset; OUT/metrics.json
records the preset and the resolved settings.
"""
from __future__ import annotations

import argparse
import datetime
import json
import math
import shlex
import sys
import time
from pathlib import Path

import numpy as np
import torch

from inshade.files import atomic_files, atomic_write
from inshade import asset_folder, command
from inshade.devices import DeviceError, add_device_argument, resolve_device
from inshade.models import brdf
from inshade.models.disney_glue import disney_glue
from inshade.models.display import srgb_display
from inshade.models import indirection as di
from inshade.techniques.di_brdf import material_balls as mb
from inshade.models.graph import GraphModule
from inshade.models.indirection import make_array
from inshade.models.lookup_array import LookupArray
from inshade.models.mlp import Dense

PROGRAM = "passes/material_balls.frag"
GGX_KIND, DISNEY_KIND = "di_brdf_ggx", "di_brdf_disney"
# Fig. 6-style GGX balls: f = n.l (GGX_KD base / pi + GGX_KS D), alpha_h swept over the columns.
GGX_KD, GGX_KS = 0.5, 0.25
GGX_ALPHA_RANGE = (0.1, 1.0)
# lr 2e-2 vs 1e-2 (clamped init, 8000 steps, seeds 0/1/2): pooled ball PSNR 49.1/48.9/47.6 vs
# 47.2/50.9/47.8 dB, worst ball 44.2/46.4/42.2 vs 41.4/46.0/41.9; 16000 steps added ~0.5 dB.
GGX_DEFAULTS = dict(steps=8000, batch=4096, lr=2e-2, schedule="cosine", seed=0)
# Weight of the function-domain term of `ggx_loss` next to the display-domain ball MSE: enough to
# keep D tracking the analytic one off the balls' domain (measured with the constant init, 8000
# steps: tone-mapped function PSNR 35.9 dB, -3.9 dB without the term), small enough not to pull
# the balls (1e-2 cost ~1.4 dB pooled).
GGX_FUNCTION_WEIGHT = 1e-3
# Cascaded init: D at the cells, clamped where the balls saturate (key light: radiance ~ 2 n.l x
# GGX_KS D, white from D ~ 2). Versus the paper's constant 0.5 it starts the primary in the right
# basin: pooled ball PSNR over seeds 0/1/2 47.2/50.9/47.8 dB vs 47.0/43.4/40.7 dB (8000 steps),
# and the cap keeps the 8-bit cascaded range (and so its step) small; a cap of 4 or 8 did worse.
GGX_INIT_CAP = 2.0
GGX_CASCADED_INIT = "clamped_d"
DISNEY_DEFAULTS = dict(steps=400, batch=4096, lr=3e-3, schedule="cosine", seed=0, samples=1 << 17)
# --preset, per BRDF: "ship" is what built trained/di_brdf_<which> (GGX: GGX_DEFAULTS; Disney: 300
# steps at batch 2048, not DISNEY_DEFAULTS' 400 x 4096); "quick" a short run.
PRESETS = {"ship": {"ggx": dict(steps=8000, batch=4096, lr=2e-2, seed=0),
                    "disney": dict(steps=300, batch=2048, lr=3e-3, samples=1 << 17, seed=0)},
           "quick": {"ggx": dict(steps=500, batch=4096, lr=2e-2, seed=0),
                     "disney": dict(steps=60, batch=2048, lr=3e-3, samples=1 << 15, seed=0)}}
ENCODER_SIZE = 64
DECODER_SIZE = 16
SWEEP_COLUMNS = 8
# Views of the material-ball pass (BRDF_VIEW define), mirrored in the GLSL.
VIEWS = {"analytic": 0, "learned": 1, "split": 2, "diffuse": 3}
MODELS = {"ggx": 1, "disney": 2}


class BrdfTrainingError(ValueError):
    """A setting the BRDF trainer cannot use."""


def preset_settings(preset: str, asset: str | None = None) -> dict:
    """The settings ``--preset PRESET`` resolves to for the asset folder ``asset`` (di_brdf_ggx or
    di_brdf_disney; default ggx)."""
    which = asset.removeprefix("di_brdf_") if asset else "ggx"
    return {"which": which, **PRESETS[preset][which]}


# =============================================================================================
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


def ggx_init_cells(x: torch.Tensor) -> torch.Tensor:
    """Cascaded-array init at the cell points x = (alpha_h, n.h) [P, 2] (what the identity primary
    reads there): D clamped to GGX_INIT_CAP (alpha_h floored so that D(0, 1) = 0/0 is the cap)."""
    return analytic_d(x[:, 0].clamp_min(1e-2), x[:, 1]).clamp(max=GGX_INIT_CAP)[:, None]


def ggx_cascade(cascaded_init: str = GGX_CASCADED_INIT) -> GraphModule:
    """16x16x2 primary (identity ramp, triangle F) -> 8x8x1 cascaded, both 8-bit. `cascaded_init`
    "clamped_d" (default, `ggx_init_cells`) or "constant" (the paper's 0.5)."""
    init, args = {"clamped_d": ("downsample", {"target": ggx_init_cells}),
                  "constant": ("constant", {"value": 0.5})}[cascaded_init]
    return di.cascade(2, 1, 16, 8, primary_bits=8, cascaded_bits=8, cascaded_init=init,
                      cascaded_init_args=args, input_name="x", input_semantic="alpha_h, n.h",
                      output_name="d", output_semantic="ggx_d")


def analytic_d(alpha_h, nh):
    return brdf.ggx_d(nh, alpha_h)


def learned_d(g: GraphModule):
    """D from a (quantised) GGX cascade, called like `analytic_d`."""
    return lambda alpha_h, nh: g(torch.stack([alpha_h, nh], -1))[..., 0]


def ggx_shade(d_fn):
    """Fig. 6 GGX ball shading with D given by `d_fn(alpha_h, nh)` (`analytic_d` or `learned_d`)."""
    def shade(sel, l, v, k):
        lo, hi = GGX_ALPHA_RANGE
        cols = shade.cols
        a = lo + (hi - lo) * (sel["col"].float() / float(max(cols - 1, 1)))
        h = brdf.half_vector(l, v)
        d = d_fn(a, h[..., 2])
        f = l[..., 2] * (GGX_KD * 0.5 * brdf.INV_PI + GGX_KS * d)
        f = torch.where((l[..., 2] > 0.0) & (v[..., 2] > 0.0), f, torch.zeros_like(f))
        return f[..., None].expand(-1, 3)
    return shade


def ggx_render(d_fn, cols: int = SWEEP_COLUMNS, size: int = 64, lights: int = 1) -> np.ndarray:
    shade = ggx_shade(d_fn)
    shade.cols = cols
    return mb.render(size * cols, size, cols, 1, shade, lights)


def ggx_metrics(g: GraphModule, cols: int = SWEEP_COLUMNS, size: int = 64) -> dict:
    """PSNR of the 8-bit GGX cascade: Fig. 6 ball row (display domain, per ball and mean) and the
    function itself on the sampling distribution (x / (1 + x) tone-mapped D, and raw D with peak max D)."""
    q = di.quantised_copy(g, 8)
    ref = ggx_render(analytic_d, cols, size)
    got = ggx_render(learned_d(q), cols, size)
    inside, ids = mb.ball_masks(size * cols, size, cols, 1)
    per_ball = [mb.ball_psnr(got, ref, inside & (ids == c)) for c in range(cols)]
    x, y = ggx_eval_set()
    with torch.no_grad():
        p = q(x)
    tm = lambda t: t / (1.0 + t)  # noqa: E731
    return {"psnr_balls_mean": float(np.mean(per_ball)), "psnr_balls_min": float(np.min(per_ball)),
            "psnr_balls": [round(v, 3) for v in per_ball],
            "psnr_balls_all_pixels": mb.ball_psnr(got, ref, inside),
            "psnr_function_tonemapped": di.psnr(tm(p), tm(y)),
            "psnr_function_raw_peak_max": di.psnr(p, y, float(y.max()))}


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


def ggx_loss(g: GraphModule, ball, fn):
    """MSE of the display-domain ball samples (what the ball PSNR measures: radiance clamped and
    sRGB-encoded, so D's peaks above white cost nothing and dim highlights count) + GGX_FUNCTION_WEIGHT
    x L1 of x / (1 + |x|) tone-mapped D on the paper's sampling (`ggx_sampler`), which keeps D sane
    where no ball pixel looks (alpha_h < 0.1, n.h no light reaches)."""
    with torch.no_grad():
        ref = ggx_ball_display(analytic_d, *ball)
    err = ggx_ball_display(learned_d(g), *ball) - ref
    x, y = fn
    return torch.mean(err * err) + GGX_FUNCTION_WEIGHT * torch.mean(torch.abs(_tonemap(g(x)) - _tonemap(y)))


def train_ggx(steps=GGX_DEFAULTS["steps"], batch=GGX_DEFAULTS["batch"], lr=GGX_DEFAULTS["lr"],
              schedule=GGX_DEFAULTS["schedule"], seed=GGX_DEFAULTS["seed"], progress=None, device=None):
    """Adam on `ggx_loss` (batch ball samples + batch / 4 function samples a step) with an
    `indirection.SCHEDULES` schedule (`indirection.train_cascade` with this objective). History:
    step, loss (mean training loss since the last record), psnr (display domain, float cascade, on
    16384 fixed ball samples), lr, seconds. Trains on `device` (default the CPU); the cascade comes
    back on the CPU."""
    torch.manual_seed(seed)
    g = ggx_cascade().to(device)
    samples = zip(ggx_ball_sampler(batch, seed, device), ggx_sampler(max(batch // 4, 1), seed + 1, device))
    ev = next(ggx_ball_sampler(1 << 14, seed + 2, device))
    with torch.no_grad():
        ev_ref = ggx_ball_display(analytic_d, *ev)

    def metric(cascade):
        got = ggx_ball_display(learned_d(cascade), *ev)
        return float(torch.mean((got - ev_ref) ** 2)), di.psnr(got, ev_ref)

    t0 = time.perf_counter()
    hist = di.train_cascade(g, samples, steps, lr=lr, schedule=schedule, seed=seed,
                            objective=lambda cascade, b: ggx_loss(cascade, *b), metric=metric,
                            progress=progress, desc="di_brdf_ggx")
    return g.to("cpu"), hist, time.perf_counter() - t0


# =============================================================================================
# Disney: encoders, decoders, glue

def _sqrt_pi_axay(r, an):
    ax, ay = brdf.aniso_alphas(r, an)
    k = torch.sqrt(math.pi * ax * ay)
    return ax, ay, k


def target_ggx(x):
    """(roughness, anisotropic) [P, 2] -> (d0, d1, d2) with D_m = 1 / (d0 hx^2 + d1 hy^2 + d2 nh^2)^2."""
    ax, ay, k = _sqrt_pi_axay(x[:, 0], x[:, 1])
    return torch.stack([k / (ax * ax), k / (ay * ay), k], -1)


def target_smith(x):
    """Initial Schlick-Smith k = alpha / 2 (alpha = sqrt(ax ay)); training refines it."""
    ax, ay = brdf.aniso_alphas(x[:, 0], x[:, 1])
    return (0.5 * torch.sqrt(ax * ay))[:, None]


def target_diff(x):
    """(roughness, subsurface) -> f_i for g = (B0, B1, S0 w + 1/2, S1 w): bilinear in the inputs,
    hence exact on a 16x16 grid (Li's r^2 terms are left to training)."""
    r, ss = x[:, 0], x[:, 1]
    return torch.stack([(1.0 - ss) * brdf.INV_PI, (1.0 - ss) * r * brdf.INV_PI,
                        1.25 * brdf.INV_PI * ss, 1.25 * brdf.INV_PI * ss * r], -1)


def target_coef(x):
    m, sh = x[:, 0], x[:, 1]
    return torch.stack([1.0 - m, m, (1.0 - m) * sh, torch.full_like(m, 0.5 * brdf.CLEARCOAT_ALPHA)], -1)


def target_gloss(x):
    g = x[:, 0]
    ag = (1.0 - g) * 0.1 + g * 0.001
    ag2 = ag * ag
    lg = torch.log(ag2)
    return torch.stack([-math.pi * lg, math.pi * lg * ag2 / (ag2 - 1.0)], -1)


# name: (encoder inputs (PARAMS names), decoder resolution, channels, exact/initial target)
DECODERS = {
    "ggx": (("roughness", "anisotropic"), [16, 16], 3, target_ggx),
    "smith": (("roughness", "anisotropic"), [16, 16], 1, target_smith),
    "diff": (("roughness", "subsurface"), [16, 16], 4, target_diff),
    "coef": (("metallic", "sheen"), [16, 16], 4, target_coef),
    "gloss": (("clearcoat_gloss",), [16], 2, target_gloss),
}
# decoders sharing a latent share an encoder
ENCODERS = {"m": ("roughness", "anisotropic"), "d": ("roughness", "subsurface"), "c": ("metallic", "sheen"),
            "g": ("clearcoat_gloss",)}
DECODER_ENCODER = {"ggx": "m", "smith": "m", "diff": "d", "coef": "c", "gloss": "g"}


class DisneyDI(torch.nn.Module):
    """Encoders (offline primaries) + decoders (runtime cascaded arrays) + the glue."""

    def __init__(self, encoder_size: int = ENCODER_SIZE):
        super().__init__()
        self.encoders = torch.nn.ModuleDict({
            k: make_array([encoder_size] * len(ins), len(ins), init="ramp", nonlinearity="sinusoid",
                          frequency=math.pi)
            for k, ins in ENCODERS.items()})
        self.decoders = torch.nn.ModuleDict({
            k: make_array(res, ch, init="downsample", target=fn) for k, (ins, res, ch, fn) in DECODERS.items()})

    def encode(self, params: torch.Tensor) -> dict:
        """Artist parameters [..., 10] -> latent codes per encoder (what the latent textures hold)."""
        return {k: self.encoders[k](torch.stack([params[..., brdf.PARAMS.index(n)] for n in ins], -1))
                for k, ins in ENCODERS.items()}

    def decode(self, z: dict) -> dict:
        return {k: self.decoders[k](z[DECODER_ENCODER[k]]) for k in DECODERS}

    def extras(self, params):
        """The per-texel scalars stored beside the latents (no lookup needed)."""
        p = lambda n: params[..., brdf.PARAMS.index(n)]  # noqa: E731
        return {"sheen_tint": p("sheen_tint"),
                "k": torch.stack([brdf.R0 * p("specular") * p("specular_tint"),
                                  brdf.R0 * p("specular") * (1.0 - p("specular_tint")), 0.25 * p("clearcoat")], -1)}

    def forward(self, l, v, base_color, params):
        dec = self.decode(self.encode(params))
        return disney_glue(dec, self.extras(params), base_color, l, v)


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


def _tonemap(x):
    return x / (1.0 + x.abs())


def train_disney(steps=DISNEY_DEFAULTS["steps"], batch=DISNEY_DEFAULTS["batch"], lr=DISNEY_DEFAULTS["lr"],
                 samples=DISNEY_DEFAULTS["samples"], seed=DISNEY_DEFAULTS["seed"], exposure: float = 1.5,
                 progress=None, device=None):
    """End-to-end L1 on tone-mapped radiance (exposure ~ the scene's E / r^2); returns (model, history, seconds).
    Trains on `device` (default the CPU); the model comes back on the CPU."""
    from inshade.progress import progress as progress_bar

    torch.manual_seed(seed)
    model = DisneyDI().to(device)
    data = disney_samples(samples, seed, device)
    history = []
    t0 = time.perf_counter()
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        opt = torch.optim.Adam(model.parameters(), lr=lr)
        sched = torch.optim.lr_scheduler.LambdaLR(
            opt, lambda i: 0.05 + 0.95 * 0.5 * (1 + math.cos(math.pi * min(i / max(steps, 1), 1.0))))
        gen = torch.Generator().manual_seed(seed + 1)
        bar = progress_bar(range(1, steps + 1), desc="di_brdf_disney", enabled=progress)
        for step in bar:
            idx = torch.randint(0, samples, (batch,), generator=gen).to(device)
            l, v, base, params, target = (t[idx] for t in data)
            pred = model(l, v, base, params)
            loss = torch.mean(torch.abs(_tonemap(exposure * pred) - _tonemap(exposure * target)))
            if not torch.isfinite(loss):
                continue  # a degenerate sample (denominator ~ 0); skip the step
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            sched.step()
            if step % max(1, steps // 10) == 0 or step == steps:
                history.append({"step": step, "loss": float(loss.detach()), "seconds": round(time.perf_counter() - t0, 2)})
                bar.set_postfix(loss=f"{history[-1]['loss']:.4f}")
    for p in model.parameters():
        p.requires_grad_(False)
    return model.to("cpu"), history, time.perf_counter() - t0


# =============================================================================================
# Disney: sweep grid, material/latent textures, bundle

def sweep_grid(cols: int = SWEEP_COLUMNS, base_color=brdf.DEFAULT_BASE_COLOR):
    """Fig. 11 grid: row i sweeps PARAMS[i] over linspace(0, 1, cols), the others at DEFAULTS.
    Returns (base [rows, cols, 3], params [rows, cols, 10]); row 0 is drawn at the bottom."""
    rows = len(brdf.PARAMS)
    base, params = brdf.material(batch=(rows, cols), base_color=base_color)
    vals = torch.linspace(0, 1, cols)
    for i in range(rows):
        params[i, :, i] = vals
    return base, params


def material_textures(model: DisneyDI, base, params) -> dict:
    """Latent + parameter textures over the grid, [rows, cols, 4] each (the lookup-array layout
    [N_1, N_0, C] of a [cols, rows] array). lat_a..lat_g feed the decoders; par0..par3 are the
    artist-parameter textures the analytic shader reads."""
    with torch.no_grad():
        z = model.encode(params)
        ex = model.extras(params)
    zero = torch.zeros_like(base[..., 0])
    p = lambda n: params[..., brdf.PARAMS.index(n)]  # noqa: E731
    return {
        "lat_a": torch.stack([z["m"][..., 0], z["m"][..., 1], ex["sheen_tint"], ex["k"][..., 2]], -1),
        "lat_b": torch.stack([z["d"][..., 0], z["d"][..., 1], ex["k"][..., 0], ex["k"][..., 1]], -1),
        "lat_c": torch.stack([z["c"][..., 0], z["c"][..., 1], base[..., 0], base[..., 1]], -1),
        "lat_g": torch.stack([z["g"][..., 0], base[..., 2], zero, zero], -1),
        "par0": torch.stack([base[..., 0], base[..., 1], base[..., 2], p("roughness")], -1),
        "par1": torch.stack([p("metallic"), p("anisotropic"), p("subsurface"), p("specular")], -1),
        "par2": torch.stack([p("specular_tint"), p("sheen"), p("sheen_tint"), p("clearcoat")], -1),
        "par3": torch.stack([p("clearcoat_gloss"), zero, zero, zero], -1),
    }


# Output lanes of the Disney bundle (mirrored by DI_* defines in passes/material_balls.frag).
DISNEY_OUTPUTS = (("ggx", 3), ("smith", 1), ("diff", 4), ("coef", 4), ("gloss", 2), ("lat_a", 4), ("lat_b", 4),
                  ("lat_c", 4), ("lat_g", 4), ("par0", 4), ("par1", 4), ("par2", 4), ("par3", 4))
DECODER_SOURCE = {"ggx": "lat_a", "smith": "lat_a", "diff": "lat_b", "coef": "lat_c", "gloss": "lat_g"}


def disney_graph(model: DisneyDI, base, params) -> GraphModule:
    """The asset's graph: input the ball-grid coordinate; latent/parameter textures (32-bit lookup
    arrays over the grid) and the five decoders (32-bit, as the paper's full-precision 12 KB)."""
    rows, cols = base.shape[:2]
    g = GraphModule([("grid", 2, "ball grid coordinate")])
    tex = material_textures(model, base, params)
    for name, t in tex.items():
        g.add(name, LookupArray([cols, rows], 4, 32, init=t.clone()), "grid")
    for src in sorted(set(DECODER_SOURCE.values())):
        # lookup arrays take exactly d-wide inputs: a one-hot dense node picks the latent lanes
        # (inline constants of 0 and 1, which GLSL compilers fold away)
        width = len(DECODERS[next(k for k, s in DECODER_SOURCE.items() if s == src)][1])
        pick = Dense(4, width, bias=False)
        with torch.no_grad():
            pick.linear.weight.zero_()
            for i in range(width):
                pick.linear.weight[i, i] = 1.0
        g.add(f"z_{src}", pick, src)
    for name in DECODERS:
        dec = model.decoders[name]
        g.add(name, LookupArray(dec.resolution, dec.channels, 32, init=dec.table().detach().clone()),
              f"z_{DECODER_SOURCE[name]}")
    for name, _ in DISNEY_OUTPUTS:
        g.output(name, name, name)
    for p in g.parameters():
        p.requires_grad_(False)
    return g


def graph_shade(g: GraphModule):
    """Disney ball shading through the exported graph (what the GLSL evaluates): learned or analytic."""
    def lanes(sel):
        with torch.no_grad():
            y = g(sel["grid"])
        out, off = {}, 0
        for name, w in DISNEY_OUTPUTS:
            out[name] = y[..., off:off + w]
            off += w
        return out

    def shade(sel, l, v, k, learned):
        y = lanes(sel)
        if learned:
            dec = {n: y[n] for n in DECODERS}
            extra = {"sheen_tint": y["lat_a"][..., 2], "k": torch.stack(
                [y["lat_b"][..., 2], y["lat_b"][..., 3], y["lat_a"][..., 3]], -1)}
            albedo = torch.stack([y["lat_c"][..., 2], y["lat_c"][..., 3], y["lat_g"][..., 1]], -1)
            return disney_glue(dec, extra, albedo, l, v)
        par = torch.cat([y["par0"], y["par1"], y["par2"], y["par3"]], -1)
        return brdf.disney(l, v, par[..., :3], par[..., 3:13])
    return shade


def disney_render(g: GraphModule, view: str, cols: int, rows: int, size: int, lights: int = 1) -> np.ndarray:
    shade = graph_shade(g)
    halves = 2 if view == "split" else 1

    def fn(sel, l, v, k):
        if view == "split":
            learned = sel["side"] == 1
            a, b = shade(sel, l, v, k, False), shade(sel, l, v, k, True)
            return torch.where(learned[..., None], b, a)
        if view == "diffuse":
            with torch.no_grad():   # the baseline: albedo n.l / pi
                par = g(sel["grid"])
            off = sum(w for n, w in DISNEY_OUTPUTS[:DISNEY_OUTPUTS.index(("par0", 4))])
            return par[..., off:off + 3] * (l[..., 2:3].clamp(min=0.0) * brdf.INV_PI)
        return shade(sel, l, v, k, view == "learned")
    return mb.render(size * cols * halves, size * rows, cols, rows, fn, lights, halves)


def sweep_psnr(g: GraphModule, cols: int, rows: int, size: int = 32, lights: int = 2) -> dict:
    """Per artist parameter (row): min and mean ball PSNR (display domain) learned vs analytic."""
    ref = disney_render(g, "analytic", cols, rows, size, lights)
    got = disney_render(g, "learned", cols, rows, size, lights)
    inside, ids = mb.ball_masks(size * cols, size * rows, cols, rows)
    out = {}
    for r in range(rows):
        vals = [mb.ball_psnr(got, ref, inside & (ids == r * cols + c)) for c in range(cols)]
        out[brdf.PARAMS[r]] = {"min": round(min(vals), 3), "mean": round(float(np.mean(vals)), 3),
                               "per_ball": [round(v, 2) for v in vals]}
    return out


def glsl_psnr(folder, model: str, lut_filter: str, ball_px: int) -> dict:
    """Quality from the shader's own output: the asset's material-ball pass rendered through the GL
    driver with the analytic and the learned BRDF (2 lights), ball PSNR in the display domain;
    Disney: min per row (artist parameter), GGX: per ball. Also returns GL_RENDERER."""
    from inshade.runtime.camera import camera_from_dict
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer
    from inshade.runtime.scene import load_scene

    scene = load_scene(folder)
    cols = scene.settings["cols"].default
    rows = scene.settings["rows"].default
    w, h = cols * ball_px, rows * ball_px
    cam = camera_from_dict({"type": "plane2d", "aspect": w / h})
    imgs = {}
    for view in ("analytic", "learned"):
        r = SceneRenderer(scene, settings={"view": VIEWS[view], "lut_filter": lut_filter, "lights": 2})
        try:
            imgs[view] = read_rgba(r.render_network(cam, w, h))[..., :3]
            renderer = r.gl["renderer"]
        finally:
            r.release()
    inside, ids = mb.ball_masks(w, h, cols, rows)
    per = [[mb.ball_psnr(imgs["learned"], imgs["analytic"], inside & (ids == rr * cols + c)) for c in range(cols)]
           for rr in range(rows)]
    out = {"gl_renderer": renderer, "lut_filter": lut_filter}
    if model == "disney":
        out["rows_min"] = {brdf.PARAMS[rr]: round(min(per[rr]), 3) for rr in range(rows)}
        out["min"] = min(out["rows_min"].values())
    else:
        out["per_ball"] = [round(v, 3) for v in per[0]]
        out["mean"], out["min"] = float(np.mean(per[0])), float(np.min(per[0]))
        out["all_pixels"] = mb.ball_psnr(imgs["learned"], imgs["analytic"], inside)
    return out


# =============================================================================================
# assets

def scene_dict(name: str, title: str, model: str, size, cols: int, rows: int, ball_px: int) -> dict:
    return {
        "format": "inshade.scene", "version": 1, "name": name, "title": title,
        "program": PROGRAM, "size": list(size),
        "networks": [{"bundle": ".", "prefix": "net"}],
        "camera": {"type": "plane2d", "center": [0.5, 0.5], "zoom": 1.0, "aspect": size[0] / size[1]},
        "lights": [{"type": "point", "position": list(L[:3]), "intensity": L[3]} for L in mb.LIGHTS],
        "environment": None,
        "display": {"mode": "network", "modes": ["network"], "split": 0.5},
        "settings": {
            "exposure": {"type": "float", "default": 1.0, "min": 0.0, "max": 8.0, "uniform": "u_exposure",
                         "label": "exposure"},
            "lights": {"type": "int", "default": 2, "min": 1, "max": mb.MAX_LIGHTS, "uniform": "u_light_count",
                       "label": "point lights"},
            "view": {"type": "int", "default": VIEWS["split"], "min": 0, "max": 3, "define": "BRDF_VIEW",
                     "label": "0 analytic, 1 learned, 2 side by side, 3 diffuse baseline"},
            "model": {"type": "int", "default": MODELS[model], "min": MODELS[model], "max": MODELS[model],
                      "define": "BRDF_MODEL", "label": "1 GGX, 2 Disney"},
            "cols": {"type": "int", "default": cols, "min": cols, "max": cols, "define": "BALL_COLS",
                     "label": "grid columns"},
            "rows": {"type": "int", "default": rows, "min": rows, "max": rows, "define": "BALL_ROWS",
                     "label": "grid rows"},
            "lut_filter": {"type": "choice", "default": "exact", "choices": ["exact", "fast"],
                           "codegen": "lut_filter", "label": "LUT filtering"},
        },
        "requires": {"gl": 330},
        "notes": f"material balls, {ball_px} px each; left half analytic, right half learned (view 2)",
        "labels": [
            {"text": "analytic", "at": [0.25, 0.95], "when": {"view": VIEWS["split"]}},
            {"text": "learned", "at": [0.75, 0.95], "when": {"view": VIEWS["split"]}},
            {"line": [[0.5, 0.0], [0.5, 1.0]], "when": {"view": VIEWS["split"]}},
            {"text": "analytic", "at": [0.5, 0.95], "when": {"view": VIEWS["analytic"]}},
            {"text": "learned", "at": [0.5, 0.95], "when": {"view": VIEWS["learned"]}},
            {"text": "diffuse baseline", "at": [0.5, 0.95], "when": {"view": VIEWS["diffuse"]}},
        ],
    }


def _provenance(command, extra):
    return {"command": command, "torch": torch.__version__,
            "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"), **extra}


def _write_scene(out: Path, scene: dict, preview: np.ndarray):
    from inshade.runtime.image_io import write_png

    atomic_write(out / "scene.json", json.dumps(scene, indent=2) + "\n")
    write_png(out / "preview.png", preview)


def build_ggx(out, steps=GGX_DEFAULTS["steps"], batch=GGX_DEFAULTS["batch"], lr=GGX_DEFAULTS["lr"],
              seed=GGX_DEFAULTS["seed"], command: str = "", progress=None, ball_px: int = 64,
              gl_metrics: bool = True, device=None) -> dict:
    device = torch.device("cpu") if device is None else torch.device(device)
    g, hist, seconds = train_ggx(steps, batch, lr, seed=seed, progress=progress, device=device)
    for p in g.parameters():
        p.requires_grad_(False)
    metrics = {"train_seconds": round(seconds, 2), "steps": steps, "batch": batch, "lr": lr,
               "history": [{"step": r["step"], "psnr": round(r["psnr"], 3), "seconds": round(r["seconds"], 2)}
                           for r in hist.records]}
    prov = _provenance(command, {
        "technique": "Differentiable Indirection isotropic GGX (Datta et al. 2023): 16x16x2 primary "
                     "(uv ramp, triangle F, 8-bit) -> 8x8x1 cascaded (init D clamped to "
                     f"{GGX_INIT_CAP:g} at the cells, no F, 8-bit)",
        "training": f"display-domain MSE on ball samples (alpha_h uniform {GGX_ALPHA_RANGE}, points over "
                    f"the ball, 1-{mb.MAX_LIGHTS} scene lights) + {GGX_FUNCTION_WEIGHT:g} x L1 on x/(1+x) "
                    f"tone-mapped D (alpha_h exponential-like, h_z cosine-hemisphere), Adam lr {lr:g} "
                    f"cosine, batch {batch} (+{max(batch // 4, 1)} function samples), {steps} steps, seed {seed}",
        "psnr_domain": "Fig. 6 ball row: radiance clamped to [0,1], sRGB-encoded, over ball pixels, peak 1",
        "device": str(device)})
    return write_ggx_asset(g, out, metrics, prov, ball_px, gl_metrics)


def write_ggx_asset(g: GraphModule, out, metrics: dict, prov: dict, ball_px: int = 64,
                    gl_metrics: bool = True) -> dict:
    """Bundle (8-bit) + scene.json + preview.png (torch, analytic | learned) + quality metrics."""
    metrics = {**metrics, "bytes": 16 * 16 * 2 + 8 * 8, **ggx_metrics(g)}
    out = Path(out)
    bundle = g.export(GGX_KIND, out.name, provenance=prov, metrics=metrics)
    bundle.save(out)
    cols = SWEEP_COLUMNS
    scene = scene_dict(out.name, "DI GGX: analytic | learned, alpha_h 0.1 -> 1", "ggx",
                       (2 * cols * ball_px, ball_px), cols, 1, ball_px)
    shade_a, shade_l = ggx_shade(analytic_d), ggx_shade(learned_d(GraphModule.from_bundle(bundle)))
    shade_a.cols = shade_l.cols = cols

    def split(sel, l, v, k):
        return torch.where((sel["side"] == 1)[..., None], shade_l(sel, l, v, k), shade_a(sel, l, v, k))
    preview = mb.render(2 * cols * ball_px, ball_px, cols, 1, split, 2, 2)
    _write_scene(out, scene, preview)
    if gl_metrics:
        metrics["glsl"] = {f: glsl_psnr(out, "ggx", f, ball_px) for f in ("exact", "fast")}
        g.export(GGX_KIND, out.name, provenance=prov, metrics=metrics).save(out)
    return metrics


def build_disney(out, steps=DISNEY_DEFAULTS["steps"], batch=DISNEY_DEFAULTS["batch"], lr=DISNEY_DEFAULTS["lr"],
                 samples=DISNEY_DEFAULTS["samples"], seed=DISNEY_DEFAULTS["seed"], command: str = "",
                 progress=None, ball_px: int = 32, gl_metrics: bool = True, device=None) -> dict:
    device = torch.device("cpu") if device is None else torch.device(device)
    model, hist, seconds = train_disney(steps, batch, lr, samples, seed, progress=progress, device=device)
    cols, rows = SWEEP_COLUMNS, len(brdf.PARAMS)
    base, params = sweep_grid(cols)
    g = disney_graph(model, base, params)
    sweep = sweep_psnr(g, cols, rows, size=ball_px)
    metrics = {"train_seconds": round(seconds, 2), "steps": steps, "batch": batch, "lr": lr,
               "decoder_bytes_fp32": 4 * (16 * 16 * (3 + 1 + 4 + 4) + 16 * 2),
               "sweep_min_psnr": min(v["min"] for v in sweep.values()), "sweep": sweep, "history": hist}
    prov = _provenance(command, {
        "technique": "Differentiable Indirection Disney BRDF (Datta et al. 2023 supp. 1.2) after Li 2022 "
                     "(no glass): albedo factored out, 5 decoders (16x16x3, 16x16x1, 16x16x4, 16x16x4, 16x2) "
                     "+ glue (shaders/lib/di_brdf.glsl); encoders 64^2 sinusoid primaries run offline into "
                     "the latent textures lat_*; par* are the artist textures for the analytic shader",
        "training": f"end-to-end L1 on x/(1+x) tone-mapped radiance, Adam lr {lr:g} cosine, batch {batch}, "
                    f"{steps} steps over {samples} samples, seed {seed}",
        "psnr_domain": "Fig. 11: ball pixels, radiance clamped to [0,1], sRGB-encoded, peak 1; min per row",
        "device": str(device)})
    out = Path(out)
    bundle = g.export(DISNEY_KIND, out.name, provenance=prov, metrics=metrics)
    bundle.save(out)
    _save_encoders(model, out / "encoders.safetensors")
    scene = scene_dict(out.name, "DI Disney: analytic | learned, one artist parameter per row, 0 -> 1",
                       "disney", (2 * cols * ball_px, rows * ball_px), cols, rows, ball_px)
    preview = disney_render(GraphModule.from_bundle(bundle), "split", cols, rows, ball_px, 2)
    _write_scene(out, scene, preview)
    if gl_metrics:
        metrics["glsl"] = {f: glsl_psnr(out, "disney", f, ball_px) for f in ("exact", "fast")}
        g.export(DISNEY_KIND, out.name, provenance=prov, metrics=metrics).save(out)
    return metrics


def _save_encoders(model: DisneyDI, path: Path):
    """The offline encoders (F baked, float32), for encoding other artist textures: safetensors,
    tensors "E_<m|d|c|g>.cells" with the lookup-array cell layout; inputs per ENCODERS."""
    from safetensors.numpy import save_file

    tensors = {f"E_{k}.cells": np.ascontiguousarray(e.table().detach().numpy(), dtype=np.float32)
               for k, e in model.encoders.items()}
    with atomic_files(path) as tmp:
        save_file(tensors, str(tmp), metadata={"inputs": json.dumps(ENCODERS)})


# =============================================================================================
# command line

def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    p.add_argument("which", choices=("ggx", "disney"), help="which learned BRDF to build")
    asset_folder.add_arguments(p, "di_brdf_<which>")
    p.add_argument("--preset", choices=sorted(PRESETS), default="ship",
                   help="ship: exactly what built trained/di_brdf_<which>; quick: a short run; options given "
                        "explicitly override it (default %(default)s)")
    p.add_argument("--steps", type=int, help="training steps (default: the preset's)")
    p.add_argument("--batch", type=int, help="samples per step (default: the preset's)")
    p.add_argument("--lr", type=float, help="Adam learning rate (default: the preset's)")
    p.add_argument("--seed", type=int, help="random seed (default: the preset's, 0)")
    p.add_argument("--no-gl", action="store_true", help="skip the shader-rendered PSNR (no GL context)")
    add_device_argument(p)
    return p


def run(args, argv=None) -> int:
    device = resolve_device(args.device)     # first: a missing CUDA device fails before any work
    args.out = str(asset_folder.claim(args.out, f"di_brdf_{args.which}", force=args.force))
    # explicit option > the preset's value
    settings = {"which": args.which, **PRESETS[args.preset][args.which]}
    for k in ("steps", "batch", "lr", "seed"):
        if getattr(args, k) is not None:
            settings[k] = getattr(args, k)
    steps, batch, lr = settings["steps"], settings["batch"], settings["lr"]
    if steps < 0 or batch < 1 or not lr > 0:
        raise BrdfTrainingError("--steps must be >= 0, --batch >= 1 and --lr > 0")
    argv = list(sys.argv[1:] if argv is None else argv)
    command = shlex.join(["inshade", "train", "di_brdf", *argv])
    kw = {k: v for k, v in settings.items() if k != "which"}
    build = build_ggx if args.which == "ggx" else build_disney
    m = build(args.out, **kw, command=command, gl_metrics=not args.no_gl, device=device)
    # metrics.json: the preset, the settings it resolved to (tests/test_presets.py holds the shipped
    # assets' equal to preset_settings("ship", asset)) and the bundle's metrics without the loss history
    atomic_write(Path(args.out) / "metrics.json",
                 json.dumps({"command": command, "preset": args.preset, "settings": settings,
                             **{k: v for k, v in m.items() if k != "history"}}, indent=1) + "\n")
    if args.which == "ggx":
        print(f"wrote {args.out}: GGX ball PSNR all pixels {m['psnr_balls_all_pixels']:.2f} dB, "
              f"mean {m['psnr_balls_mean']:.2f} dB (min {m['psnr_balls_min']:.2f}), "
              f"function (tone-mapped) {m['psnr_function_tonemapped']:.2f} dB, {m['train_seconds']:.1f} s")
    else:
        rows = ", ".join(f"{k} {v['min']:.1f}" for k, v in m["sweep"].items())
        print(f"wrote {args.out}: Disney sweep min PSNR {m['sweep_min_psnr']:.2f} dB ({rows}), "
              f"{m['train_seconds']:.1f} s")
    return 0


def main(argv=None) -> int:
    return command.main("inshade train di_brdf", __doc__, add_arguments, run, argv, errors=(DeviceError,))

