"""Learned shading frames (Real-Time Neural Appearance Models, Eq. 7): the bundle-level spec."""
from __future__ import annotations

from inshade.components.spec import ComponentSpec, Param, TensorSpec, pos_int, register


register(ComponentSpec(
    "shading_frames",
    "learned shading frames (Eq. 7): input [z (latent), light (3), view (3)]; a linear layer "
    "[6N, latent] gives per frame k n_k = rows 6k..6k+2, t_k = rows 6k+3..6k+5; n, t normalised "
    "(not orthogonalised), b = normalize(n x t); output per frame (t.l, b.l, n.l, t.v, b.v, n.v)",
    {"frames": Param(int, 2, pos_int(8)), "latent": Param(int, 8, pos_int(64))},
    out_dim=lambda p, d: 6 * p["frames"],
    tensors=lambda p, d: {"weight": TensorSpec((6 * p["frames"], p["latent"]), "float32"),
                          "bias": TensorSpec((6 * p["frames"],), "float32")},
    in_dim=lambda p, d: d == p["latent"] + 6,
    category="layer",
))
