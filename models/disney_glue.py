"""The learned DI Disney BRDF's glue: the arithmetic that combines the five runtime decoder lookups
(Differentiable Indirection, Datta et al. 2023 supp. 1.2) into the BRDF value; the torch twin of
shaders/lib/di_brdf.glsl `di_disney_brdf`, operation for operation, so the GLSL and torch agree to
float32 rounding.

`dec` holds the decoder outputs by name (ggx [..., 3] d0..d2, smith [..., 1] k, diff [..., 4]
f_0..f_3, coef [..., 4] c_d, c_m, c_s, k_cc, gloss [..., 2] e0, e1), `extra` the per-texel scalars
stored beside the latents (sheen_tint [...], k [..., 3]); l and v are unit directions in the local
frame (normal +z, tangent +x). Shared by the material-ball BRDFs and the end-to-end shading
pipeline that trains through the frozen decoder.
"""
from __future__ import annotations

import torch

from inshade.models import brdf


def disney_glue(dec: dict, extra: dict, albedo, l, v):
    """shaders/lib/di_brdf.glsl `di_disney_brdf`, operation for operation."""
    g, k, f, c, e = dec["ggx"], dec["smith"][..., 0], dec["diff"], dec["coef"], dec["gloss"]
    st, kk = extra["sheen_tint"], extra["k"]
    h = l + v
    h = h * torch.rsqrt(h[..., 0] * h[..., 0] + h[..., 1] * h[..., 1] + h[..., 2] * h[..., 2])[..., None]
    nl, nv, nh = l[..., 2], v[..., 2], h[..., 2]
    hl = h[..., 0] * l[..., 0] + h[..., 1] * l[..., 1] + h[..., 2] * l[..., 2]
    fl, fv, s = brdf.pow5(1.0 - nl), brdf.pow5(1.0 - nv), brdf.pow5(1.0 - hl)
    t = hl * hl
    flv = fl * fv
    w = 1.0 / (nl + nv) - 0.5
    fd = nl * (f[..., 0] * ((1.0 - 0.5 * fl) * (1.0 - 0.5 * fv)) + f[..., 1] * (2.0 * t * (fl + fv - flv))
               + f[..., 2] * ((1.0 - fl) * (1.0 - fv) * w + 0.5) + f[..., 3] * (t * (fl + fv - 2.0 * flv) * w))
    den = g[..., 0] * (h[..., 0] * h[..., 0]) + g[..., 1] * (h[..., 1] * h[..., 1]) + g[..., 2] * (nh * nh)
    dg = 1.0 / (den * den) * (nl / (nl * (1.0 - k) + k)) * (1.0 / (4.0 * (nv * (1.0 - k) + k)))
    kc = c[..., 3]
    gc = (nl / (nl * (1.0 - kc) + kc)) * (1.0 / (4.0 * (nv * (1.0 - kc) + kc)))
    dc = 1.0 / (e[..., 0] * (1.0 - nh * nh) + e[..., 1])
    fc = 0.04 + 0.96 * s
    lum = torch.clamp(albedo[..., 0] * 0.2126 + albedo[..., 1] * 0.7152 + albedo[..., 2] * 0.0722, min=0.0001)
    sn = s * nl
    p = c[..., 0] * lum * fd + c[..., 2] * st * sn + (c[..., 0] * kk[..., 0] + c[..., 1] * lum) * (1.0 - s) * dg
    q = (c[..., 2] - c[..., 2] * st) * sn + (c[..., 0] * kk[..., 1] * (1.0 - s) + s) * dg + kk[..., 2] * fc * dc * gc
    out = albedo / lum[..., None] * p[..., None] + q[..., None]
    above = (nl > 0.0) & (nv > 0.0)
    return torch.where(above[..., None], out, torch.zeros_like(out))
