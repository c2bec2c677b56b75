"""Torch side of sub-scene PRT (Learnt Transfer, Dhawal et al. 2022 §4.4): training one transfer network per region
on its cells plus the δ-margin, exporting the set as bundles, and the torch twin of the
region-selecting passes (shaders/lib/prt_regions.glsl through passes/sdf_prt.frag and the deferred
passes/mesh_prt.frag).

- ``region_transfer(region_set, nets, frames, p, n)``: the blended transfer [N, 16] (float32) at
  points p with normals n: regions.py ``blend_weights`` (the shader's weights, bit for bit), each
  network with its own frame (transfer_model.evaluate_transfer), summed in network order as the
  shader's prt_region_blend.
- ``render_regions(sdf, region_set, nets, frames, uniforms, w, h, sh, shading)``: twin.render
  with that transfer.
- ``render_gbuffer_regions(position, normal, region_set, nets, frames, uniforms, w, h, sh, shading)``:
  twin.render_gbuffer (the deferred mesh_prt pass, fed the GL G-buffer) with that transfer.
- ``load_region_set(bundles)``: (RegionSet, nets, frames) from the scene's bundles.
- ``train_regions(data, grid, table, delta, band, ...)``: one network per table entry.
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.models.graph import GraphModule
from inshade.techniques.prt import regions, twin
from inshade.techniques.prt.transfer_model import TransferFrame, evaluate_transfer, export_transfer
from inshade.techniques.prt.transfer_training import train_transfer


def load_region_set(bundles):
    """(RegionSet, nets in network order, frames in network order)."""
    rs = regions.read_region_set(bundles)
    nets = [GraphModule.from_bundle(bundles[pos]).eval() for pos in rs.order]
    frames = [TransferFrame.from_bundle(bundles[pos]) for pos in rs.order]
    return rs, nets, frames


def region_transfer(rs: regions.RegionSet, nets, frames, p: torch.Tensor, n: torch.Tensor) -> torch.Tensor:
    """The transfer the region pass computes at p [N, 3] with unit normals n [N, 3]."""
    p = p.float()
    n = n.float()
    ids, w = regions.blend_weights(rs.grid, np.asarray(rs.table), rs.band, p.numpy())
    out = torch.zeros(p.shape[0], 16)
    w = torch.from_numpy(w)
    ids = torch.from_numpy(ids)
    wr = torch.stack([torch.where(ids == r, w, torch.zeros_like(w)).sum(1) for r in range(rs.count)], 1)
    with torch.no_grad():
        for r in range(rs.count):               # network order, as prt_region_blend
            sel = (wr[:, r] > 0).nonzero().squeeze(1)
            if sel.numel() == 0:
                continue
            t = evaluate_transfer(nets[r], frames[r], p[sel], n[sel]).float()
            out[sel] = out[sel] + wr[sel, r, None] * t
    return out


def render_regions(sdf, rs, nets, frames, uniforms: dict, width: int, height: int, sh_coeffs,
                   shading: twin.PrtShading = twin.PrtShading()) -> dict:
    """The sdf_prt pass with a region set's transfer, in torch (see twin.compose for the result)."""
    view = twin.trace_view(sdf, uniforms, width, height)
    t = region_transfer(rs, nets, frames, view.p, view.n) if view.idx.numel() else torch.zeros(0, 16)
    return twin.compose(view, t, sh_coeffs, shading)


def render_gbuffer_regions(position, normal, rs, nets, frames, uniforms: dict, width: int, height: int, sh_coeffs,
                           shading: twin.PrtShading = twin.PrtShading()) -> dict:
    """The mesh_prt pass with a region set's transfer, in torch, fed the G-buffer the GL pass read
    (runtime/geometry.py MeshGBuffer.read(); as twin.render_gbuffer): the network is selected by the
    region of each visible surface point, exactly as for SDFs."""
    view = twin.gbuffer_view(position, normal, uniforms, width, height)
    t = region_transfer(rs, nets, frames, view.p, view.n) if view.idx.numel() else torch.zeros(0, 16)
    return twin.compose(view, t, sh_coeffs, shading)


def region_subset(data: dict, mask: np.ndarray, held_mask: np.ndarray | None, center, radius) -> dict:
    """A dataset dict restricted to ``mask`` (training points) and ``held_mask`` (held-out points)."""
    m = torch.from_numpy(np.asarray(mask, bool))
    out = {k: data[k][m] for k in ("position", "normal", "transfer")}
    if held_mask is not None and "heldout_transfer" in data:
        h = torch.from_numpy(np.asarray(held_mask, bool))
        if int(h.sum()) > 0:
            out.update({f"heldout_{k}": data[f"heldout_{k}"][h] for k in ("position", "normal", "transfer")})
    out["center"], out["radius"] = list(center), float(radius)
    return out


def train_regions(data: dict, grid: regions.RegionGrid, table, delta: float, band, *, width: int, layers: int,
                  steps: int, batch: int, lr: float, seed: int = 0, progress=None, checkpoint_dir=None,
                  pos_freqs: int = 6, normal_freqs: int = 4):
    """[(net, frame, metrics, record)] per network of ``table``: trained on the points of its cells
    plus ``delta`` around them, held out on the held-out points of its cells (no margin)."""
    from pathlib import Path

    table = np.asarray(table, np.int64)
    p = data["position"].numpy()
    hp = data["heldout_position"].numpy()
    held_cells = grid.cell_of(hp)
    out = []
    for r in range(int(table.max()) + 1):
        cells = np.nonzero(table == r)[0].tolist()
        mask = regions.margin_mask(grid, cells, p, delta)
        center, radius = regions.region_frame(grid, table, r, p, delta)
        held = np.isin(held_cells, cells)
        sub = region_subset(data, mask, held, center, radius)
        ckpt = Path(checkpoint_dir) / f"region-{r}.safetensors" if checkpoint_dir is not None else None
        # (checkpoint_dir names the width: a checkpoint of another configuration is refused)
        net, frame, metrics = train_transfer(sub, width=width, layers=layers, steps=steps, batch=batch, lr=lr,
                                             seed=seed + r, checkpoint=ckpt, progress=progress,
                                             pos_freqs=pos_freqs, normal_freqs=normal_freqs)
        metrics.update({"cells": cells, "train_points": int(mask.sum()), "heldout_points": int(held.sum())})
        out.append((net, frame, metrics, regions.region_record(grid, table, band, delta, r)))
    return out


def export_regions(trained, out_dir, provenance: dict | None = None, name: str = "atrium") -> list:
    """Writes ``out_dir/region_<i>/`` bundles (kind "prt", render.transfer + render.region)."""
    from pathlib import Path

    bundles = []
    for r, (net, frame, metrics, record) in enumerate(trained):
        b = net.export("prt", f"{name}_region_{r}", provenance=provenance or {}, metrics=metrics,
                       render={"transfer": frame.to_dict(), "region": record})
        b.save(Path(out_dir) / f"region_{r}")
        bundles.append(b)
    return bundles


__all__ = ["load_region_set", "region_transfer", "render_regions", "render_gbuffer_regions", "train_regions",
           "export_regions", "export_transfer"]
