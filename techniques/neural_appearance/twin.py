"""Torch twin of passes/mesh_neural_appearance.frag (neural view, scene lights): the same G-buffer,
camera rays, level choice (lib/random's hashes via inshade/random.py), latent fetch, decoder and
light loop, in the same order — the whole-image parity reference for the shader (camera rays:
models/sdf.py ``camera_rays``, lib/camera's twin).

``render_lights(asset, gbuffer, camera, width, height, decoder=64, sample_index=0, light_count=4,
level_bias=0.0)`` takes ``MeshGBuffer.read()`` (data orientation: row 0 = GL y 0) and returns the
first sample's linear RGB [H, W, 3] and the covered mask, in the same data orientation.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from inshade.bundle import load
from inshade.models.graph import GraphModule
from inshade.models.sdf import camera_rays
from inshade.random import random_uniform

from . import DECODERS


def _normalize(x):
    return x / np.sqrt(np.maximum((x * x).sum(-1, keepdims=True), 1e-30))


def render_lights(asset, gbuffer, camera, width: int, height: int, *, lights, decoder: int = 64,
                  sample_index: int = 0, light_count: int = 4, level_bias: float = 0.0):
    """(linear RGB [H, W, 3] float32, covered mask [H, W]); ``lights``: the scene's lights."""
    asset = Path(asset)
    position, normal, uv, tangent, uv_grad = (np.asarray(g, np.float32) for g in gbuffer)
    covered = position[..., 3] != 0
    _, rd = camera_rays(camera.uniforms(width, height), width, height)   # image orientation
    rd = rd.numpy().reshape(height, width, 3)[::-1]
    n = normal[..., :3]
    t = _normalize(tangent[..., :3] - n * (n * tangent[..., :3]).sum(-1, keepdims=True))
    b = np.cross(n, t) * np.where(tangent[..., 3:] < 0, -1.0, 1.0)
    frame = np.stack([t, b, n], -2)                                   # rows t, b, n

    def local(w):
        return np.einsum("...ij,...j->...i", frame, w)

    view = local(-rd)
    latents = GraphModule.from_bundle(load(asset / "latents")).eval()
    node = next(nd for nd in load(asset / "latents").nodes if nd.type == "latent_pyramid")
    res, levels = int(node.params["resolution"]), int(node.params["levels"])
    dx, dy = uv_grad[..., :2] * res, uv_grad[..., 2:] * res
    area = np.abs(dx[..., 0] * dy[..., 1] - dx[..., 1] * dy[..., 0])
    lod = np.clip(0.5 * np.log2(np.maximum(area, 1e-20)) + level_bias, 0.0, levels - 1)
    py, px = np.mgrid[0:height, 0:width]
    xi = random_uniform(px, py, sample_index, 0, n=2)[..., 0]
    base = np.floor(lod)
    level = np.minimum(base + (xi < lod - base), levels - 1)

    dec = GraphModule.from_bundle(load(asset / [v for k, v in DECODERS.items() if k.endswith(str(decoder))][0])).eval()
    sel = np.nonzero(covered)
    with torch.no_grad():
        z = latents(torch.from_numpy(np.stack([uv[..., 0][sel], uv[..., 1][sel], level[sel]], -1).astype(np.float32)))
        v = torch.from_numpy(view[sel].astype(np.float32))
        total = torch.zeros(len(sel[0]), 3)
        for i, light in enumerate(lights[:light_count]):
            p = position[..., :3][sel]
            if light.get("type", "point") == "directional":
                d = np.asarray(light["direction"], np.float32)
                to_light = np.broadcast_to(d / np.linalg.norm(d), p.shape)
                scale = np.ones(len(p), np.float32)
            else:
                d = np.asarray(light["position"], np.float32) - p
                d2 = np.maximum((d * d).sum(-1), 1e-12)
                to_light, scale = d / np.sqrt(d2)[:, None], 1.0 / d2
            ld = np.einsum("nij,nj->ni", frame[sel], to_light).astype(np.float32)
            lt = torch.from_numpy(ld)
            f = torch.clamp(dec(torch.cat([z, lt, v], -1)), min=0)
            ok = ((lt[:, 2] > 0) & (v[:, 2] > 0)).float()[:, None]
            total += f * ok * float(light["intensity"]) * torch.from_numpy(np.asarray(scale, np.float32))[:, None]
    out = np.zeros((height, width, 3), np.float32)
    out[sel] = total.numpy()
    return out, covered
