"""What an appearance-prefilter bundle costs in GPU memory (torch-free: the trainer's metrics and the
bench share it), as the generated code's resources hold it (components/sparse_voxels/emit.py):

- per voxel: its latent row at the bundle's precision (Z * 2 bytes for f16, Z * 4 for f32), its
  sphere (RGBA32F, 16 bytes) and its share of the cell -> slot index (the node's ``index``:
  ``dense``, one R32UI texel per cell of every scale, or ``bricks``, a brick table per scale plus
  R32UI bricks where voxels are; codegen/voxel_index.py), divided by the voxel count;
- the decoders: every dense weight and bias as fp32 (literals, a uniform block or a texture).

The dense grid's bytes are reported beside the index the bundle uses (``dense_index_bytes``).
The paper stores 797 fp32 floats per voxel (latents 792 + id + sphere), "just over 3 KB"; PAPER_BYTES.
"""
from __future__ import annotations

import numpy as np

from inshade.codegen.voxel_index import dense_bytes, index_bytes

PAPER_FLOATS_PER_VOXEL = 797
PAPER_BYTES_PER_VOXEL = 4 * PAPER_FLOATS_PER_VOXEL
SPHERE_BYTES = 16
INDEX_TEXEL_BYTES = 4


LATENT_VALUE_BYTES = {"f32": 4, "f16": 2, "u8": 1}   # the u8 form's per-channel range aside


def grid_texels(scale_min: int, scale_max: int) -> int:
    """Texels of the dense index grid's mip chain: (2^s)^3 for each scale s_min..s_max."""
    return sum(1 << (3 * s) for s in range(scale_min, scale_max + 1))


def memory_report(bundle) -> dict:
    node = next(n for n in bundle.nodes if n.type == "sparse_voxels")
    p = node.params
    n, z = p["voxels"], p["channels"]
    latent_bytes = z * LATENT_VALUE_BYTES[p["precision"]]
    kind = p.get("index", "dense")
    grid = index_bytes(np.asarray(bundle.tensor(node, "cells")), p)
    dense = dense_bytes(p["scale_min"], p["scale_max"])
    decoder = sum(int(a.size) * 4 for name, a in bundle.tensors.items() if name.endswith((".weight", ".bias")))
    per_voxel = latent_bytes + SPHERE_BYTES + grid / n
    voxel_total = n * (latent_bytes + SPHERE_BYTES) + grid
    return {"voxels": int(n), "latent_channels": int(z), "precision": p["precision"],
            "latent_bytes_per_voxel": int(latent_bytes), "sphere_bytes_per_voxel": SPHERE_BYTES,
            "index": kind, "brick": int(p.get("brick", 4)) if kind == "bricks" else None,
            "index_bytes": int(grid), "index_bytes_per_voxel": round(grid / n, 2),
            "dense_index_bytes": int(dense), "dense_index_bytes_per_voxel": round(dense / n, 2),
            "bytes_per_voxel": round(per_voxel, 2), "voxel_bytes": int(voxel_total), "decoder_bytes": int(decoder),
            "total_bytes": int(voxel_total + decoder), "paper_bytes_per_voxel": PAPER_BYTES_PER_VOXEL,
            "per_voxel_vs_paper": round(per_voxel / PAPER_BYTES_PER_VOXEL, 4)}
