"""Sparse multi-scale voxel latents: the parity envelope's rule."""
from __future__ import annotations

from inshade.envelope_base import Site, rule


@rule("sparse_voxels")
def _sparse_voxels(s: Site):   # one latent row per slot, fetched as stored
    latents = s.table("latents")
    return latents.min(0), latents.max(0)
