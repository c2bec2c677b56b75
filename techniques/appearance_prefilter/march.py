"""The prefiltered march in torch: the twin of shaders/lib/dap_march.glsl and
passes/appearance_prefilter.frag, step for step and in float32 (the parity tests compare the two
images, >= 50 dB).

Per pixel (the pixel-centre ray of lib/camera's camera_ray; models/sdf.py camera_rays):
 1. dolly: ro = 0.5 + (ro - 0.5) * distance;
 2. unit box entry t0 >= 0 / exit t1 (slab test, zero direction components replaced by 1e-12);
    missed: the environment max(SH radiance(rd), 0), alpha 0;
 3. pixel width per unit distance px = 2 / (proj[1][1] * height) (= 2 tan(fov_y / 2) / height);
    L = clamp(-log2(t0 px) + 1, S_MIN, S_MAX) (the next finer scale than the footprint's: Nyquist);
    force_scale >= 0 replaces L; colour = mix(march(floor L), march(min(floor L + 1, S_MAX)), fract L);
 4. march(s): Amanatides-Woo DDA over the 2^s grid, at most 3 * 2^s + 3 cells, the next boundary
    of each axis recomputed from the integer cell ((cell + (step > 0)) / 2^s - ro) / rd, ties to x
    then y; every occupied cell (slot + 1 != 0, from the node's index: dense grid or bricks) with
    sphere (c, r) is shaded once:
    w = -rd, (t, b) = view_frame(w); d = (c - ro).rd, q = ro + rd d, wb = d px; beam mask texel
    (u, v) -> voxel mask coordinates x = ((q - c).t + o_u wb) / r, y = ((q - c).b + o_v wb) / r,
    o = (index + 0.5) / M - 0.5; NEAREST voxel texel floor((x + 1) M / 2), outside: alpha 0;
    decoder(slot, w, light in (t, b, w)) -> coverage, albedo, phase, slice;
    weight_j = (1 - Lambda_j) alpha_j; wgt = mean weight; Lambda_j += weight_j;
    radiance += wgt albedo (phase E_sun shadow + sum_b slice_b env(bin centre b));
    stop after a voxel once mean Lambda > 0.999;
 5. rgb = radiance + (1 - mean Lambda) env(rd), alpha = mean Lambda.
shadow (``shadows`` given) = shadows(c + sun_dir (r + sqrt(3) / 2^S_MAX)): the sun's shadow map at
the sphere centre moved toward the sun past the voxel's own caster cubes (dap_shadow); e.g.
runtime/shadow.py shadow_visibility_np(depth, matrices, points, 0, SHADOW_BIAS).
The march is vectorised over pixels: every pixel takes the same number of DDA steps, with masks
for those that left the grid or stopped.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from inshade.codegen.voxel_index import brick_index, index_grid
from inshade.models.sdf import camera_rays, sh_background_t, sh_radiance_t
from inshade.models.unit_box import unit_box

from . import VIEWS

STOP = 0.999          # mean coverage that ends a march
TINY = 1e-12          # |rd component| below this is replaced by it (a finite slab test)
SHADOW_BIAS = 1e-4    # dap_march.glsl DAP_SHADOW_BIAS (shadow-map depth units)


def f32(x) -> torch.Tensor:
    return torch.tensor(x, dtype=torch.float32)


def _dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def view_frame(w: torch.Tensor):
    """(t, b) [..., 3] of unit directions w [..., 3]: lib/dap_frame.glsl dap_view_frame (numpy twin:
    frame.py view_frame)."""
    pole = (w[..., 1].abs() > 0.999)[..., None]
    up = torch.where(pole, f32([1.0, 0.0, 0.0]), f32([0.0, 1.0, 0.0])).expand_as(w)
    t = torch.linalg.cross(up, w, dim=-1)
    t = t * torch.rsqrt(_dot(t, t))[..., None]
    return t, torch.linalg.cross(w, t, dim=-1)


def bin_centres(bins_theta: int, bins_phi: int) -> torch.Tensor:
    """Local bin centres [B, 3] (x = t, y = b, z = w) as lib/dap_frame.glsl dap_bin_centre computes them."""
    p = torch.arange(bins_theta).repeat_interleave(bins_phi).float()
    q = torch.arange(bins_phi).repeat(bins_theta).float()
    c = 1.0 - (2.0 * p + 1.0) / float(bins_theta)
    s = torch.sqrt((1.0 - c * c).clamp_min(0.0))
    phi = f32(6.28318531) * (q + 0.5) / float(bins_phi)
    return torch.stack([s * torch.cos(phi), s * torch.sin(phi), c], -1)


def _safe(rd):
    return torch.where(rd.abs() < TINY, f32(TINY), rd)


def _uniforms(camera, width, height):
    return camera if isinstance(camera, dict) else camera.uniforms(width, height)


def pixel_rays(camera, width: int, height: int, distance: float):
    """Dollied rays [H*W, 3] (image orientation) and px, the pixel width per unit distance."""
    u = _uniforms(camera, width, height)
    ro, rd = camera_rays(u, width, height)
    ro = 0.5 + (ro - 0.5) * f32(distance)
    p11 = f32(float(np.frombuffer(u["u_proj"], np.float32).reshape(4, 4)[1, 1]))
    px = f32(2.0) / (p11 * f32(float(height)))
    return ro, rd, px


def footprint_scale(t0, px, scale_min: int, scale_max: int, force_scale: int = -1):
    """L per ray (dap_footprint_scale)."""
    if force_scale >= 0:
        return torch.full_like(t0, float(min(max(force_scale, scale_min), scale_max)))
    s_f = -torch.log2((t0 * px).clamp_min(1e-30))
    return (s_f + 1.0).clamp(float(scale_min), float(scale_max))


def scale_map(camera, width, height, *, distance, scale_min, scale_max, force_scale=-1):
    """(L [H, W], hit [H, W]) as the `scale` view sees them (image orientation)."""
    ro, rd, px = pixel_rays(camera, width, height, distance)
    hit, t0, _ = unit_box(ro, rd)
    L = footprint_scale(t0, px, scale_min, scale_max, force_scale)
    return L.reshape(height, width).numpy(), hit.reshape(height, width).numpy()


class _Pixels:
    """What a pixel's marches share (DapPixel)."""

    def __init__(self, ro, rd, px, t0, sun_dir, sun_radiance, sh, bins_theta, bins_phi):
        self.ro, self.rd, self.px, self.t0 = ro, rd, px, t0
        w = -rd
        self.t, self.b = view_frame(w)
        sun = torch.as_tensor(np.asarray(sun_dir, np.float32))
        self.sun_dir = sun
        self.light = torch.stack([_dot(sun, self.t), _dot(sun, self.b), _dot(sun, w)], -1)
        self.sun = torch.as_tensor(np.broadcast_to(np.asarray(sun_radiance, np.float32), (3,)).copy())
        local = bin_centres(bins_theta, bins_phi)                        # [B, 3]
        world = (local[None, :, 0:1] * self.t[:, None] + local[None, :, 1:2] * self.b[:, None]
                 + local[None, :, 2:3] * w[:, None])                     # [P, B, 3]
        coeffs = torch.as_tensor(np.asarray(sh, np.float32))
        self.env = sh_radiance_t(coeffs, world.reshape(-1, 3)).clamp_min(0.0).reshape(*world.shape)


def _dense_lookup(cells, smin, smax, brick):
    """{scale: cell [K, 3] -> slot + 1}: the dense grid's texel (codegen/voxel_index.py)."""
    grids = {smax - i: torch.from_numpy(g[..., 0].astype(np.int64))
             for i, g in enumerate(index_grid(cells, smin, smax))}
    return {s: (lambda c, g=g: g[c[:, 2], c[:, 1], c[:, 0]]) for s, g in grids.items()}


def _brick_lookup(cells, smin, smax, brick):
    """{scale: cell [K, 3] -> slot + 1}: the brick table, then the brick (codegen/voxel_index.py)."""
    ix = brick_index(cells, smin, smax, brick)
    top, bricks = torch.from_numpy(ix.top.astype(np.int64)), torch.from_numpy(ix.bricks.astype(np.int64))
    lb, b = ix.log2b, ix.brick

    def lookup(c, s):
        m = max((1 << s) >> lb, 1)
        bc = c >> lb
        row = top[ix.offsets[s - smin] + (bc[:, 2] * m + bc[:, 1]) * m + bc[:, 0]]
        lc = c & (b - 1)
        u = ((row - 1).clamp_min(0) << (3 * lb)) + (lc[:, 2] * b + lc[:, 1]) * b + lc[:, 0]
        return torch.where(row > 0, bricks[u], 0)
    return {s: (lambda c, s=s: lookup(c, s)) for s in range(smin, smax + 1)}


# the cell -> slot lookups of sparse_voxels' ``index`` layouts
INDEX_LOOKUPS = {"dense": _dense_lookup, "bricks": _brick_lookup}


def _march(pix: _Pixels, idx, s, slot_of, spheres, decoder, mask, bins, shadows, finest):
    """march(s) for pixels idx: (radiance [K, 3], coverage [K], albedo [K, 3]); slot_of: cell [K, 3]
    -> slot + 1 at scale s."""
    k = idx.numel()
    n = 1 << s
    ro, rd, t0, px = pix.ro[idx], pix.rd[idx], pix.t0[idx], pix.px
    tv, bv, light, env = pix.t[idx], pix.b[idx], pix.light[idx], pix.env[idx]
    d = _safe(rd)
    inv = 1.0 / d
    step = torch.where(d > 0.0, 1, -1)
    ahead = (step > 0).long()
    cell = torch.floor((ro + rd * t0[:, None]) * float(n)).long().clamp(0, n - 1)
    texels = mask * mask
    lam = torch.zeros(k, texels)
    radiance, albedo_sum, mean = torch.zeros(k, 3), torch.zeros(k, 3), torch.zeros(k)
    active = torch.ones(k, dtype=torch.bool)
    o = (torch.arange(mask).float() + 0.5) / float(mask) - 0.5        # beam texel offsets
    half_m = 0.5 * float(mask)
    for _ in range(3 * n + 3):
        active &= ((cell >= 0) & (cell < n)).all(-1)
        if not bool(active.any()):
            break
        a = active.nonzero().squeeze(1)
        c = cell[a]
        slot = slot_of(c)
        occ = a[slot != 0]
        if occ.numel():
            row = slot[slot != 0] - 1
            sph = spheres[row]
            centre, r = sph[:, :3], sph[:, 3]
            x = torch.cat([row.float()[:, None], -rd[occ], light[occ]], -1)
            with torch.no_grad():
                y = decoder(x)
            cov = y[:, :texels]
            alb = y[:, texels:texels + 3]
            phase = y[:, texels + 3]
            slc = y[:, texels + 4:texels + 4 + bins]
            dist = _dot(centre - ro[occ], rd[occ])
            q = ro[occ] + rd[occ] * dist[:, None]
            wb = dist * px
            qt, qb = _dot(q - centre, tv[occ]), _dot(q - centre, bv[occ])
            inv_r = 1.0 / r
            tu = torch.floor(((qt[:, None] + o[None] * wb[:, None]) * inv_r[:, None] + 1.0) * half_m).long()
            tw = torch.floor(((qb[:, None] + o[None] * wb[:, None]) * inv_r[:, None] + 1.0) * half_m).long()
            tu2, tw2 = tu[:, None, :].expand(-1, mask, -1), tw[:, :, None].expand(-1, -1, mask)  # [K, v, u]
            inside = (tu2 >= 0) & (tu2 < mask) & (tw2 >= 0) & (tw2 < mask)
            lane = (tw2.clamp(0, mask - 1) * mask + tu2.clamp(0, mask - 1)).reshape(-1, texels)
            alpha = torch.where(inside.reshape(-1, texels), torch.gather(cov, 1, lane), f32(0.0))
            weight = (1.0 - lam[occ]) * alpha
            lam[occ] = lam[occ] + weight
            wgt = weight.sum(-1) / float(texels)
            if shadows is None:
                shadow = torch.ones(occ.numel())
            else:
                lift = r + f32(1.7320508) / float(1 << finest)
                shadow = torch.as_tensor(shadows(centre + pix.sun_dir * lift[:, None]), dtype=torch.float32)
            env_term = (slc[:, :, None] * env[occ]).sum(1)
            radiance[occ] += wgt[:, None] * alb * (phase[:, None] * pix.sun * shadow[:, None] + env_term)
            albedo_sum[occ] += wgt[:, None] * alb
            mean[occ] = lam[occ].sum(-1) / float(texels)
            active[occ[mean[occ] > STOP]] = False
        tn = ((cell + ahead).float() / float(n) - ro) * inv
        ax = torch.where((tn[:, 0] <= tn[:, 1]) & (tn[:, 0] <= tn[:, 2]), 0,
                         torch.where(tn[:, 1] <= tn[:, 2], 1, 2))
        cell = cell + torch.nn.functional.one_hot(ax, 3) * step
    return radiance, mean, albedo_sum


def render_prefiltered(decoder, cells, spheres, camera, width: int, height: int, *, distance: float = 1.0,
                       sun_dir=(0.0, 1.0, 0.0), sun_radiance=0.0, sh, force_scale: int = -1, mask: int, bins: int,
                       bins_theta: int | None = None, bins_phi: int | None = None, scale_min: int | None = None,
                       scale_max: int | None = None, shadows=None, view: str = "prefiltered", index: str = "dense",
                       brick: int = 4) -> np.ndarray:
    """The pass in torch: float32 [H, W, 4] in image orientation (row 0 = top).

    decoder: x [K, 7] = (slot row as an exact float, w, light in w's view frame) -> [K, M*M + 4 + B]
    (a GraphModule of the bundle); cells [N, 4] (scale, i, j, k); spheres [N, 4]; camera: a runtime
    camera or its uniforms(width, height); sh: radiance SH [K, 3] float32; sun_dir: unit direction
    towards the sun; sun_radiance: E_sun (scalar or RGB); bins_theta x bins_phi = bins (default
    bins_phi = 2 bins_theta); scale range default: the cells'; shadows: None, or a callable
    points [K, 3] (tensor) -> visibility [K] (module docstring); view: one of VIEWS; index, brick: the
    sparse_voxels node's cell -> slot index (the same slots either way)."""
    if view not in VIEWS:
        raise ValueError(f"view: {view!r} is not one of {list(VIEWS)}")
    cells = np.asarray(cells, np.int64)
    smin = int(cells[:, 0].min()) if scale_min is None else int(scale_min)
    smax = int(cells[:, 0].max()) if scale_max is None else int(scale_max)
    if bins_theta is None:
        bins_theta = round(math.sqrt(bins / 2))
        bins_phi = 2 * bins_theta
    if bins_theta * bins_phi != bins:
        raise ValueError(f"bins: {bins} is not bins_theta x bins_phi ({bins_theta} x {bins_phi})")
    spheres_t = torch.as_tensor(np.asarray(spheres, np.float32))
    if index not in INDEX_LOOKUPS:
        raise ValueError(f"index: {index!r} is not one of {list(INDEX_LOOKUPS)}")
    lookups = INDEX_LOOKUPS[index](cells, smin, smax, brick)
    ro, rd, px = pixel_rays(camera, width, height, distance)
    hit, t0, _ = unit_box(ro, rd)
    coeffs = torch.as_tensor(np.asarray(sh, np.float32))
    background = sh_background_t(coeffs, rd)
    out = torch.zeros(ro.shape[0], 4)
    if view == "prefiltered":
        out[:, :3] = background
    L = footprint_scale(t0, px, smin, smax, force_scale)
    x = (L - float(smin)) / float(max(smax - smin, 1))
    ramp = torch.stack([x, 1.0 - (2.0 * x - 1.0).abs(), 1.0 - x], -1)   # the scale view's colours
    idx = hit.nonzero().squeeze(1)
    if idx.numel():
        pix = _Pixels(ro[idx], rd[idx], px, t0[idx], sun_dir, sun_radiance, sh, bins_theta, bins_phi)
        Lh = L[idx]
        lo = torch.floor(Lh).long()
        f = Lh - lo.float()
        hi = torch.clamp(lo + 1, max=smax)
        res = {}
        for s in range(smin, smax + 1):
            for side, scales, keep in (("lo", lo, torch.ones_like(f, dtype=torch.bool)), ("hi", hi, f > 0.0)):
                sel = ((scales == s) & keep).nonzero().squeeze(1)
                if sel.numel():
                    r = _march(pix, sel, s, lookups[s], spheres_t, decoder, mask, bins, shadows, smax)
                    res.setdefault(side, [torch.zeros(idx.numel(), 3), torch.zeros(idx.numel()),
                                          torch.zeros(idx.numel(), 3)])
                    for acc, part in zip(res[side], r):
                        acc[sel] = part
        rad, cov, alb = res["lo"]
        if "hi" in res:
            blend = f > 0.0
            fb = f[:, None]
            rad = torch.where(blend[:, None], rad * (1.0 - fb) + res["hi"][0] * fb, rad)
            cov = torch.where(blend, cov * (1.0 - f) + res["hi"][1] * f, cov)
            alb = torch.where(blend[:, None], alb * (1.0 - fb) + res["hi"][2] * fb, alb)
        colour = {"prefiltered": rad + (1.0 - cov[:, None]) * background[idx],
                  "coverage": cov[:, None].expand(-1, 3), "albedo": alb, "scale": cov[:, None] * ramp[idx]}[view]
        out[idx] = torch.cat([colour, cov[:, None]], -1)
    return out.reshape(height, width, 4).numpy()


def bundle_args(bundle) -> dict:
    """render_prefiltered's bundle-side arguments from an appearance_prefilter bundle: the decoder
    (GraphModule), cells, spheres, mask, bins (and their layout) and the scale range."""
    from inshade.models import GraphModule

    from . import bins_layout

    node = next((n for n in bundle.nodes if n.type == "sparse_voxels"), None)
    if node is None:
        raise ValueError(f"bundle {bundle.name!r}: nodes: no sparse_voxels node (not an appearance_prefilter bundle)")
    mask, bins, bt, bp = bins_layout(bundle.meta.get("render") or {}, f"bundle {bundle.name!r}")
    return {"decoder": GraphModule.from_bundle(bundle), "cells": bundle.tensor(node, "cells"),
            "spheres": bundle.tensor(node, "spheres"), "mask": mask, "bins": bins, "bins_theta": bt,
            "bins_phi": bp, "scale_min": int(node.params["scale_min"]), "scale_max": int(node.params["scale_max"]),
            "index": node.params.get("index", "dense"), "brick": int(node.params.get("brick", 4))}
