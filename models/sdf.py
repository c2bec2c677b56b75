"""Torch reference for analytic SDF scenes (geometry/sdf.py descriptions) and for the sdf_diffuse
pass: the same operations, in the same order and float32, as the GLSL that codegen/sdf.py
generates and shaders/lib/sdf.glsl + shaders/passes/sdf_diffuse.frag.glsl run.

- ``SdfModule(scene)(p)`` -> distances [N]; ``.albedo(p)`` -> [N, 3]; batched over p [N, 3]
  float32, differentiable (autograd gives the analytic gradient where the field is smooth).
- ``normals(module, p)``: central differences with the scene's ``normal_eps``, the estimator the
  shader uses (not autograd: the renderer must match the shader, and the shader has no autograd).
  ``gradient(module, p)`` is the autograd alternative, for training losses.
- ``camera_rays`` / ``trace`` / ``render``: the torch reference renderer of the pass.
"""
from __future__ import annotations

import functools
import math

import numpy as np
import torch

from inshade.geometry.sdf import DEFAULT_ALBEDO, TIE_EPS, SdfScene, f32
from inshade.sh import background_bands, band_of, lambert_bands, sh_basis

INV_PI = f32(1.0 / math.pi)


def _length3(v):
    return torch.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1] + v[..., 2] * v[..., 2])


def _length2(x, y):
    return torch.sqrt(x * x + y * y)


@functools.lru_cache(maxsize=4096)
def _const(v, device=None):
    return torch.tensor(v, dtype=torch.float32, device=device)


def _c(v, like):
    # on the points' device (a CUDA trace, e.g. PRT transfer data), cached per device
    return _const(tuple(v), like.device)


class SdfModule(torch.nn.Module):
    """Distance (and albedo) of an ``SdfScene`` at points [N, 3] (float32)."""

    def __init__(self, scene: SdfScene):
        super().__init__()
        self.scene = scene

    def forward(self, p: torch.Tensor) -> torch.Tensor:
        return self._node(self.scene.root, p.float(), DEFAULT_ALBEDO, False)[0]

    def albedo(self, p: torch.Tensor) -> torch.Tensor:
        return self._node(self.scene.root, p.float(), DEFAULT_ALBEDO, True)[1]

    def evaluate(self, p: torch.Tensor):
        """(distance [N], albedo [N, 3])."""
        return self._node(self.scene.root, p.float(), DEFAULT_ALBEDO, True)

    # one method per node type, mirroring codegen/sdf.py's _Emitter ---------------------------------
    def _node(self, node, p, inherited, colour):
        col = node.albedo if node.albedo is not None else inherited
        return getattr(self, "_" + node.type)(node, p, col, colour)

    @staticmethod
    def _leaf(d, col, colour):
        return d, (_c(col, d).expand(d.shape[0], 3) if colour else None)

    def _sphere(self, node, p, col, colour):
        return self._leaf(_length3(p) - node.params["radius"], col, colour)

    @staticmethod
    def _box_d(p, size):
        q = p.abs() - _c(size, p)
        m = q.clamp_min(0.0)
        return _length3(m) + torch.clamp_max(torch.maximum(q[:, 0], torch.maximum(q[:, 1], q[:, 2])), 0.0)

    def _box(self, node, p, col, colour):
        return self._leaf(self._box_d(p, node.params["size"]), col, colour)

    def _round_box(self, node, p, col, colour):
        r = node.params["radius"]
        inner = tuple(f32(s - r) for s in node.params["size"])
        return self._leaf(self._box_d(p, inner) - r, col, colour)

    def _capsule(self, node, p, col, colour):
        a, b = np.float64(node.params["a"]), np.float64(node.params["b"])
        ba = tuple(f32(x) for x in b - a)
        inv_bb = f32(1.0 / float(np.dot(np.float64(ba), np.float64(ba))))
        pa = p - _c(node.params["a"], p)
        h = ((pa[:, 0] * ba[0] + pa[:, 1] * ba[1] + pa[:, 2] * ba[2]) * inv_bb).clamp(0.0, 1.0)
        return self._leaf(_length3(pa - _c(ba, p) * h[:, None]) - node.params["radius"], col, colour)

    def _torus(self, node, p, col, colour):
        qx = _length2(p[:, 0], p[:, 2]) - node.params["major"]
        return self._leaf(_length2(qx, p[:, 1]) - node.params["minor"], col, colour)

    def _cylinder(self, node, p, col, colour):
        wx = _length2(p[:, 0], p[:, 2]).abs() - node.params["radius"]
        wy = p[:, 1].abs() - node.params["height"]
        d = torch.clamp_max(torch.maximum(wx, wy), 0.0) + _length2(wx.clamp_min(0.0), wy.clamp_min(0.0))
        return self._leaf(d, col, colour)

    def _plane(self, node, p, col, colour):
        n = node.params["normal"]
        return self._leaf(p[:, 0] * n[0] + p[:, 1] * n[1] + p[:, 2] * n[2] - node.params["offset"], col, colour)

    def _fold(self, node, p, col, colour, combine):
        a, ca = self._node(node.children[0], p, col, colour)
        for child in node.children[1:]:
            b, cb = self._node(child, p, col, colour)
            a, ca = combine(node.params["k"], a, ca, b, cb)
        return a, ca

    def _union(self, node, p, col, colour):
        def combine(k, a, ca, b, cb):
            if k == 0:
                return torch.minimum(a, b), (torch.where((a <= b + TIE_EPS)[:, None], ca, cb) if colour else None)
            h = (0.5 + (b - a) * f32(0.5 / k)).clamp(0.0, 1.0)
            d = b + (a - b) * h - k * h * (1.0 - h)
            return d, (cb + (ca - cb) * h[:, None] if colour else None)
        return self._fold(node, p, col, colour, combine)

    def _subtract(self, node, p, col, colour):
        def combine(k, a, ca, b, cb):
            if k == 0:
                return torch.maximum(a, -b), ca
            h = (0.5 - (b + a) * f32(0.5 / k)).clamp(0.0, 1.0)
            return a + (-b - a) * h + k * h * (1.0 - h), ca
        return self._fold(node, p, col, colour, combine)

    def _intersect(self, node, p, col, colour):
        def combine(k, a, ca, b, cb):
            if k == 0:
                return torch.maximum(a, b), (torch.where((a >= b - TIE_EPS)[:, None], ca, cb) if colour else None)
            h = (0.5 - (b - a) * f32(0.5 / k)).clamp(0.0, 1.0)
            d = b + (a - b) * h + k * h * (1.0 - h)
            return d, (cb + (ca - cb) * h[:, None] if colour else None)
        return self._fold(node, p, col, colour, combine)

    def _transform(self, node, p, col, colour):
        prm = node.params
        t = prm["translate"]
        q = p - _c(t, p) if any(t) else p
        if prm["rotated"]:
            r = prm["inv_rotation"]
            q = torch.stack([q[:, 0] * row[0] + q[:, 1] * row[1] + q[:, 2] * row[2] for row in r], -1)
        s = prm["scale"]
        if s != 1.0:
            q = q * f32(1.0 / s)
        d, c = self._node(node.children[0], q, col, colour)
        if s != 1.0:
            d = d * s
        return d, c

    def _repeat(self, node, p, col, colour):
        cols = []
        for i, (s, n) in enumerate(zip(node.params["spacing"], node.params["count"])):
            x = p[:, i]
            if s > 0:
                x = x - s * torch.floor(x * f32(1.0 / s) + 0.5).clamp(-n, n)
            cols.append(x)
        return self._node(node.children[0], torch.stack(cols, -1), col, colour)

    def _repeat_polar(self, node, p, col, colour):
        prm = node.params
        a = torch.atan2(p[:, 2], p[:, 0])
        k = torch.floor(a * prm["inv_sector"] + 0.5)
        b = a - k * prm["sector"]
        r = _length2(p[:, 0], p[:, 2])
        q = torch.stack([r * torch.cos(b), p[:, 1], r * torch.sin(b)], -1)
        return self._node(node.children[0], q, col, colour)


def normals(sdf: SdfModule, p: torch.Tensor, eps: float | None = None) -> torch.Tensor:
    """Unit normals [N, 3] by central differences (6 evaluations, step ``normal_eps``), as
    ``sdf_normal`` in shaders/lib/sdf.glsl."""
    e = f32(sdf.scene.trace["normal_eps"] if eps is None else eps)
    g = []
    for i in range(3):
        off = torch.zeros(3, dtype=torch.float32, device=p.device)
        off[i] = e
        g.append(sdf(p + off) - sdf(p - off))
    g = torch.stack(g, -1)
    return g * (1.0 / _length3(g))[:, None]


def gradient(sdf: SdfModule, p: torch.Tensor) -> torch.Tensor:
    """Autograd gradient of the distance at p [N, 3] (not normalised)."""
    p = p.detach().requires_grad_(True)
    (g,) = torch.autograd.grad(sdf(p).sum(), p)
    return g


# the reference renderer --------------------------------------------------------------------------
def camera_rays(uniforms: dict, width: int, height: int):
    """Ray origins and unit directions [H*W, 3] in image orientation (row 0 = top), from the camera
    uniforms (``camera.uniforms(w, h)``: u_inv_view_proj bytes, u_eye) exactly as ``camera_ray`` (lib/camera.glsl):
    the pixel centre's far-plane point (ndc z = 1) unprojected, minus the eye, normalised."""
    inv = torch.from_numpy(np.frombuffer(uniforms["u_inv_view_proj"], np.float32).reshape(4, 4).copy())
    eye = torch.tensor(uniforms["u_eye"], dtype=torch.float32)
    ys = torch.arange(height - 1, -1, -1, dtype=torch.float32) + 0.5      # gl_FragCoord.y, top row first
    xs = torch.arange(width, dtype=torch.float32) + 0.5
    fy, fx = torch.meshgrid(ys, xs, indexing="ij")
    ndc_x = fx.reshape(-1) * f32(2.0 / width) - 1.0
    ndc_y = fy.reshape(-1) * f32(2.0 / height) - 1.0
    # GLSL: inv * vec4(x, y, 1, 1) with column j = row j of the row-vector matrix -> v @ inv
    clip = torch.stack([ndc_x, ndc_y, torch.ones_like(ndc_x), torch.ones_like(ndc_x)], -1)
    w = clip[:, 0:1] * inv[0] + clip[:, 1:2] * inv[1] + clip[:, 2:3] * inv[2] + clip[:, 3:4] * inv[3]
    far = w[:, :3] * (1.0 / w[:, 3:4])
    d = far - eye
    d = d / _length3(d)[:, None]
    return eye.expand_as(d).contiguous(), d


def trace(sdf: SdfModule, ro: torch.Tensor, rd: torch.Tensor):
    """Sphere tracing as ``sdf_hit``: (hit [N] bool, t [N]). Enter the bound sphere, step
    d * step_scale, stop when d < hit_eps (hit), t > t_exit or after max_steps."""
    tr, scene = sdf.scene.trace, sdf.scene
    oc = ro - torch.tensor(scene.center, dtype=torch.float32)
    b = oc[:, 0] * rd[:, 0] + oc[:, 1] * rd[:, 1] + oc[:, 2] * rd[:, 2]
    c = oc[:, 0] * oc[:, 0] + oc[:, 1] * oc[:, 1] + oc[:, 2] * oc[:, 2] - f32(scene.radius * scene.radius)
    h = b * b - c
    inside = h >= 0.0
    sq = torch.sqrt(h.clamp_min(0.0))
    t0 = (-b - sq).clamp_min(0.0)
    t1 = -b + sq
    active = inside & (t1 >= 0.0)
    t = t0.clone()
    hit = torch.zeros_like(active)
    with torch.no_grad():
        for _ in range(int(tr["max_steps"])):
            if not active.any():
                break
            idx = active.nonzero().squeeze(1)
            p = ro[idx] + rd[idx] * t[idx, None]
            d = sdf(p)
            now_hit = d < tr["hit_eps"]
            hit[idx[now_hit]] = True
            tn = t[idx] + d * tr["step_scale"]
            go = ~now_hit
            t[idx[go]] = tn[go]
            still = go & (tn <= t1[idx])
            active[idx] = still
    return hit, t


def sh_convolved_t(coeffs: torch.Tensor, d: torch.Tensor, bands) -> torch.Tensor:
    """``sh_convolved`` of lib/spherical_harmonics.glsl in float32 (sequential accumulation):
    sum bands[l] c_lm Y_lm(d) with per-band factors ``bands`` [degree]."""
    degree = int(round(math.sqrt(coeffs.shape[0])))
    y = sh_basis(d, degree, torch)
    a = np.asarray(bands, np.float32)[band_of(degree)]
    acc = torch.zeros(d.shape[0], 3)
    for i in range(coeffs.shape[0]):
        acc = acc + coeffs[i] * (float(a[i]) * y[:, i:i + 1])
    return acc


def sh_irradiance_t(coeffs: torch.Tensor, n: torch.Tensor) -> torch.Tensor:
    """``sh_irradiance`` of lib/spherical_harmonics.glsl in float32 (sequential accumulation)."""
    return sh_convolved_t(coeffs, n, lambert_bands(int(round(math.sqrt(coeffs.shape[0])))))


def sh_radiance_t(coeffs: torch.Tensor, d: torch.Tensor) -> torch.Tensor:
    degree = int(round(math.sqrt(coeffs.shape[0])))
    y = sh_basis(d, degree, torch)
    acc = torch.zeros(d.shape[0], 3)
    for i in range(coeffs.shape[0]):
        acc = acc + coeffs[i] * y[:, i:i + 1]
    return acc


def sh_background_t(coeffs: torch.Tensor, d: torch.Tensor) -> torch.Tensor:
    """``sh_background`` of lib/spherical_harmonics.glsl: the environment as a background (Hann-
    windowed bands, clamped at 0), float32, sequential accumulation."""
    bands = background_bands(int(round(math.sqrt(coeffs.shape[0]))))
    return sh_convolved_t(coeffs, d, bands).clamp_min(0.0)


def render(scene, uniforms: dict, width: int, height: int, sh_coeffs) -> dict:
    """The sdf_diffuse pass in torch. ``scene``: an SdfScene, or an SDF module with ``.scene`` and
    ``.albedo`` (models/network_sdf.py NetworkSdfModule); ``uniforms``: the camera's (``camera.uniforms(w, h)``);
    ``sh_coeffs``: float32 [K, 3] radiance SH (``codegen.sdf.environment_sh``). Returns
    {"rgba": [H, W, 4] linear float32 (alpha 1), "hit": [H, W] bool, "t": [H, W]}:
    hit -> albedo * sh_irradiance(n) / pi, miss -> sh_background(rd) (the environment)."""
    sdf = scene if isinstance(scene, torch.nn.Module) else SdfModule(scene)
    coeffs = torch.as_tensor(np.asarray(sh_coeffs, np.float32))
    ro, rd = camera_rays(uniforms, width, height)
    hit, t = trace(sdf, ro, rd)
    out = sh_background_t(coeffs, rd)
    with torch.no_grad():
        if hit.any():
            idx = hit.nonzero().squeeze(1)
            p = ro[idx] + rd[idx] * t[idx, None]
            n = normals(sdf, p)
            alb = sdf.albedo(p)
            out[idx] = alb * sh_irradiance_t(coeffs, n) * INV_PI
    rgba = torch.cat([out, torch.ones(out.shape[0], 1)], -1)
    return {"rgba": rgba.reshape(height, width, 4).numpy(), "hit": hit.reshape(height, width).numpy(),
            "t": t.reshape(height, width).numpy()}
