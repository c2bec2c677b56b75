"""Learned shading frames (Real-Time Neural Appearance Models, Eq. 7): the torch twin (GLSL twin: emit.py).

A linear layer maps the latent z to N normals and N tangents: for frame k, rows 6k..6k+2 of
`weight`/`bias` give n_k and rows 6k+3..6k+5 give t_k. Each is normalised (n and t are not
orthogonalised, as in the paper), b_k = normalize(n_k x t_k). The output per frame is
(t.l, b.l, n.l, t.v, b.v, n.v): light and view in the frame, 6N lanes.
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.models.registry import Component, register

EPS = 1e-12   # normalize(x) = x * inversesqrt(max(dot(x, x), EPS)) on both sides: finite at x = 0


def safe_normalize(x: torch.Tensor) -> torch.Tensor:
    return x * torch.rsqrt(torch.clamp_min((x * x).sum(-1, keepdim=True), EPS))


@register
class ShadingFrames(Component):
    """forward(x [..., latent + 6] = [z, light, view]) -> [..., 6 * frames]."""

    type = "shading_frames"

    def __init__(self, latent: int = 8, frames: int = 2):
        super().__init__()
        self.latent, self.frames = int(latent), int(frames)
        self.linear = torch.nn.Linear(self.latent, 6 * self.frames)

    def params(self):
        return {"frames": self.frames, "latent": self.latent}

    def frames_of(self, z: torch.Tensor):
        """(n, t, b), each [..., frames, 3]."""
        nt = self.linear(z).reshape(*z.shape[:-1], self.frames, 2, 3)
        n, t = safe_normalize(nt[..., 0, :]), safe_normalize(nt[..., 1, :])
        return n, t, safe_normalize(torch.cross(n, t, dim=-1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        z, light, view = x[..., :self.latent], x[..., self.latent:self.latent + 3], x[..., self.latent + 3:]
        n, t, b = self.frames_of(z)
        basis = torch.stack([t, b, n], -2)                       # [..., frames, 3 (t b n), 3]
        dirs = torch.stack([light, view], -2)[..., None, :, :]   # [..., 1, 2 (l v), 3]
        local = (basis[..., None, :, :] * dirs[..., :, None, :]).sum(-1)   # [..., frames, 2, 3]
        return local.reshape(*x.shape[:-1], 6 * self.frames)

    def export_tensors(self):
        return {"weight": self.linear.weight.detach().cpu().float().numpy().copy(),
                "bias": self.linear.bias.detach().cpu().float().numpy().copy()}

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        m = cls(params["latent"], params["frames"])
        with torch.no_grad():
            m.linear.weight.copy_(torch.from_numpy(np.asarray(tensors["weight"])))
            m.linear.bias.copy_(torch.from_numpy(np.asarray(tensors["bias"])))
        return m
