"""di_pbr_set's pictures: the torch twin of the pass (lib/pbr_set.glsl shading and
passes/mesh_pbr_set.frag), fed the G-buffer the GL pass rasterised (the same operations in the
same order, float32), and the GL renders of an asset's scene it is checked against.

- ``shade``: lib/pbr_shading pbr_shade with metallic 0 on unpacked lanes (models/pbr_lanes.py ``unpack``).
- ``render_gbuffer``: the whole pass per view (DI network, uncompressed RGBA8 set, or the split).
- ``render_views``: the GL renders per view, with the G-buffer, camera uniforms and SH they used.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from inshade.models import brdf
from inshade.models.pbr_lanes import CHANNELS, dot3, unpack
from inshade.techniques.di_pbr_set import VIEWS

# (world position, intensity): lib/pbr_set.glsl PBR_SET_LIGHTS
LIGHTS = ((2.5, 3.0, 2.5, 16.0), (-3.0, 1.5, 1.5, 8.0), (0.5, -2.5, 3.0, 5.0), (-1.5, 3.5, -2.5, 6.0))
DEFAULT_LIGHTS = 2                           # point lights a scene starts with


def _normalise(x, floor=None):
    d = dot3(x, x)
    if floor is not None:
        d = torch.clamp(d, min=floor)
    return x * torch.rsqrt(d)[:, None]


def shade(s: dict, p, ng, tangent, rd, sh: torch.Tensor, light_count: int) -> torch.Tensor:
    """lib/pbr_shading pbr_shade with metallic 0: [N, 3] linear radiance (the same operations in the same order)."""
    from inshade.models.sdf import sh_irradiance_t

    t = _normalise(tangent[:, :3] - ng * dot3(ng, tangent[:, :3])[:, None], 1e-30)
    b = torch.cross(ng, t, dim=-1) * torch.where(tangent[:, 3] < 0.0, -1.0, 1.0)[:, None]
    nts = s["normal_ts"]
    n = _normalise(t * nts[:, 0:1] + b * nts[:, 1:2] + ng * nts[:, 2:3])
    ts = _normalise(t - n * dot3(n, t)[:, None], 1e-30)
    bs = torch.cross(n, ts, dim=-1)

    def local(w):
        return torch.stack([dot3(w, ts), dot3(w, bs), dot3(w, n)], -1)

    params = torch.zeros(len(p), len(brdf.PARAMS))
    params[:, brdf.PARAMS.index("roughness")] = s["roughness"]
    params[:, brdf.PARAMS.index("specular")] = 0.5
    params[:, brdf.PARAMS.index("sheen_tint")] = 0.5
    params[:, brdf.PARAMS.index("clearcoat_gloss")] = 1.0
    v = local(-rd)
    colour = s["albedo"] * (s["ao"] * np.float32(1.0 / math.pi))[:, None] * sh_irradiance_t(sh, n)
    for x, y, z, power in LIGHTS[:light_count]:
        d = torch.tensor([x, y, z], dtype=torch.float32) - p
        d2 = dot3(d, d)
        l = local(d * torch.rsqrt(d2)[:, None])
        colour = colour + brdf.disney(l, v, s["albedo"], params) * (power / d2)[:, None]
    return colour


def bilinear_repeat(image8: np.ndarray, uv: torch.Tensor) -> torch.Tensor:
    """GL LINEAR + REPEAT sampling of an RGBA8 image (row 0 = top, uv (0,0) bottom-left) at texel
    centres, float32 weights (the driver's are 8-bit fixed point: see tests for the bound)."""
    img = torch.from_numpy(np.ascontiguousarray(image8[::-1]).astype(np.float32) / 255.0)  # row 0 = v 0
    h, w = img.shape[:2]
    x, y = uv[:, 0] * w - 0.5, uv[:, 1] * h - 0.5
    x0, y0 = torch.floor(x), torch.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.long() % w, y0.long() % h
    x1, y1 = (x0 + 1) % w, (y0 + 1) % h
    top = img[y0, x0] * (1 - fx) + img[y0, x1] * fx
    bottom = img[y1, x0] * (1 - fx) + img[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def render_gbuffer(gbuffer, uniforms: dict, width: int, height: int, sh, *, graph=None, set8=None,
                   view: str = "di", light_count: int = DEFAULT_LIGHTS) -> np.ndarray:
    """The mesh_pbr_set pass in torch, fed the G-buffer (MeshGBuffer.read(): position, normal, uv,
    tangent in data orientation) the GL pass used: linear RGBA [H, W, 4], image orientation.
    ``graph``: the DI GraphModule (views "di"/"split"); ``set8``: the two RGBA8 images
    (views "uncompressed"/"split")."""
    from inshade.models.sdf import camera_rays, sh_background_t

    def flat(x):
        return torch.from_numpy(np.ascontiguousarray(np.asarray(x, np.float32)[::-1]).reshape(-1, 4))

    pos, nrm, uvs, tan = (flat(x) for x in gbuffer[:4])
    _, rd = camera_rays(uniforms, width, height)
    sh = torch.as_tensor(np.asarray(sh, np.float32))
    out = sh_background_t(sh, rd)
    hit = pos[:, 3] != 0.0
    idx = hit.nonzero().squeeze(1)
    if idx.numel():
        uv = uvs[idx, :2] - torch.floor(uvs[idx, :2])
        column = (idx % width).float() + 0.5
        compressed = {"di": column >= 0.0, "uncompressed": column < 0.0, "split": column >= 0.5 * width}[view]
        lanes = torch.zeros(len(idx), CHANNELS)
        if compressed.any():
            with torch.no_grad():
                lanes[compressed] = graph(uv[compressed])[:, :CHANNELS].float()
        if (~compressed).any():
            lanes[~compressed] = torch.cat([bilinear_repeat(set8[0], uv[~compressed]),
                                            bilinear_repeat(set8[1], uv[~compressed])], -1)
        with torch.no_grad():
            out[idx] = shade(unpack(lanes[:, :4], lanes[:, 4:]), pos[idx, :3], nrm[idx, :3], tan[idx], rd[idx], sh,
                             light_count)
    rgba = torch.cat([out, torch.ones(len(out), 1)], -1)
    return rgba.reshape(height, width, 4).numpy()


def render_views(folder, views=VIEWS, size: int | None = None, ctx=None) -> dict:
    """GL renders of the asset's scene per view: {view: linear RGBA [H, W, 4]} plus "_gbuffer"
    (the G-buffer read back) and "_uniforms"/"_sh" for the torch twin."""
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(folder)
    w, h = (size, size) if size else scene.size
    r = SceneRenderer(scene, ctx)
    out = {}
    try:
        cam = scene.make_camera()
        for view in views:
            r.set_setting("view", view)
            out[view] = read_rgba(r.render_network(cam, w, h)).copy()
        out["_gbuffer"] = tuple(a.copy() for a in r.gbuffer.read())
        out["_uniforms"] = cam.uniforms(w, h)
        out["_sh"] = r.environment_sh()
    finally:
        r.release()
    return out
