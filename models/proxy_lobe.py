"""The importance-sampling proxy of Real-Time Neural Appearance Models (§5, Eqs. 8-11, App. A):
the `proxy_params` output activation and the proxy lobe's sampling routine and density, batched.
The component's twin is components/proxy_params/torch_twin.py; GLSL twins: components/proxy_params/emit.py
and shaders/lib/proxy_lobe.glsl (same formulas, same order).

Parameters, 9 lanes: [w_d, w_s, mu_d.x, mu_d.y, alpha_x, alpha_y, rho, mu_s.x, mu_s.y].

Output activation (Appendix A's quadratic tanh / sinh approximations, our exact choice):
    tq(x) = x (1 - |x| / 4) for |x| < 2, else sign(x)        (C1, range [-1, 1])
    sq(x) = x (1 + |x| / 4)                                  (odd, monotone, range R)
    (w_d, w_s) = softmax(raw0, raw1), written 1 / (1 + exp(other - own))
    alpha = max(0.5 (1 + tq(raw)), alpha_min), rho = 0.99 tq(raw), mu = sq(raw)
Isotropic (the baseline proxy): raw = (logit_d, logit_s, alpha) -> alpha_x = alpha_y, rho = 0,
mu_d = mu_s = 0.

Directions live in the local frame (z = surface normal); `view` is the known direction towards
the viewer, the routine samples `light`. u = (u.x, u.y, u.z) in [0, 1)^3: u.x < w_d picks the
diffuse lobe, u.yz draws the direction in either lobe.

Diffuse: cosine-weighted around n_d = normalize(-mu_d.x, -mu_d.y, 1) in the basis of Duff et al.
2017 (n_d.z > 0, so no sign branch): a = -1 / (1 + n.z), c = n.x n.y a,
b1 = (1 + n.x^2 a, c, -n.x), b2 = (c, 1 + n.y^2 a, -n.y).
Specular: the standard (alpha = 1) GGX NDF weighted by cos is D_std(h) h.z = h.z / pi, i.e.
cosine-weighted h_std; h = normalize(M h_std) with M of Eq. 11, light = reflect(-view, h).

Density on the whole sphere (samples may go below the horizon; the renderer discards them):
    pdf = w_d max(0, light . n_d) / pi
        + w_s q(h') det(M^-1) / |M^-1 h|^3 / (4 |light . h|),
h = +-normalize(view + light) oriented to h.z >= 0 (M h_std has z = h_std.z > 0, so the
generating half vector is the upper one; h and -h give the same light), h' = M^-1 h / |M^-1 h|,
q(h') = max(h'.z, 0) / pi, det(M^-1) = 1 / (alpha_x alpha_y sqrt(1 - rho^2)).
Differentiable in the parameters (the KL loss trains the sampler through it).
"""
from __future__ import annotations

import math

import torch

EPS = 1e-12


def tanh_q(x: torch.Tensor) -> torch.Tensor:
    return torch.where(x.abs() < 2.0, x * (1.0 - 0.25 * x.abs()), torch.sign(x))


def sinh_q(x: torch.Tensor) -> torch.Tensor:
    return x * (1.0 + 0.25 * x.abs())


def softmax2(a: torch.Tensor, b: torch.Tensor):
    return 1.0 / (1.0 + torch.exp(b - a)), 1.0 / (1.0 + torch.exp(a - b))


def proxy_activation(raw: torch.Tensor, isotropic: bool = False, alpha_min: float = 0.01) -> torch.Tensor:
    """raw [..., 9] (or [..., 3] isotropic) -> the 9 proxy parameters."""
    w_d, w_s = softmax2(raw[..., 0], raw[..., 1])
    if isotropic:
        a = torch.clamp_min(0.5 * (1.0 + tanh_q(raw[..., 2])), alpha_min)
        zero = torch.zeros_like(a)
        return torch.stack([w_d, w_s, zero, zero, a, a, zero, zero, zero], -1)
    mu_d = sinh_q(raw[..., 2:4])
    alpha = torch.clamp_min(0.5 * (1.0 + tanh_q(raw[..., 4:6])), alpha_min)
    rho = 0.99 * tanh_q(raw[..., 6:7])
    mu_s = sinh_q(raw[..., 7:9])
    return torch.cat([w_d[..., None], w_s[..., None], mu_d, alpha, rho, mu_s], -1)


def _normalize(x: torch.Tensor) -> torch.Tensor:
    return x * torch.rsqrt(torch.clamp_min((x * x).sum(-1, keepdim=True), EPS))


def _dot(a, b):
    return (a * b).sum(-1)


def diffuse_normal(params: torch.Tensor) -> torch.Tensor:
    return _normalize(torch.stack([-params[..., 2], -params[..., 3], torch.ones_like(params[..., 2])], -1))


def cosine_direction(u1, u2):
    """A cosine-weighted direction about +z from two uniforms (r = sqrt(u1), phi = 2 pi u2)."""
    r = torch.sqrt(u1)
    phi = (2.0 * math.pi) * u2
    return torch.stack([r * torch.cos(phi), r * torch.sin(phi), torch.sqrt(torch.clamp_min(1.0 - u1, 0.0))], -1)


def _m_apply(params, v):
    """M v (Eq. 11)."""
    ax, ay, rho, msx, msy = (params[..., i] for i in (4, 5, 6, 7, 8))
    s = torch.sqrt(torch.clamp_min(1.0 - rho * rho, 0.0))
    return torch.stack([ax * v[..., 0] - msx * v[..., 2],
                        ay * rho * v[..., 0] + ay * s * v[..., 1] - msy * v[..., 2], v[..., 2]], -1)


def _m_inverse_apply(params, v):
    """M^-1 v and det(M^-1)."""
    ax, ay, rho, msx, msy = (params[..., i] for i in (4, 5, 6, 7, 8))
    s = torch.sqrt(torch.clamp_min(1.0 - rho * rho, 0.0))
    px = (v[..., 0] + msx * v[..., 2]) / ax
    py = (v[..., 1] + msy * v[..., 2]) / ay
    return torch.stack([px, (py - rho * px) / s, v[..., 2]], -1), 1.0 / (ax * ay * s)


def proxy_sample(params: torch.Tensor, view: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
    """params [..., 9], view [..., 3] (unit), u [..., 3] in [0, 1) -> light [..., 3] (unit)."""
    local = cosine_direction(u[..., 1], u[..., 2])
    n = diffuse_normal(params)
    a = -1.0 / (1.0 + n[..., 2])
    c = n[..., 0] * n[..., 1] * a
    b1 = torch.stack([1.0 + n[..., 0] * n[..., 0] * a, c, -n[..., 0]], -1)
    b2 = torch.stack([c, 1.0 + n[..., 1] * n[..., 1] * a, -n[..., 1]], -1)
    diffuse = b1 * local[..., :1] + b2 * local[..., 1:2] + n * local[..., 2:]
    h = _normalize(_m_apply(params, local))
    specular = 2.0 * _dot(view, h)[..., None] * h - view
    return torch.where((u[..., 0] < params[..., 0])[..., None], diffuse, specular)


def proxy_pdf(params: torch.Tensor, view: torch.Tensor, light: torch.Tensor) -> torch.Tensor:
    """The density of proxy_sample's lights (solid angle, whole sphere): [...]."""
    p_d = torch.clamp_min(_dot(light, diffuse_normal(params)), 0.0) / math.pi
    h = _normalize(view + light)
    h = torch.where((h[..., 2] < 0.0)[..., None], -h, h)
    hp, det = _m_inverse_apply(params, h)
    len2 = _dot(hp, hp)
    q = torch.clamp_min(hp[..., 2], 0.0) * torch.rsqrt(len2) / math.pi
    p_s = q * det / (len2 * torch.sqrt(len2)) / torch.clamp_min(4.0 * _dot(light, h).abs(), EPS)
    return params[..., 0] * p_d + params[..., 1] * p_s
