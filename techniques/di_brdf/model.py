"""The learned BRDFs' networks (Differentiable Indirection, Datta et al. 2023 §4.3, supp. 1.1-1.2).

GGX: the 16x16x2 primary -> 8x8x1 cascaded (`ggx_cascade`, initialised to D clamped at GGX_INIT_CAP)
and D read from it (`learned_d`, called like `analytic_d`). Disney: `DisneyDI`, the offline encoders
E_* and the five runtime decoders (DECODERS, ENCODERS; decoders start at their exact / initial
targets) combined by the glue (models/disney_glue.py), and the asset's graph (`disney_graph`): the
latent and artist-parameter textures over the ball grid (`material_textures`) feeding the decoders.
"""
from __future__ import annotations

import math

import torch

from inshade.components.dense.torch_twin import Dense
from inshade.components.lookup_array.torch_twin import LookupArray
from inshade.models import brdf
from inshade.models import indirection as di
from inshade.models.disney_glue import disney_glue
from inshade.models.graph import GraphModule
from inshade.models.indirection import make_array

# Cascaded init: D at the cells, clamped where the balls saturate (key light: radiance ~ 2 n.l x
# GGX_KS D, white from D ~ 2). Versus the paper's constant 0.5 it starts the primary in the right
# basin: pooled ball PSNR over seeds 0/1/2 47.2/50.9/47.8 dB vs 47.0/43.4/40.7 dB (8000 steps),
# and the cap keeps the 8-bit cascaded range (and so its step) small; a cap of 4 or 8 did worse.
GGX_INIT_CAP = 2.0
GGX_CASCADED_INIT = "clamped_d"
ENCODER_SIZE = 64
DECODER_SIZE = 16


# GGX
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


# Disney: decoder targets, encoder and decoder tables, the module
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


# Disney: the asset's graph
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
