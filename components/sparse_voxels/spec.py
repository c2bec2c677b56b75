"""Sparse multi-scale voxel latents (Deep Appearance Prefiltering, Bako et al. 2022): the bundle-level spec."""
from __future__ import annotations

import numpy as np

from inshade.components.spec import ComponentError, ComponentSpec, Param, TensorSpec, pos_int, register
from inshade.components.unorm import TABLE_PRECISIONS, range_tensors, table_spec


VOXEL_MAX_SCALE = 9                 # 512^3 cells: the finest grid a 3D index texture may hold
VOXEL_MAX_COUNT = 1 << 24           # slots travel through torch as exact float32 integers
VOXEL_INDEXES = ("dense", "bricks")  # cell -> slot index layouts (codegen/voxel_index.py)
VOXEL_BRICKS = (2, 4, 8)


def _voxel_checks(p, d):
    if not 0 <= p["scale_min"] <= p["scale_max"]:
        raise ComponentError(f"scale_min: must be <= scale_max ({p['scale_max']}), got {p['scale_min']}")


def check_voxel_tables(cells: np.ndarray, spheres: np.ndarray, scale_min: int, scale_max: int,
                       latents: np.ndarray | None = None) -> None:
    """The voxel tables of a sparse_voxels node (torch_twin.py has the rules): cells
    [N, 4] (scale, i, j, k) in range and sorted by (scale, k, j, i) without repeats, spheres
    [N, 4] finite with radius >= 1e-6, latents [N, Z] finite. One ComponentError naming the field.
    The index grid built from these tables holds slot + 1 for slot < N by construction, so it
    cannot point past the latent table: N equal across the three tables is what is checked."""
    cells, spheres = np.asarray(cells), np.asarray(spheres)
    if cells.ndim != 2 or cells.shape[1] != 4 or cells.dtype.kind not in "iu":
        raise ComponentError(f"cells: must be integer [N, 4] (scale, i, j, k), got {cells.dtype} {list(cells.shape)}")
    n = cells.shape[0]
    if spheres.shape != (n, 4):
        raise ComponentError(f"spheres: shape {list(spheres.shape)}, expected {[n, 4]} (one per cell)")
    if latents is not None and (np.ndim(latents) != 2 or np.shape(latents)[0] != n):
        raise ComponentError(f"latents: shape {list(np.shape(latents))}, expected [{n}, Z] (one row per cell: "
                             f"the index grid points at rows 0..{n - 1})")
    c = cells.astype(np.int64)
    scale = c[:, 0]
    bad = np.flatnonzero((scale < scale_min) | (scale > scale_max))
    if bad.size:
        raise ComponentError(f"cells: row {bad[0]} has scale {scale[bad[0]]}, outside scale_min..scale_max "
                             f"{scale_min}..{scale_max}")
    bad = np.flatnonzero(((c[:, 1:] < 0) | (c[:, 1:] >= (1 << scale)[:, None])).any(1))
    if bad.size:
        r = bad[0]
        raise ComponentError(f"cells: row {r} (scale {scale[r]}, cell {c[r, 1:].tolist()}) is outside the "
                             f"{1 << scale[r]}^3 grid of its scale")
    if n > 1:
        key = ((scale << 30 | c[:, 3] << 20) | c[:, 2] << 10) | c[:, 1]    # (scale, k, j, i), each < 2^10
        step = np.diff(key)
        bad = np.flatnonzero(step <= 0)
        if bad.size:
            r = bad[0] + 1
            what = "repeats" if step[bad[0]] == 0 else "is out of order"
            raise ComponentError(f"cells: row {r} {c[r].tolist()} {what} (rows must be sorted by (scale, k, j, i), "
                                 f"without repeats)")
    if not np.isfinite(spheres).all():
        raise ComponentError(f"spheres: NaN or Inf at row {int(np.argwhere(~np.isfinite(spheres))[0, 0])}")
    bad = np.flatnonzero(spheres[:, 3] < 1e-6)
    if bad.size:
        raise ComponentError(f"spheres: row {bad[0]} has radius {float(spheres[bad[0], 3]):.9g} (must be >= 1e-6)")
    if latents is not None:
        lat = np.asarray(latents)
        finite = np.isfinite(lat)
        if not finite.all():
            r = int(np.argwhere(~finite)[0, 0])
            raise ComponentError(f"latents: {'NaN' if np.isnan(lat[r]).any() else 'Inf'} at row {r}")


register(ComponentSpec(
    "sparse_voxels",
    "sparse multi-scale voxel latents: input the slot (a voxel's row, uint or an exact float); "
    "output latents[slot] (channels lanes). cells [N, 4] (scale, i, j, k) sorted by (scale, k, j, i), "
    "spheres [N, 4] (centre, radius) of the geometry in each voxel; the GLSL side also emits the "
    "index grid (P_voxel_slot) and the spheres (P_voxel_sphere)",
    {"voxels": Param(int, check=pos_int(VOXEL_MAX_COUNT), doc=f"1..{VOXEL_MAX_COUNT}"),
     "channels": Param(int, check=lambda v: isinstance(v, int) and 4 <= v <= 64 and v % 4 == 0,
                       doc="a multiple of 4 from 4 to 64: Z/4 RGBA texels per voxel"),
     "scale_min": Param(int, check=lambda v: 0 <= v <= VOXEL_MAX_SCALE, doc=f"0..{VOXEL_MAX_SCALE}"),
     "scale_max": Param(int, check=lambda v: 0 <= v <= VOXEL_MAX_SCALE, doc=f"0..{VOXEL_MAX_SCALE}"),
     "precision": Param(str, "f16", lambda v: v in TABLE_PRECISIONS,
                        doc="f16, f32 or u8 (8-bit codes, value = offset + scale * q / 255 per channel)"),
     "index": Param(str, "dense", lambda v: v in VOXEL_INDEXES,
                    doc="dense (one 3D grid per scale) or bricks (a brick table + B^3 bricks where voxels are)"),
     "brick": Param(int, 4, lambda v: v in VOXEL_BRICKS, doc="the bricks index's side B: 2, 4 or 8")},
    out_dim=lambda p, d: p["channels"],
    tensors=lambda p, d: {
        "latents": table_spec((p["voxels"], p["channels"]), p["precision"]),
        "cells": TensorSpec((p["voxels"], 4), "uint32"),
        "spheres": TensorSpec((p["voxels"], 4), "float32"),
        **(range_tensors(p["channels"]) if p["precision"] == "u8" else {})},
    in_dim=lambda p, d: d == 1,
    category="lookup",
    extra_checks=_voxel_checks,
))
