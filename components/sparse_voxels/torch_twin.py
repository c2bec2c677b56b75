"""Sparse multi-scale voxel latents (Deep Appearance Prefiltering, Bako et al. 2022): the torch twin
(GLSL twin: emit.py).

One table over all scales: row (slot) r holds the voxel cells[r] = (scale, i, j, k), covering
[i, i+1] / 2^scale x [j, j+1] / 2^scale x [k, k+1] / 2^scale of the unit box, rows sorted by
(scale, k, j, i); spheres[r] = (cx, cy, cz, radius) bounds the geometry inside it; latents[r] is
its latent row (an auto-decoder embedding: trained directly, no encoder).

forward(x [..., 1] = slot as an exact float) -> latents[slot] [..., channels]. A slot outside
0..N-1 is a ValueError here (the GLSL side clamps it to that range: a shader cannot raise).
precision "f16": the latents are rounded to fp16 in forward (straight-through) and at export, so
the loss sees what an RGBA16F texture holds; "u8": offset + scale * q / 255 per channel, as the
shader decodes a unorm8 texel (models/unorm_lanes.py). cells and spheres are buffers: not trained.
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.components import check_node, check_voxel_tables, resolve_params
from inshade.models.latent_pyramid import _round_fp16
from inshade.components.unorm import decode
from inshade.models.registry import Component, register
from inshade.models.unorm_lanes import UnormLanes


@register
class SparseVoxels(UnormLanes, Component):
    type = "sparse_voxels"

    def __init__(self, cells, spheres, channels: int, scale_min: int, scale_max: int, precision: str = "f16",
                 latents=None, init_scale: float = 0.01, seed: int = 0, index: str = "dense", brick: int = 4):
        super().__init__()
        cells = np.asarray(cells.cpu().numpy() if torch.is_tensor(cells) else cells)
        spheres = np.asarray(spheres.cpu().numpy() if torch.is_tensor(spheres) else spheres, np.float32)
        self.channels, self.scale_min, self.scale_max = int(channels), int(scale_min), int(scale_max)
        self.precision = precision
        self.index, self.brick = index, brick   # the GLSL side's cell -> slot index (codegen/voxel_index.py)
        n = int(cells.shape[0]) if cells.ndim == 2 else 0
        check_node(self.type, resolve_params(self.type, self.params_with(n)), 1)
        if latents is None:
            gen = torch.Generator().manual_seed(seed)
            latents = torch.randn((n, self.channels), generator=gen) * init_scale
        latents = np.asarray(latents.detach().cpu().numpy() if torch.is_tensor(latents) else latents, np.float32)
        if latents.shape != (n, self.channels):
            raise ValueError(f"latents: shape {list(latents.shape)}, expected {[n, self.channels]}")
        check_voxel_tables(cells, spheres, self.scale_min, self.scale_max, latents)
        self.register_buffer("cells", torch.from_numpy(cells.astype(np.int64)))
        self.register_buffer("spheres", torch.from_numpy(spheres.copy()))
        self.latents = torch.nn.Parameter(torch.from_numpy(latents.copy()))
        if precision == "u8":
            self.calibrate()

    def unorm_values(self) -> torch.Tensor:
        return self.latents

    @property
    def voxels(self) -> int:
        return int(self.cells.shape[0])

    def params_with(self, voxels: int) -> dict:
        return {"voxels": voxels, "channels": self.channels, "scale_min": self.scale_min,
                "scale_max": self.scale_max, "precision": self.precision, "index": self.index, "brick": self.brick}

    def params(self):
        return self.params_with(self.voxels)

    def table(self) -> torch.Tensor:
        """The latents as the lookup sees them (fp16-rounded for precision f16, decoded codes for u8)."""
        if self.precision == "u8":
            return self.decode(self.unit(self.latents))
        return _round_fp16(self.latents) if self.precision == "f16" else self.latents

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        lead = x.shape[:-1]
        slot = x.reshape(-1, 1)[:, 0].detach()
        if slot.numel():
            bad = (slot < 0) | (slot > self.voxels - 1) | (slot != torch.floor(slot))
            if bool(bad.any()):
                raise ValueError(f"sparse_voxels: slot {float(slot[bad][0]):g} is not a row 0..{self.voxels - 1}")
        return self.table()[slot.long()].reshape(*lead, self.channels)

    def export_tensors(self):
        lat = self.latents.detach().cpu().float()
        if self.precision == "f16":
            lat = lat.half().float()
        stored = {"latents": self.codes(lat), **self.unorm_range()} if self.precision == "u8" else {
            "latents": np.ascontiguousarray(lat.numpy())}
        return {**stored,
                "cells": self.cells.cpu().numpy().astype(np.uint32),
                "spheres": np.ascontiguousarray(self.spheres.cpu().numpy().astype(np.float32))}

    @classmethod
    def from_node(cls, params, in_dim, tensors):
        u8 = params["precision"] == "u8"
        latents = decode(tensors["latents"], tensors["scale"], tensors["offset"]) if u8 else tensors["latents"]
        m = cls(tensors["cells"], tensors["spheres"], params["channels"], params["scale_min"],
                params["scale_max"], params["precision"], latents=latents,
                index=params.get("index", "dense"), brick=params.get("brick", 4))
        if u8:
            m.calibrate(tensors["scale"], tensors["offset"])
        return m
