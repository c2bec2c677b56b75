"""Analytic BRDFs, the torch twin of shaders/lib/brdf.glsl (Differentiable Indirection, Datta et al. 2023 §4.3).

- `ggx_d(nh, alpha_h)`: the isotropic GGX distribution exactly as the paper approximates it,
  D(h_z, a) = a^4 / (pi (1 + (a^4 - 1) h_z^2)^2), a = alpha_h in [0, 1) the artist roughness,
  h_z = n.h. (Only D: the paper learns this 2D function, not the full microfacet BRDF.)
- `disney(l, v, base_color, params)`: the principled BRDF after Tzu-Mao Li, "UCSD CSE 272
  Assignment 1: Disney Principled BSDF" (2022) -- diffuse (with subsurface), metal (anisotropic
  GGX, Smith masking, tinted Schlick Fresnel), clearcoat, sheen; glass excluded (no
  specularTransmission, eta fixed at 1.5). Like Li's, the value includes the cosine |n.l|, so a
  render is sum_lights disney(l, v) * E / r^2. Directions are unit vectors in the local frame:
  normal +z, tangent +x (the anisotropy axis), bitangent +y; v is Li's w_in (to the camera), l
  his w_out (to the light). Zero where n.l <= 0 or n.v <= 0.
- `disney_pq(...)`: the paper's Eq. 3 factorisation Disney(x, A) = (A / lum(A)) p(x) + q(x):
  the BRDF is affine in the albedo A, so p and q are exact scalars (tested against `disney`).

Artist parameters (`PARAMS`, a [..., 10] tensor in this order, each in [0, 1]): roughness,
metallic, anisotropic, subsurface, specular, specular_tint, sheen, sheen_tint, clearcoat,
clearcoat_gloss (Li's / Burley's names in snake case), plus base_color [..., 3] (linear RGB).

float32 mirroring (as codegen/sdf.py): the GLSL performs these operations one for one in the same
order; powers are written as products, constants are float32 literals, the one log and the sqrts
are the driver's. Parity is |glsl - torch| <= 1e-5 max(1, |torch|) (tests/models/test_brdf.py).
"""
from __future__ import annotations

import math

import torch

PARAMS = ("roughness", "metallic", "anisotropic", "subsurface", "specular", "specular_tint",
          "sheen", "sheen_tint", "clearcoat", "clearcoat_gloss")
# Defaults for a sweep (Fig. 11 protocol: one parameter varies, the others stay here).
DEFAULTS = {"roughness": 0.35, "metallic": 0.0, "anisotropic": 0.0, "subsurface": 0.0, "specular": 0.5,
            "specular_tint": 0.0, "sheen": 0.0, "sheen_tint": 0.5, "clearcoat": 0.0, "clearcoat_gloss": 1.0}
DEFAULT_BASE_COLOR = (0.8, 0.35, 0.15)
LUMINANCE = (0.2126, 0.7152, 0.0722)
ALPHA_MIN = 1e-4          # Li: anisotropic alphas are clamped here
ETA = 1.5                 # dielectric IOR of the specular and clearcoat layers
R0 = ((ETA - 1.0) / (ETA + 1.0)) ** 2   # 0.04
CLEARCOAT_ALPHA = 0.25    # Smith masking roughness of the clearcoat layer
INV_PI = 1.0 / math.pi


def _p(params: torch.Tensor, name: str) -> torch.Tensor:
    return params[..., PARAMS.index(name)]


def pow5(x):
    x2 = x * x
    return x2 * x2 * x


def ggx_d(nh: torch.Tensor, alpha_h: torch.Tensor) -> torch.Tensor:
    """Isotropic GGX D (paper supp. Eq. 1)."""
    a2 = alpha_h * alpha_h
    a4 = a2 * a2
    t = 1.0 + (a4 - 1.0) * (nh * nh)
    return a4 / (math.pi * (t * t))


def luminance(rgb: torch.Tensor) -> torch.Tensor:
    return rgb[..., 0] * LUMINANCE[0] + rgb[..., 1] * LUMINANCE[1] + rgb[..., 2] * LUMINANCE[2]


def half_vector(l, v):
    h = l + v
    return h * torch.rsqrt(h[..., 0] * h[..., 0] + h[..., 1] * h[..., 1] + h[..., 2] * h[..., 2])[..., None]


def dot3(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def aniso_alphas(roughness, anisotropic):
    aspect = torch.sqrt(1.0 - 0.9 * anisotropic)
    r2 = roughness * roughness
    return torch.clamp(r2 / aspect, min=ALPHA_MIN), torch.clamp(r2 * aspect, min=ALPHA_MIN)


def smith_g1(w, ax, ay):
    """Li's anisotropic Smith G1 = 1 / (1 + Lambda), Lambda = (sqrt(1 + (wx^2 ax^2 + wy^2 ay^2) / wz^2) - 1) / 2."""
    x = w[..., 0] * ax
    y = w[..., 1] * ay
    t = (x * x + y * y) / (w[..., 2] * w[..., 2])
    lam = (torch.sqrt(1.0 + t) - 1.0) * 0.5
    return 1.0 / (1.0 + lam)


def disney_lobes(l, v, params):
    """Albedo-free pieces shared by `disney` and `disney_pq` (all [...]):
    fd (diffuse incl. subsurface, times |n.l|, per unit albedo), sheen_w ((1 - h.l)^5 |n.l|),
    s ((1 - h.l)^5), metal (D G / (4 n.v), i.e. D G / (4 n.l n.v) times |n.l|), clear (Fc Dc Gc / (4 n.v)),
    and the mask of directions above the surface."""
    r, ss = _p(params, "roughness"), _p(params, "subsurface")
    h = half_vector(l, v)
    nl, nv, nh = l[..., 2], v[..., 2], h[..., 2]
    hl = dot3(h, l)
    fl, fv, s = pow5(1.0 - nl), pow5(1.0 - nv), pow5(1.0 - hl)
    hl2 = hl * hl
    # diffuse (Li Eq. 3-5): Schlick-like retro-reflection and the Hanrahan-Krueger subsurface
    fd90 = 0.5 + 2.0 * r * hl2
    base = INV_PI * (1.0 + (fd90 - 1.0) * fl) * (1.0 + (fd90 - 1.0) * fv) * nl
    fss90 = r * hl2
    fss = (1.0 + (fss90 - 1.0) * fl) * (1.0 + (fss90 - 1.0) * fv)
    sub = (1.25 * INV_PI) * (fss * (1.0 / (nl + nv) - 0.5) + 0.5) * nl
    fd = (1.0 - ss) * base + ss * sub
    # metal (Li Eq. 6-10): anisotropic GGX + Smith; Fresnel is applied by the callers
    ax, ay = aniso_alphas(r, _p(params, "anisotropic"))
    hx, hy = h[..., 0] / ax, h[..., 1] / ay
    q = hx * hx + hy * hy + nh * nh
    d = 1.0 / (math.pi * ax * ay * (q * q))
    metal = d * smith_g1(l, ax, ay) * smith_g1(v, ax, ay) / (4.0 * nv)
    # clearcoat (Li Eq. 11-13)
    g = _p(params, "clearcoat_gloss")
    ag = (1.0 - g) * 0.1 + g * 0.001
    ag2 = ag * ag
    dc = (ag2 - 1.0) / (math.pi * torch.log(ag2) * (1.0 + (ag2 - 1.0) * (nh * nh)))
    ca = torch.full_like(nl, CLEARCOAT_ALPHA)
    fc = R0 + (1.0 - R0) * s
    clear = fc * dc * smith_g1(l, ca, ca) * smith_g1(v, ca, ca) / (4.0 * nv)
    above = (nl > 0.0) & (nv > 0.0)
    return {"fd": fd, "sheen_w": s * nl, "s": s, "metal": metal, "clear": clear, "above": above}


def _tint(base_color):
    lum = luminance(base_color)
    return torch.where(lum[..., None] > 0.0, base_color / torch.clamp(lum, min=1e-30)[..., None],
                       torch.ones_like(base_color)), lum


def disney(l, v, base_color, params):
    """Li's Disney BRDF (no glass) times |n.l|: [..., 3] linear RGB."""
    t = disney_lobes(l, v, params)
    m, sp = _p(params, "metallic")[..., None], _p(params, "specular")[..., None]
    st, sh = _p(params, "specular_tint")[..., None], _p(params, "sheen")[..., None]
    sht, cc = _p(params, "sheen_tint")[..., None], _p(params, "clearcoat")[..., None]
    tint, _ = _tint(base_color)
    ks = (1.0 - st) + st * tint
    c0 = sp * R0 * (1.0 - m) * ks + m * base_color
    s = t["s"][..., None]
    fm = c0 + (1.0 - c0) * s
    csheen = (1.0 - sht) + sht * tint
    out = ((1.0 - m) * base_color * t["fd"][..., None]
           + (1.0 - m) * sh * csheen * t["sheen_w"][..., None]
           + fm * t["metal"][..., None]
           + 0.25 * cc * t["clear"][..., None])
    return torch.where(t["above"][..., None], out, torch.zeros_like(out))


def disney_pq(l, v, params, lum):
    """Paper Eq. 3: disney(l, v, A, x) = (A / lum) p + q for any albedo A of luminance lum > 0.
    Returns (p, q), both [...]. Metal's C0 and the tints are affine in A, hence the exact split."""
    t = disney_lobes(l, v, params)
    m, sp, st = _p(params, "metallic"), _p(params, "specular"), _p(params, "specular_tint")
    sh, sht, cc = _p(params, "sheen"), _p(params, "sheen_tint"), _p(params, "clearcoat")
    one_s = 1.0 - t["s"]
    p = ((1.0 - m) * lum * t["fd"] + (1.0 - m) * sh * sht * t["sheen_w"]
         + (sp * R0 * (1.0 - m) * st + m * lum) * one_s * t["metal"])
    q = ((1.0 - m) * sh * (1.0 - sht) * t["sheen_w"]
         + (sp * R0 * (1.0 - m) * (1.0 - st) * one_s + t["s"]) * t["metal"]
         + 0.25 * cc * t["clear"])
    zero = torch.zeros_like(p)
    return torch.where(t["above"], p, zero), torch.where(t["above"], q, zero)


def material(params: dict | None = None, base_color=DEFAULT_BASE_COLOR, batch=()):
    """(base_color [*batch, 3], params [*batch, 10]) from a dict of overrides on DEFAULTS."""
    vals = {**DEFAULTS, **(params or {})}
    unknown = sorted(set(vals) - set(PARAMS))
    if unknown:
        raise ValueError(f"unknown Disney parameter {unknown[0]!r} (known: {', '.join(PARAMS)})")
    p = torch.tensor([float(vals[k]) for k in PARAMS], dtype=torch.float32).expand(*batch, len(PARAMS))
    b = torch.tensor(base_color, dtype=torch.float32).expand(*batch, 3)
    return b.clone(), p.clone()


# --- sampling (paper supp. 1.1-1.2: local frame with n = +z) -------------------------------------

def cosine_hemisphere(n: int, gen: torch.Generator) -> torch.Tensor:
    """n unit directions, pdf cos(theta)/pi."""
    u1, u2 = torch.rand(n, generator=gen), torch.rand(n, generator=gen)
    r, phi = torch.sqrt(u1), 2.0 * math.pi * u2
    return torch.stack([r * torch.cos(phi), r * torch.sin(phi), torch.sqrt(torch.clamp(1.0 - u1, min=0.0))], -1)


def uniform_hemisphere(n: int, gen: torch.Generator, min_cos: float = 0.0) -> torch.Tensor:
    z = min_cos + (1.0 - min_cos) * torch.rand(n, generator=gen)
    phi = 2.0 * math.pi * torch.rand(n, generator=gen)
    r = torch.sqrt(torch.clamp(1.0 - z * z, min=0.0))
    return torch.stack([r * torch.cos(phi), r * torch.sin(phi), z], -1)


def exponential_like(n: int, gen: torch.Generator, rate: float = 3.0) -> torch.Tensor:
    """Roughness biased to low values (paper: "exponential-like"): a truncated exponential on [0, 1)."""
    u = torch.rand(n, generator=gen)
    return -torch.log1p(-u * (1.0 - math.exp(-rate))) / rate
