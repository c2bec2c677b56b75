"""Torch twin of shaders/lib/na_reference.glsl (same operations in the same order, float32) and
the parameter-texture sampling GL does (bilinear, repeat, texel centres at (i + 0.5) / N, box mips).

The material: a clear coat (isotropic GGX on the geometric normal, IOR from the description,
roughened by the smudge mask) over a base that mixes Lambert (albedo = base colour) and a tinted
conductor (Schlick F0 = base colour, anisotropic GGX with height-correlated Smith G2, rotated by
the direction angle) by metallic, shaded in the normal-mapped frame; the base is attenuated by
(1 - w_c F_c(l.z)) (1 - w_c F_c(v.z)); a rough diffuse dust is mixed in by dust_weight * mask.
`reflectance` is f * cos (the base's cosine in its shading frame), 0 below the geometric horizon.
Channel layout and decoding: material.py.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from inshade.models.brdf import half_vector, pow5

from .material import ALPHA_MIN, CHANNELS, Material

PI = math.pi
INV_PI = 1.0 / math.pi
COS_MIN = 1e-6


def _lambda(w, ax, ay):
    x = w[..., 0] * ax
    y = w[..., 1] * ay
    z2 = torch.clamp(w[..., 2] * w[..., 2], min=COS_MIN * COS_MIN)
    return (torch.sqrt(1.0 + (x * x + y * y) / z2) - 1.0) * 0.5


def _ggx_dg(l, v, h, ax, ay):
    """D(h) G2(l, v) / (4 v.z)."""
    hx = h[..., 0] / ax
    hy = h[..., 1] / ay
    q = hx * hx + hy * hy + h[..., 2] * h[..., 2]
    d = 1.0 / (PI * ax * ay * (q * q))
    g = 1.0 / (1.0 + _lambda(l, ax, ay) + _lambda(v, ax, ay))
    return d * g / (4.0 * torch.clamp(v[..., 2], min=COS_MIN))


def _schlick(f0, c):
    return f0 + (1.0 - f0) * pow5(1.0 - c)


def _dot(a, b0, b1, b2):
    return a[..., 0] * b0 + a[..., 1] * b1 + a[..., 2] * b2


def reflectance(params: torch.Tensor, light: torch.Tensor, view: torch.Tensor, material: Material | dict) -> torch.Tensor:
    """f * cos for params [..., 12] (texture values), unit light/view [..., 3] -> [..., 3] (float32,
    or float64 when params are float64)."""
    c_ = material.constants if isinstance(material, Material) else material
    if params.shape[-1] != len(CHANNELS):
        raise ValueError(f"reflectance: params must end in {len(CHANNELS)} channels, got {tuple(params.shape)}")
    dt = torch.float64 if params.dtype == torch.float64 else torch.float32   # float64: an accuracy yardstick
    p = params.to(dt)
    light, view = light.to(dt), view.to(dt)
    f32 = lambda x: float(np.float32(x))   # constants as the GLSL uniforms hold them
    rlo, rhi = (f32(x) for x in c_["roughness_range"])
    clo, chi = (f32(x) for x in c_["coat_roughness_range"])
    amax, slope, ior = f32(c_["anisotropy_max"]), f32(c_["slope_scale"]), f32(c_["coat_ior"])
    smudge, dust_w = f32(c_["smudge_coat_roughness"]), f32(c_["dust_weight"])
    dust_c = torch.tensor([f32(x) for x in c_["dust_colour"]], dtype=dt, device=p.device)
    amin = f32(ALPHA_MIN)
    base = p[..., 0:3]
    r = rlo + f32(rhi - rlo) * p[..., 3]
    alpha = torch.clamp(r * r, min=amin)
    aspect = torch.sqrt(1.0 - amax * p[..., 4])
    ax = torch.clamp(alpha / aspect, min=amin)
    ay = torch.clamp(alpha * aspect, min=amin)
    phi = f32(PI) * p[..., 5]
    c, s = torch.cos(phi), torch.sin(phi)
    sx = (2.0 * p[..., 6] - 1.0) * slope
    sy = (2.0 * p[..., 7] - 1.0) * slope
    ni = torch.rsqrt(sx * sx + sy * sy + 1.0)
    nx, ny, nz = -sx * ni, -sy * ni, ni
    nt = nx * c + ny * s
    tx, ty, tz = c - nx * nt, s - ny * nt, -(nz * nt)
    ti = torch.rsqrt(torch.clamp(tx * tx + ty * ty + tz * tz, min=1e-12))
    tx, ty, tz = tx * ti, ty * ti, tz * ti
    bx, by, bz = ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx
    ls = torch.stack([_dot(light, tx, ty, tz), _dot(light, bx, by, bz), _dot(light, nx, ny, nz)], -1)
    vs = torch.stack([_dot(view, tx, ty, tz), _dot(view, bx, by, bz), _dot(view, nx, ny, nz)], -1)
    # base
    hs = half_vector(ls, vs)
    hl = _dot(hs, ls[..., 0], ls[..., 1], ls[..., 2])
    f5 = pow5(1.0 - hl)[..., None]
    fm = base + (1.0 - base) * f5
    spec = _ggx_dg(ls, vs, hs, ax, ay)[..., None]
    m = p[..., 8:9]
    under = (1.0 - m) * base * (f32(INV_PI) * ls[..., 2:3]) + m * fm * spec
    under = torch.where(((ls[..., 2] > 0.0) & (vs[..., 2] > 0.0))[..., None], under, torch.zeros_like(under))
    # coat
    w = p[..., 9]
    rc = torch.clamp(clo + f32(chi - clo) * p[..., 10] + smudge * p[..., 11], max=1.0)
    ac = torch.clamp(rc * rc, min=amin)
    e = f32(np.float32(ior - 1.0) / np.float32(ior + 1.0))
    f0c = f32(np.float32(e) * np.float32(e))
    h = half_vector(light, view)
    hlc = _dot(h, light[..., 0], light[..., 1], light[..., 2])
    coat = w * _schlick(f0c, hlc) * _ggx_dg(light, view, h, ac, ac)
    att = (1.0 - w * _schlick(f0c, light[..., 2])) * (1.0 - w * _schlick(f0c, view[..., 2]))
    layered = coat[..., None] + att[..., None] * under
    wd = (dust_w * p[..., 11])[..., None]
    out = (1.0 - wd) * layered + wd * dust_c * (f32(INV_PI) * light[..., 2:3])
    above = (light[..., 2] > 0.0) & (view[..., 2] > 0.0)
    return torch.where(above[..., None], out, torch.zeros_like(out))


# --- sampling the parameter textures as GL does ----------------------------------------------

def mip_chain(raw, levels: int) -> list[torch.Tensor]:
    """[N, N, C] -> levels mips, each a 2x2 box average (float32) of the one above; row 0 = v = 0."""
    x = torch.as_tensor(np.asarray(raw) if not isinstance(raw, torch.Tensor) else raw, dtype=torch.float32)
    if x.ndim != 3 or x.shape[0] != x.shape[1]:
        raise ValueError(f"mip_chain: expected [N, N, C], got {tuple(x.shape)}")
    if levels < 1 or x.shape[0] % (1 << (levels - 1)):
        raise ValueError(f"mip_chain: levels={levels} does not fit size {x.shape[0]}")
    out = [x]
    for _ in range(levels - 1):
        x = 0.25 * (x[0::2, 0::2] + x[1::2, 0::2] + x[0::2, 1::2] + x[1::2, 1::2])
        out.append(x)
    return out


def _bilinear(tex: torch.Tensor, uv: torch.Tensor) -> torch.Tensor:
    n_v, n_u, ch = tex.shape
    x = uv[..., 0] * n_u - 0.5
    y = uv[..., 1] * n_v - 0.5
    x0, y0 = torch.floor(x), torch.floor(y)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    i0, j0 = x0.long() % n_u, y0.long() % n_v
    i1, j1 = (i0 + 1) % n_u, (j0 + 1) % n_v
    flat = tex.reshape(-1, ch)
    g = lambda j, i: flat[j * n_u + i]
    return (g(j0, i0) * (1 - fx) + g(j0, i1) * fx) * (1 - fy) + (g(j1, i0) * (1 - fx) + g(j1, i1) * fx) * fy


def sample_parameters(textures, uv, level) -> torch.Tensor:
    """Parameters [..., C] at uv [..., 2] (wrap = repeat) on mip `level` (an int, a float or a
    [...] tensor; fractional levels blend the two neighbouring mips linearly, as GL's trilinear
    filtering does). `textures` is a mip chain (`mip_chain`) or one [N, N, C] level-0 array."""
    chain = list(textures) if isinstance(textures, (list, tuple)) else None
    if chain is None:
        base = torch.as_tensor(np.asarray(textures) if not isinstance(textures, torch.Tensor) else textures)
        chain = mip_chain(base, int(math.log2(base.shape[0])) + 1)
    uv = torch.as_tensor(uv, dtype=torch.float32)
    chain = [torch.as_tensor(t, dtype=torch.float32, device=uv.device) for t in chain]
    lv = torch.as_tensor(level, dtype=torch.float32, device=uv.device).expand(uv.shape[:-1])
    lv = torch.clamp(lv, 0.0, float(len(chain) - 1))
    lo = torch.floor(lv).long()
    frac = (lv - lo.to(torch.float32))[..., None]
    out = torch.zeros(*uv.shape[:-1], chain[0].shape[-1], dtype=torch.float32, device=uv.device)
    for k, tex in enumerate(chain):
        w = torch.where((lo == k)[..., None], 1.0 - frac, torch.zeros_like(frac)) \
            + torch.where((lo + 1 == k)[..., None], frac, torch.zeros_like(frac))
        sel = (w[..., 0] > 0)
        if sel.any():
            out[sel] += w[sel] * _bilinear(tex, uv[sel])
    return out
