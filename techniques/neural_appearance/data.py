"""What the neural material trains on (Real-Time Neural Appearance Models §3.1, §3.3, §3.4) and
the scene its asset is shown in:

- online samples: pyramid levels favouring fine ones, (light, view) pairs above the horizon (half
  from half/difference vectors, half cosine-weighted), light directions jittered in a cone;
- ``Targets``: the reference material (sources.py) prefiltered over the level's footprint and
  mollified over a cone of light directions;
- ``scene_description``: the asset's ``scene.json`` (the teapot, its lights and settings).
"""
from __future__ import annotations

import math

import numpy as np
import torch

from inshade.lit_settings import lit_settings
from inshade.models.latent_pyramid import bilinear_repeat
from inshade.models.proxy_lobe import cosine_direction
from inshade.scene.builder import (choice_setting, directional_light, display_modes, int_setting, mesh_shape, network,
                                    orbit, point_light, requires, scene_json, sky, texture)
from inshade.scene.labels import split_labels

from . import NETWORKS
from .scene_settings import pyramid_settings, sampling_settings


# ---------------------------------------------------------------------------------------------
# samples

def draw_levels(n: int, levels: int, scale: float, gen: torch.Generator) -> torch.Tensor:
    """Integer levels in [0, levels) from a truncated exponential favouring fine levels (§3.3)."""
    p = torch.exp(-torch.arange(levels, dtype=torch.float64) / scale)
    return torch.multinomial(p / p.sum(), n, replacement=True, generator=gen)


def _uniform_hemisphere(u1, u2):
    z = u1
    r, phi = torch.sqrt(torch.clamp(1 - z * z, min=0)), 2 * math.pi * u2
    return torch.stack([r * torch.cos(phi), r * torch.sin(phi), z], -1)


def half_difference_pairs(n: int, gen: torch.Generator):
    """(light, view) from uniformly sampled half and difference vectors (Rusinkiewicz 1998)."""
    u = torch.rand(n, 4, generator=gen, dtype=torch.float64)
    h = _uniform_hemisphere(u[:, 0], u[:, 1])
    d = _uniform_hemisphere(u[:, 2], u[:, 3])
    # frame around h: rotate (0, 0, 1) onto h
    t = torch.nn.functional.normalize(torch.cross(torch.tensor([0.0, 1.0, 0.0], dtype=h.dtype).expand_as(h), h,
                                                  dim=-1) + torch.tensor([1e-9, 0, 0], dtype=h.dtype), dim=-1)
    b = torch.cross(h, t, dim=-1)
    light = d[:, :1] * t + d[:, 1:2] * b + d[:, 2:] * h
    view = 2 * (light * h).sum(-1, keepdim=True) * h - light
    return light, view


def direction_pairs(n: int, gen: torch.Generator):
    """n (light, view) pairs above the horizon: half half/difference, half cosine x cosine."""
    lights, views, have = [], [], 0
    while have < n:
        m = 2 * (n - have) + 64
        l1, v1 = half_difference_pairs(m // 2, gen)
        u = torch.rand(m - m // 2, 4, generator=gen, dtype=torch.float64)
        l2, v2 = cosine_direction(u[:, 0], u[:, 1]), cosine_direction(u[:, 2], u[:, 3])
        light, view = torch.cat([l1, l2]), torch.cat([v1, v2])
        ok = (light[:, 2] > 1e-4) & (view[:, 2] > 1e-4)
        lights.append(light[ok])
        views.append(view[ok])
        have += int(ok.sum())
    light = torch.cat(lights)[:n]
    view = torch.cat(views)[:n]
    perm = torch.randperm(n, generator=gen)
    return light[perm].float(), view[perm].float()


def jitter_cone(d: torch.Tensor, angle: float, gen: torch.Generator) -> torch.Tensor:
    """Directions drawn uniformly in a cone of half-angle ``angle`` (radians) around d."""
    if angle <= 0:
        return d
    u = torch.rand(d.shape[0], 2, generator=gen).to(d.device)    # drawn on the CPU generator, used on d's device
    cos_max = math.cos(angle)
    z = 1 - u[:, 0] * (1 - cos_max)
    r, phi = torch.sqrt(torch.clamp(1 - z * z, min=0)), 2 * math.pi * u[:, 1]
    helper = torch.where(d[:, 2:].abs() < 0.9, torch.tensor([0.0, 0.0, 1.0], device=d.device),
                         torch.tensor([1.0, 0.0, 0.0], device=d.device))
    t = torch.nn.functional.normalize(torch.cross(helper.expand_as(d), d, dim=-1), dim=-1)
    b = torch.cross(d, t, dim=-1)
    return (r * torch.cos(phi))[:, None] * t + (r * torch.sin(phi))[:, None] * b + z[:, None] * d


class Targets:
    """Prefiltered, mollified reference values (§3.3, §3.4) from the material's level-0 textures;
    ``source`` evaluates the reference (sources.py: a layered or a glTF material)."""

    def __init__(self, source, raw: np.ndarray, device):
        self.source = source
        self.texels = torch.from_numpy(np.ascontiguousarray(raw)).float().to(device)
        self.size = raw.shape[0]

    def __call__(self, uv, level, light, view, samples: int, cone: float, gen) -> torch.Tensor:
        n = uv.shape[0]
        k = torch.where(level == 0, torch.ones_like(level), torch.full_like(level, samples))
        reps = int(k.max())
        total = torch.zeros(n, 3, device=uv.device)
        for s in range(reps):
            active = (k > s).nonzero(as_tuple=True)[0]
            sigma = (0.4 * 2.0 ** level[active].float() / self.size)[:, None]
            offset = torch.randn(active.numel(), 2, generator=gen).to(uv.device) * sigma
            offset = torch.where(level[active, None] == 0, torch.zeros_like(offset), offset)
            p = bilinear_repeat(self.texels, uv[active] + offset)
            l_jit = jitter_cone(light[active], cone, gen)
            total[active] += self.source.reflectance(p, l_jit, view[active])
        return total / k[:, None].float()


# ---------------------------------------------------------------------------------------------
# the asset's scene

def scene_description(mat, name: str) -> dict:
    """The asset's scene: the teapot under two lights and the studio environment."""
    from . import LIGHTING, VIEWS

    return scene_json(
        name, f"neural appearance: {mat.name} (latent pyramid + MLP decoder) on the Utah teapot",
        "passes/mesh_neural_appearance.frag", (384, 288),
        networks=[network(folder, prefix) for folder, prefix in NETWORKS],
        mesh=mesh_shape("teapot", segments=12),
        # the spout's tip inside a square picture too (the teapot is wider than tall)
        camera=orbit((0.35, 1.15, 0.0), 10.4, 30.0, -22.0, fov_y=35.0),
        bookmarks={
            "close-up": orbit((0.6, 1.6, 1.2), 3.0, 20.0, -20.0, fov_y=35.0),
            "far": orbit((0.0, 1.2, 0.0), 24.0, 30.0, -22.0, fov_y=35.0)},
        lights=[point_light((4.0, 6.0, 5.0), 60.0), directional_light((-0.6, 0.5, 0.3), 1.5)],
        environment=sky("studio"),
        display=display_modes(),
        labels=split_labels("reference", "neural"),
        settings={
            **lit_settings("studio"),
            "view": choice_setting("neural", VIEWS, "view (split: left reference, right neural)", uniform="u_na_view"),
            "decoder": choice_setting(32, [16, 32, 64], "decoder: 16 = 2x16, 32 = 2x32, 64 = 3x64",
                                      define="NA_DECODER"),
            "lighting": choice_setting("lights", LIGHTING, "lighting (environment: Monte Carlo, accumulated)",
                                       uniform="u_na_lighting"),
            **sampling_settings("BRDF sampling"),
            "lights": int_setting(2, 0, 4, "lights", uniform="u_light_count"),
            **pyramid_settings(),
            "latent_page": int_setting(0, 0, 2, "latent channels (page)", uniform="u_na_latent_page"),
        },
        textures=[texture(f"u_na_param{k}", f"param{k}.png", mipmaps=True, repeat=True) for k in range(3)],
        requires=requires(),
        notes="neural | reference: the 'view' setting; environment lighting accumulates (inshade render --spp N)",
    )
