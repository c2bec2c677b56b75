"""The BRDF of the per-voxel data bake and of the reference renderer (numpy, float64).

    f(v, l, n) = (1 - metallic) * base / pi * F_D(n.l) * F_D(n.v)               (Burley diffuse)
               + D(n.h) * G1(n.v) * G1(n.l) * F(v.h) / (4 (n.l) (n.v))           (GGX specular)

with alpha = max(roughness^2, ALPHA_MIN), h = normalize(v + l) and
  F_D(c)   = 1 + (F_D90 - 1) (1 - c)^5,  F_D90 = 0.5 + 2 roughness (l.h)^2
  D(c)     = alpha^2 / (pi ((alpha^2 - 1) c^2 + 1)^2)
  G1(c)    = 2 c / (c + sqrt(alpha^2 + (1 - alpha^2) c^2))           (separable Smith GGX)
  F(c)     = F0 + (1 - F0) (1 - c)^5,  F0 = 0.04 (1 - metallic) + base * metallic.
f = 0 where n.l <= 0 or n.v <= 0. The value excludes the cosine: reflected radiance from a
light of irradiance E (at normal incidence) along l is f * max(0, n.l) * E. The formula is
symmetric in (v, l) (reciprocal). The bake evaluates it with base = 1 (white), the reference
with the face's base colour (DAP's rho * albedo factorisation, paper Eq. 17).
"""
from __future__ import annotations

import math

import numpy as np

ALPHA_MIN = 1e-3    # keeps D finite for roughness 0 (a mirror would need a delta lobe)
DIELECTRIC_F0 = 0.04


def _dot(a, b):
    return (a * b).sum(-1)


def brdf(n, v, l, base, roughness, metallic):
    """f [..., C] for unit n, v, l [..., 3], base [..., C] (C = 1 or 3), roughness and metallic [...]."""
    n, v, l = (np.asarray(x, np.float64) for x in (n, v, l))
    base = np.asarray(base, np.float64)
    rough = np.asarray(roughness, np.float64)
    metal = np.asarray(metallic, np.float64)
    nl, nv = _dot(n, l), _dot(n, v)
    h = v + l
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-30)
    nh, lh = _dot(n, h), _dot(l, h)
    cl, cv = np.clip(nl, 0.0, 1.0), np.clip(nv, 0.0, 1.0)
    fd90 = 0.5 + 2.0 * rough * lh * lh
    diffuse = (1.0 + (fd90 - 1.0) * (1.0 - cl) ** 5) * (1.0 + (fd90 - 1.0) * (1.0 - cv) ** 5) / math.pi
    a2 = np.maximum(rough * rough, ALPHA_MIN) ** 2
    d = a2 / (math.pi * ((a2 - 1.0) * nh * nh + 1.0) ** 2)
    g = _g1(cl, a2) * _g1(cv, a2)
    f0 = DIELECTRIC_F0 * (1.0 - metal[..., None]) + base * metal[..., None]
    fresnel = f0 + (1.0 - f0) * ((1.0 - np.clip(lh, 0.0, 1.0)) ** 5)[..., None]
    denom = np.maximum(4.0 * cl * cv, 1e-12)
    spec = (d * g / denom)[..., None] * fresnel
    f = ((1.0 - metal) * diffuse)[..., None] * base + spec
    return np.where(((nl > 0.0) & (nv > 0.0))[..., None], f, 0.0)


def _g1(c, a2):
    return 2.0 * c / np.maximum(c + np.sqrt(a2 + (1.0 - a2) * c * c), 1e-30)
