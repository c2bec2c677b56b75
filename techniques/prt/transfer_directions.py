"""Ray directions of the ground-truth transfer (techniques/prt/transfer.py) and their projection onto
the SH basis.

``y_k`` is ``inshade.sh.sh_basis`` (real orthonormal, index l*l + l + m), degree 4 (16 lanes).

Estimator: cosine-weighted hemisphere samples about n, so every ray counts and
``T_k ~ (pi / D) sum_d V_d y_k(w_d)`` (the clamped cosine is the sampling density, pdf cos/pi).
The D samples are a 2D Fibonacci lattice in the unit square, shifted per point by a random
Cranley-Patterson offset (mod 1), mapped to the disk (r = sqrt(u)) and lifted to the hemisphere
in an orthonormal frame about n. Stratified, unbiased, and decorrelated between neighbouring
points (no coherent banding for a network to learn). Unoccluded, the estimate is exact for band 0
(pi * 0.2821) and within ~1/D of ``lambert_bands`` x basis for the other bands.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from inshade.sh import sh_basis

from inshade.techniques.prt.transfer_inputs import TransferError

DEGREE = 4
GOLDEN = (1.0 + math.sqrt(5.0)) / 2.0


def _rotation(gen: torch.Generator) -> torch.Tensor:
    """A uniformly random rotation matrix (unit quaternion from 4 normals), float64."""
    q = torch.randn(4, generator=gen, dtype=torch.float64)
    w, x, y, z = (q / q.norm()).tolist()
    return torch.tensor([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]],
                        dtype=torch.float64)


def sphere_directions(n: int, seed: int = 0) -> torch.Tensor:
    """``n`` unit directions [n, 3] float32: a spherical Fibonacci set (equal-area, low
    discrepancy), randomly rotated by ``seed`` so repeated estimates are independent."""
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise TransferError(f"n: must be a positive int, got {n!r}")
    i = torch.arange(n, dtype=torch.float64) + 0.5
    z = 1.0 - 2.0 * i / n
    r = torch.sqrt((1.0 - z * z).clamp_min(0.0))
    phi = 2.0 * math.pi * torch.remainder(i / GOLDEN, 1.0)
    d = torch.stack([r * torch.cos(phi), r * torch.sin(phi), z], -1)
    d = d @ _rotation(torch.Generator().manual_seed(int(seed))).T
    return (d / d.norm(dim=-1, keepdim=True)).float()


def _lattice(n: int) -> torch.Tensor:
    """2D Fibonacci lattice [n, 2] in [0, 1)^2 (float64)."""
    i = torch.arange(n, dtype=torch.float64)
    return torch.stack([(i + 0.5) / n, torch.remainder(i / GOLDEN, 1.0)], -1)


def _frame(nrm: torch.Tensor):
    """Orthonormal tangents (t, b) of unit normals [N, 3] (Duff et al. 2017, branchless)."""
    x, y, z = nrm.unbind(-1)
    s = torch.where(z >= 0, torch.ones_like(z), -torch.ones_like(z))
    a = -1.0 / (s + z)
    b = x * y * a
    t = torch.stack([1.0 + s * x * x * a, s * b, -s * x], -1)
    bt = torch.stack([b, s + y * y * a, -y], -1)
    return t, bt


def hemisphere_directions(nrm: torch.Tensor, n_dirs: int, gen: torch.Generator) -> torch.Tensor:
    """Cosine-weighted stratified directions [N, n_dirs, 3] about unit normals [N, 3] (see the
    module docstring); float32."""
    lat = _lattice(n_dirs)[None]                                            # [1, D, 2]
    shift = torch.rand(nrm.shape[0], 1, 2, generator=gen, dtype=torch.float64)
    u = torch.remainder(lat + shift, 1.0)                                   # [N, D, 2]
    r = torch.sqrt(u[..., 0])
    phi = 2.0 * math.pi * u[..., 1]
    lx, ly = r * torch.cos(phi), r * torch.sin(phi)
    lz = torch.sqrt((1.0 - u[..., 0]).clamp_min(0.0))
    n64 = nrm.double()
    t, b = _frame(n64)
    d = lx[..., None] * t[:, None] + ly[..., None] * b[:, None] + lz[..., None] * n64[:, None]
    return d.float()


def project_visibility(visible: torch.Tensor, dirs: torch.Tensor) -> torch.Tensor:
    """(pi / D) sum_d V_d y_k(w_d): visible [N, D] bool, dirs [N, D, 3] -> [N, 16] float32."""
    y = sh_basis(dirs, DEGREE, torch)                                       # [N, D, 16]
    v = visible.to(y.dtype)
    return torch.einsum("nd,ndk->nk", v, y) * (math.pi / dirs.shape[1])


def chunk_generator(seed: int, start: int, per: int) -> torch.Generator:
    """The direction generator of an estimate over points ``start:``, chunked ``per`` points at a
    time: seeded by ``seed`` and advanced past the draws of the ``start`` points before (one
    ``hemisphere_directions`` draw per chunk, replayed chunk by chunk). A shard that starts on a
    chunk boundary thus draws exactly what the unsharded estimate draws for its points, whichever
    worker runs it, and computes the same chunks: sharded results are bit-identical to one run."""
    if isinstance(start, bool) or not isinstance(start, (int, np.integer)) or start < 0 or start % per:
        raise TransferError(f"start: must be a multiple of the chunk ({per} points), got {start!r}")
    gen = torch.Generator().manual_seed(int(seed))
    for i in range(0, int(start), per):
        torch.rand(min(per, start - i), 1, 2, generator=gen, dtype=torch.float64)
    return gen
