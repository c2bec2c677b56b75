"""The footprint-aware texture sampler of Differentiable Indirection (Datta et al. 2023 §4.2.2 and
supp. 1.4), the library every footprint-filtered DI texture shares: the emulated GL trilinear
sampler its targets come from (a box-filtered mip chain rounded to 8 bits, GL_LINEAR_MIPMAP_LINEAR
with GL_REPEAT), the paper's footprint distribution, the sizing and the trainable graph
(uv -> 2D primary, log2_footprint -> fixed lod node -> 1D footprint primary, both -> a 4D cascaded
array whose last axis is the LOD), and the tiled ground plane the footprint views draw
(shaders/lib/footprint.glsl).

Footprint convention: ``log2_footprint = log2(max(|duv/dx|, |duv/dy|))`` in uv units, GL's
isotropic max-axis LOD rule, so the GL mip level is ``log2_footprint + log2 N`` for an N x N texture.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from inshade.components.dense.torch_twin import Dense
from inshade.models import indirection as di
from inshade.models.graph import GraphModule
from inshade.models.texture_cascade import CompressionError

PRIMARY_CHANNELS = 3
LOD_OVERSAMPLE = 4            # N_p1 = 4 N_lod (paper)
P_LOD0 = 0.5                  # fraction of training samples in LOD 0 (paper)
MIN_SIZE = 8
N_CASCADED = 8                # N_c unless given

class FootprintError(CompressionError):
    """A texture or setting the footprint sampler cannot use; the message says what to change."""


# ---------------------------------------------------------------------------------------------
# the emulated GL trilinear sampler (training targets)

def levels(size: int) -> int:
    """L = log2 N: the index of the 1x1 mip level of an N x N (power-of-two) texture."""
    return int(round(math.log2(size)))


def mip_chain(image: torch.Tensor, round_bits: int | None = 8) -> list[torch.Tensor]:
    """[N, N, C] power-of-two -> [level 0 .. level L]: each level the 2x2 box mean of the one
    before (glGenerateMipmap's filter for power-of-two sizes), rounded to `round_bits` as an RGB8
    texture stores it (None: keep float)."""
    chain = [image.float()]
    q = float((1 << round_bits) - 1) if round_bits else None
    while chain[-1].shape[0] > 1:
        a = chain[-1]
        h, w, c = a.shape
        m = a.reshape(h // 2, 2, w // 2, 2, c).mean((1, 3))
        chain.append(torch.round(m * q) / q if q else m)
    return chain


def bilinear_repeat(image: torch.Tensor, uv: torch.Tensor) -> torch.Tensor:
    """GL_LINEAR with GL_REPEAT: texel (i, j) centred at ((j + 0.5) / W, (i + 0.5) / H), u along
    the width, v along the rows. image [H, W, C], uv [B, 2] (any real values)."""
    h, w = image.shape[:2]

    def axis(t, n):
        p = t * n - 0.5
        i0 = torch.floor(p)
        f = (p - i0)[:, None]
        i0 = i0.long()
        return torch.remainder(i0, n), torch.remainder(i0 + 1, n), f

    x0, x1, fx = axis(uv[:, 0], w)
    y0, y1, fy = axis(uv[:, 1], h)
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bot = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return top * (1 - fy) + bot * fy


def gl_lod(log2_footprint: torch.Tensor, size: int) -> torch.Tensor:
    """GL's lambda for a max-axis footprint of 2^log2_footprint uv units on an N x N texture,
    clamped to [0, L] (below 0 GL magnifies from level 0)."""
    return (log2_footprint + math.log2(size)).clamp(0.0, float(levels(size)))


def emulated_trilinear(chain: list[torch.Tensor], uv: torch.Tensor, log2_footprint: torch.Tensor) -> torch.Tensor:
    """GL_LINEAR_MIPMAP_LINEAR: bilinear in levels floor(lambda) and floor(lambda) + 1, mixed by
    the fraction. chain from `mip_chain`, uv [B, 2], log2_footprint [B]."""
    lam = gl_lod(log2_footprint.reshape(-1), chain[0].shape[0])
    top = len(chain) - 1
    l0 = torch.floor(lam).clamp(max=top).long()
    l1 = (l0 + 1).clamp(max=top)
    f = (lam - l0.float())[:, None]
    flat, offsets = _packed(chain)
    return (1 - f) * _bilinear_levels(flat, offsets, uv, l0, top) + f * _bilinear_levels(flat, offsets, uv, l1, top)


def _packed(chain):
    """All levels in one [sum n^2, C] table (one gather for any mix of levels) + level offsets."""
    flat = torch.cat([c.reshape(-1, c.shape[-1]) for c in chain])
    offsets = torch.tensor(np.cumsum([0] + [c.shape[0] * c.shape[1] for c in chain[:-1]]), device=flat.device)
    return flat, offsets


def _bilinear_levels(flat, offsets, uv, level, top):
    """`bilinear_repeat` of level `level[b]` (a square of side 2^(top - level)) for each sample."""
    n = torch.bitwise_left_shift(torch.ones_like(level), top - level)
    nf = n.float()

    def axis(t):
        p = t * nf - 0.5
        i0 = torch.floor(p)
        f = (p - i0)[:, None]
        i0 = i0.long()
        return torch.remainder(i0, n), torch.remainder(i0 + 1, n), f

    x0, x1, fx = axis(uv[:, 0])
    y0, y1, fy = axis(uv[:, 1])
    base = offsets[level]

    def at(y, x):
        return flat[base + y * n + x]

    top_row = at(y0, x0) * (1 - fx) + at(y0, x1) * fx
    bottom = at(y1, x0) * (1 - fx) + at(y1, x1) * fx
    return top_row * (1 - fy) + bottom * fy


def footprint_exponent(size: int, p: float = P_LOD0) -> float:
    """n = log_p(t), t = 1 / N: x = u^n puts a fraction p of the samples at footprints <= one
    texel (LOD 0); p = 0.5 gives n = log2 N (paper supp. Eq. 5-8)."""
    return math.log(1.0 / size) / math.log(p)


def sample_log2_footprint(n: int, size: int, gen: torch.Generator, device=None) -> torch.Tensor:
    """The paper's footprint distribution as log2 of the linear footprint in uv units:
    x = u^n  =>  log2 x = n log2 u. Drawn on `gen` (a CPU generator), computed on `device`."""
    u = torch.rand(n, generator=gen).to(device).clamp_min(1e-12)
    return footprint_exponent(size) * torch.log2(u)


def footprint_sampler(image: torch.Tensor, batch: int, seed: int = 0, chain=None):
    """Endless (x [B, 3] = (u, v, log2_footprint), target [B, C]) batches: stratified uv (one
    jittered sample per texel per epoch, as indirection.image_sampler), the paper's footprint
    distribution, targets from `emulated_trilinear`. image [N, N, C] with row 0 at v ~ 0.
    Random numbers come from a seeded CPU generator (the same on every device); the batches are
    computed on the device `chain` (default: `image`) lives on."""
    chain = mip_chain(image) if chain is None else chain
    device = chain[0].device
    size = image.shape[0]
    gen = torch.Generator().manual_seed(seed)
    n = size * size
    while True:
        order = torch.randperm(n, generator=gen)
        for start in range(0, n, batch):
            idx = order[start:start + batch].to(device)
            jitter = torch.rand(len(idx), 2, generator=gen).to(device)
            uv = torch.stack([(idx % size + jitter[:, 0]) / size, (idx // size + jitter[:, 1]) / size], -1)
            lf = sample_log2_footprint(len(idx), size, gen, device)
            yield torch.cat([uv, lf[:, None]], -1), emulated_trilinear(chain, uv, lf)


def held_out_set(image: torch.Tensor, n: int = 65536, seed: int = 12345, chain=None):
    """(x, target) from the training distribution with an independent seed (uniform uv), on the
    device of `chain` (default: of `image`)."""
    chain = mip_chain(image) if chain is None else chain
    gen = torch.Generator().manual_seed(seed)
    uv = torch.rand(n, 2, generator=gen).to(chain[0].device)
    lf = sample_log2_footprint(n, image.shape[0], gen, chain[0].device)
    return torch.cat([uv, lf[:, None]], -1), emulated_trilinear(chain, uv, lf)


def lod_sets(image: torch.Tensor, n: int = 8192, seed: int = 777, chain=None):
    """{level: (x, target)} at each integer GL level 0..L with uniform uv (PSNR per level)."""
    chain = mip_chain(image) if chain is None else chain
    size = image.shape[0]
    gen = torch.Generator().manual_seed(seed)
    out = {}
    for level in range(levels(size) + 1):
        uv = torch.rand(n, 2, generator=gen).to(chain[0].device)
        lf = torch.full((n,), float(level) - math.log2(size), device=chain[0].device)
        out[level] = (torch.cat([uv, lf[:, None]], -1), emulated_trilinear(chain, uv, lf))
    return out


# ---------------------------------------------------------------------------------------------
# sizing and the graph

@dataclass(frozen=True)
class Sizing:
    n_primary: int      # N_p0 (multiple of 8)
    n_footprint: int    # N_p1 = 4 N_lod
    n_cascaded: int     # N_c (multiple of 4)
    n_lod: int          # L + 1
    channels: int
    bytes: int          # cells: 3 N_p0^2 + N_p1 + k N_c^3 N_lod (paper supp. Eq. 4)
    budget: float

    @property
    def rho(self) -> float:
        return self.n_primary / self.n_cascaded


def texture_bytes(size: int, channels: int, mips: bool = True) -> int:
    """Bytes of an RGB8-style texture (k bytes a texel), with its full mip chain or base only."""
    total, s = 0, size
    while True:
        total += s * s * channels
        if s == 1 or not mips:
            return total
        s //= 2


def plan(size: int, channels: int, ratio: float, n_cascaded: int = N_CASCADED) -> Sizing:
    """Arrays for a budget of (N^2 k bytes) / ratio -- the ratio against the base level alone,
    as the paper counts it; the mip chain the sampler replaces adds another third. N_c is given
    (multiple of 4); N_p0 is the largest multiple of 8 that fits."""
    if size < MIN_SIZE or size & (size - 1):
        raise FootprintError(f"texture size {size}: must be a power of two >= {MIN_SIZE} (a full mip "
                             "chain halves to 1x1); pass --size 256")
    if not (isinstance(ratio, (int, float)) and math.isfinite(ratio) and ratio >= 1.0):
        raise FootprintError(f"ratio must be a number >= 1, got {ratio!r}")
    if n_cascaded < 4 or n_cascaded % 4:
        raise FootprintError(f"n_cascaded must be a multiple of 4 (>= 4), got {n_cascaded}")
    n_lod = levels(size) + 1
    n_fp = LOD_OVERSAMPLE * n_lod
    budget = size * size * channels / float(ratio)
    cascaded = n_cascaded ** 3 * n_lod * channels
    side = int(math.floor(math.sqrt(max(budget - cascaded - n_fp, 0) / PRIMARY_CHANNELS) / 8)) * 8
    if side < 8:
        need = PRIMARY_CHANNELS * 64 + n_fp + cascaded
        raise FootprintError(f"ratio {ratio:g} cannot be met for a {size}x{size}x{channels} texture with "
                             f"N_c = {n_cascaded}: the budget is {int(budget)} bytes and the smallest sampler "
                             f"(8x8x3 primary + {n_fp} footprint cells + {n_cascaded}^3x{n_lod}x{channels} "
                             f"cascaded) needs {need} (lower --ratio or --n-cascaded)")
    total = PRIMARY_CHANNELS * side * side + n_fp + cascaded
    return Sizing(side, n_fp, n_cascaded, n_lod, channels, total, budget)


def lod_node(size: int) -> Dense:
    """The fixed affine map log2_footprint -> x_f = (log2_footprint + log2 N) / L."""
    L = float(levels(size))
    d = Dense(1, 1, bias=True)
    with torch.no_grad():
        d.linear.weight.fill_(1.0 / L)
        d.linear.bias.fill_(math.log2(size) / L)
    for p in d.parameters():
        p.requires_grad_(False)
    return d


def sampler_graph(size: int, sizing: Sizing, mean) -> GraphModule:
    """The trainable core (no colour decode): output ``values`` = sRGB-encoded channels."""
    k = sizing.channels
    g = GraphModule([("uv", 2, "uv"), ("log2_footprint", 1, "log2_footprint_uv")])
    g.add("primary", di.make_array([sizing.n_primary] * 2, PRIMARY_CHANNELS, init="ramp", bits=8,
                                   nonlinearity="triangle"), "uv")
    g.add("lod", lod_node(size), "log2_footprint")
    g.add("lod_primary", di.make_array([sizing.n_footprint], 1, init="ramp", bits=8, nonlinearity="triangle"),
          "lod")
    g.add("cascaded", di.make_array([sizing.n_cascaded] * 3 + [sizing.n_lod], k, init="mean", bits=8,
                                    target=np.asarray(mean, np.float32).reshape(1, k)),
          ["primary", "lod_primary"])
    g.output("values", "cascaded", "generic")
    return g


def texture_tensor(image: np.ndarray) -> torch.Tensor:
    """Image orientation (row 0 = top) -> texture orientation (row 0 at v ~ 0, the bottom)."""
    return torch.from_numpy(np.ascontiguousarray(image[::-1], dtype=np.float32))


# A grazing view of the tiled ground plane (y = 0): eye 0.3 above it, looking 8 degrees down.
CAMERA = {"type": "fly", "position": [0.0, 0.3, 0.0], "yaw": 0.0, "pitch": -8.0, "fov_y": 50.0,
          "near": 0.05, "far": 100.0}
TILE = 1.0                    # world units per texture tile
EXTENT = 16.0                 # the plane is |x|, |z| <= EXTENT (a finite square: see lib/footprint.glsl)
