"""The glTF 2.0 BRDF (spec appendix B with the KHR clearcoat, sheen, anisotropy and ior lobes), the
numpy twin of shaders/lib/gltf_brdf.glsl: the same operations in the same order, in float32.

- ``brdf(s, n, at, ab, nc, v, l)``: f(v, l) * |n.l| for a unit punctual light, [N, 3];
- ``environment(s, n, v, irradiance, radiance)``: the SH environment's share (split sum with Karis'
  analytic environment BRDF);
- ``Shading``: the material's values at the shaded points (arrays [N] or [N, 3]), as the GLSL struct;
  ``shading_from_material(material, n)`` fills it from a ``geometry.gltf.Material``'s factors (no
  textures), for trainers that need the material's reference values.

The trainers that learn a glTF material (neural_appearance --gltf) take their targets from here.
numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

F = np.float32
PI = F(3.14159265)
INV_PI = F(0.318309886)


@dataclass
class Shading:
    base_color: np.ndarray           # [N, 3] linear
    metallic: np.ndarray             # [N]
    roughness: np.ndarray            # [N]
    f0: np.ndarray                   # [N]
    clearcoat: np.ndarray            # [N]
    clearcoat_roughness: np.ndarray  # [N]
    sheen_color: np.ndarray          # [N, 3]
    sheen_roughness: np.ndarray      # [N]
    anisotropy: np.ndarray           # [N]

    def __post_init__(self):
        for k, v in vars(self).items():
            setattr(self, k, np.asarray(v, F))


def ior_f0(ior: float) -> float:
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def shading_from_material(material, count: int) -> Shading:
    """The factors of a ``geometry.gltf.Material`` (textures ignored) repeated ``count`` times."""
    rep = lambda x: np.full(count, x, F)  # noqa: E731
    col = lambda c: np.tile(np.asarray(c[:3], F), (count, 1))  # noqa: E731
    m = material
    return Shading(col(m.base_color), rep(m.metallic), rep(m.roughness), rep(ior_f0(m.ior)), rep(m.clearcoat),
                   rep(m.clearcoat_roughness), col(m.sheen_color), rep(m.sheen_roughness), rep(m.anisotropy_strength))


def dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def pow5(x):
    x2 = x * x
    return x2 * x2 * x


def max3(c):
    return np.maximum(np.maximum(c[..., 0], c[..., 1]), c[..., 2])


def mix(a, b, t):
    return a * (F(1) - t) + b * t


def d_ggx(nh, alpha):
    a2 = alpha * alpha
    f = (nh * nh) * (a2 - F(1)) + F(1)
    return a2 / (PI * f * f)


def v_ggx(nl, nv, alpha):
    a2 = alpha * alpha
    ggxv = nl * np.sqrt(nv * nv * (F(1) - a2) + a2)
    ggxl = nv * np.sqrt(nl * nl * (F(1) - a2) + a2)
    ggx = ggxv + ggxl
    return np.where(ggx > 0, F(0.5) / np.where(ggx > 0, ggx, F(1)), F(0))


def d_ggx_anisotropic(nh, th, bh, at, ab):
    a2 = at * ab
    f = np.stack([ab * th, at * bh, a2 * nh], -1)
    w2 = a2 / dot(f, f)
    return a2 * w2 * w2 * INV_PI


def v_ggx_anisotropic(nl, nv, bv, tv, tl, bl, at, ab):
    ggxv = nl * np.sqrt((at * tv) ** 2 + (ab * bv) ** 2 + nv * nv)
    ggxl = nv * np.sqrt((at * tl) ** 2 + (ab * bl) ** 2 + nl * nl)
    return np.clip(F(0.5) / (ggxv + ggxl), F(0), F(1))


def d_charlie(nh, r):
    inv_r = F(1) / r
    sin2h = F(1) - nh * nh
    return (F(2) + inv_r) * np.power(np.maximum(sin2h, F(0)), inv_r * F(0.5)) / (F(2) * PI)


def sheen_l(x, r):
    s = (F(1) - r) * (F(1) - r)
    a, b = mix(F(21.5473), F(25.3245), s), mix(F(3.82987), F(3.32435), s)
    c, d = mix(F(0.19823), F(0.16801), s), mix(F(-1.97760), F(-1.27393), s)
    e = mix(F(-4.32054), F(-4.85967), s)
    return a / (F(1) + b * np.power(x, c)) + d * x + e


def sheen_lambda(cos_theta, r):
    return np.where(np.abs(cos_theta) < F(0.5), np.exp(sheen_l(cos_theta, r)),
                    np.exp(F(2) * sheen_l(F(0.5), r) - sheen_l(F(1) - cos_theta, r)))


def v_charlie(nl, nv, r):
    nv = np.maximum(nv, F(1e-4))
    return F(1) / ((F(1) + sheen_lambda(nv, r) + sheen_lambda(nl, r)) * (F(4) * nv * nl))


def sheen_e(cos_theta, r):
    c = F(1) - cos_theta
    return F(0.65584461) * (c * c * c) + F(1) / (F(4.16526551) + np.exp(F(-7.97291361) * np.sqrt(r) + F(6.33516894)))


def brdf(s: Shading, n, at_dir, ab_dir, nc, v, l) -> np.ndarray:
    """f(v, l) * |n.l| [N, 3] float32 (lib/gltf_brdf.glsl gltf_brdf)."""
    n, at_dir, ab_dir, nc, v, l = (np.asarray(x, F) for x in (n, at_dir, ab_dir, nc, v, l))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        nl = np.clip(dot(n, l), F(0), F(1))
        nv = np.clip(dot(n, v), F(0), F(1))
        h = l + v
        h = h / np.sqrt(np.maximum(dot(h, h), F(1e-30)))[:, None]
        nh = np.clip(dot(n, h), F(0), F(1))
        vh = np.clip(dot(v, h), F(0), F(1))
        alpha = s.roughness * s.roughness
        at = mix(alpha, F(1), s.anisotropy * s.anisotropy)
        aniso = v_ggx_anisotropic(nl, nv, dot(ab_dir, v), dot(at_dir, v), dot(at_dir, l), dot(ab_dir, l), at, alpha) \
            * d_ggx_anisotropic(nh, dot(at_dir, h), dot(ab_dir, h), at, alpha)
        specular = np.where(s.anisotropy > 0, aniso, v_ggx(nl, nv, alpha) * d_ggx(nh, alpha))[:, None]
        schlick = pow5(F(1) - vh)[:, None]
        diffuse = s.base_color * INV_PI
        f_dielectric = s.f0[:, None] + (F(1) - s.f0[:, None]) * schlick
        f_metal = s.base_color + (F(1) - s.base_color) * schlick
        dielectric = diffuse + (specular - diffuse) * f_dielectric
        metal = f_metal * specular
        colour = (dielectric + (metal - dielectric) * s.metallic[:, None]) * nl[:, None]
        r = np.maximum(s.sheen_roughness, F(0.07))
        sheen = s.sheen_color * (d_charlie(nh, r) * v_charlie(nl, nv, r) * nl)[:, None]
        m3 = max3(s.sheen_color)
        scale = np.minimum(F(1) - m3 * sheen_e(nv, r), F(1) - m3 * sheen_e(nl, r))[:, None]
        colour = np.where((m3 > 0)[:, None], sheen + colour * scale, colour)
        cl, cv, ch = (np.clip(dot(nc, x), F(0), F(1)) for x in (l, v, h))
        ca = s.clearcoat_roughness * s.clearcoat_roughness
        coat = (v_ggx(cl, cv, ca) * d_ggx(ch, ca) * cl)[:, None]
        fc = (s.clearcoat * (F(0.04) + F(0.96) * pow5(F(1) - cv)))[:, None]
        colour = np.where((s.clearcoat > 0)[:, None], colour + (coat - colour) * fc, colour)
        out = np.where((nl <= 0)[:, None], F(0), colour)
    return out.astype(F)


def env_brdf(f0, roughness, nv):
    r = roughness[:, None] * np.array([-1.0, -0.0275, -0.572, 0.022], F) + np.array([1.0, 0.0425, 1.04, -0.04], F)
    a004 = np.minimum(r[:, 0] * r[:, 0], np.exp2(F(-9.28) * nv)) * r[:, 0] + r[:, 1]
    ab = np.stack([F(-1.04) * a004 + r[:, 2], F(1.04) * a004 + r[:, 3]], -1)
    return f0 * ab[:, :1] + ab[:, 1:]


def environment(s: Shading, n, v, irradiance, radiance) -> np.ndarray:
    """The environment's share [N, 3] (lib/gltf_brdf.glsl gltf_environment), before occlusion."""
    n, v, irradiance, radiance = (np.asarray(x, F) for x in (n, v, irradiance, radiance))
    nv = np.clip(dot(n, v), F(0), F(1))
    f0 = s.f0[:, None] + (s.base_color - s.f0[:, None]) * s.metallic[:, None]
    spec = env_brdf(f0, s.roughness, nv)
    diffuse = s.base_color * (F(1) - s.metallic[:, None]) * INV_PI
    colour = diffuse * irradiance * (F(1) - spec) + spec * radiance
    fc = (s.clearcoat * (F(0.04) + F(0.96) * pow5(F(1) - nv)))[:, None]
    return np.where((s.clearcoat > 0)[:, None], colour * (F(1) - fc) + radiance * fc, colour).astype(F)
