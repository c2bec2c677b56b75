"""The appearance-prefiltering decoders (Bako et al. 2022) as one GraphModule,
so the bundle/codegen pipeline runs them unchanged.

Inputs: ``slot`` (1 uint lane: the voxel's row), ``view`` (3: w in world, from the voxel toward the
viewer), ``light`` (3: the light direction in w's view-local frame, frame.py). Outputs, in order:
``coverage`` (M*M, sigmoid), ``albedo`` (3), ``phase`` (1), ``slice`` (B).

Per voxel one latent row (component ``sparse_voxels``): [``latent`` learned floats | ``raw`` fixed
floats]. The paper's encoders see the raw data; an auto-decoder has none, so the raw data enter as
fixed lanes: the voxel's mean albedo over its views that hit (3) and T(mean phase) with the paper's
HDR range compression T(x) = log(1 + mu x) / log(1 + mu), mu = 2 (Eq. 18: inputs only, targets stay
linear). A gradient hook zeroes the raw lanes' gradient, so Adam never moves them.

As in the paper, each decoder has its own latent (there 256 coverage + 256 phase + 280 albedo
floats): the learned lanes are split coverage | albedo | phase (``latent_split``; 3/7, 1/7, 3/7 by
default), and each decoder's first dense layer reads only its own lanes (+ its raw lanes: albedo
the mean albedo, phase T(mean phase); coverage none) and the view encoding. The other columns of
that layer are zero and kept zero by a gradient mask, so the phase loss's noisy gradients never
reach the coverage latent (one table and one texture fetch loop still serve all three).
The shader finds a cell's row through the sparse_voxels ``bricks`` index, with the brick side
that takes the fewest bytes for these cells (codegen/voxel_index.py best_brick).

Decoders (width W, 3 residual blocks each, Xavier-normal weights, zero biases):

    trunk(x) = relu(R3(R2(R1(dense(x -> W)))))     R(h) = h + dense(relu(dense(relu(h))))  (node "add")
    coverage = sigmoid(dense(trunk_c([latent, PE(view)]) -> M*M))
    albedo   = dense(trunk_a([latent, PE(view)]) -> 3)
    slice    = dense(t -> B),  t = trunk_p([latent, PE(view)])
    phase    = dense(relu(dense(relu(dense([t, PE(light)] -> W)) -> W)) -> 1)

Phase and slice share one trunk with two heads: the slice is the phase function binned over light
directions, so the trunk must carry the whole function of the light anyway, and the point-query
head reads it out at PE(light); the slice head never sees the light (it is a function of the view
only, as the environment shading needs). PE = NeRF ``frequency`` encoding (view_freqs, light_freqs).

Losses (Eq. 19, unit weights): L2 coverage + 1(reference coverage of the view has a non-zero texel)
* [relative MSE phase (rho_hat - rho)^2 / (|rho_hat| + 0.01)^2 with the prediction detached
(Noise2Noise: no bias on the expectation; |.| keeps a negative prediction from zeroing the
denominator), L1 albedo, L2 slice with target P_b = phase_b * 4 pi / B].
"""
from __future__ import annotations

import math

import numpy as np
import torch

from inshade.codegen.voxel_index import best_brick
from inshade.components.dense.torch_twin import Dense
from inshade.components.elementwise.torch_twin import ReLU, Sigmoid
from inshade.components.encodings.torch_twin import Frequency
from inshade.components.feature_axis.torch_twin import Add
from inshade.components.sparse_voxels.torch_twin import SparseVoxels
from inshade.models import GraphModule

KIND = "appearance_prefilter"
MU = 2.0                 # range compression of the raw phase input (Eq. 18)
EPS = 0.01               # relative-MSE epsilon (Eq. 19)
RAW = 4                  # mean albedo (3) + T(mean phase)
OUTPUTS = ("coverage", "albedo", "phase", "slice")


def compress(x):
    """T(x) = log(1 + mu x) / log(1 + mu) (numpy or torch; x >= 0)."""
    lib = torch if torch.is_tensor(x) else np
    return lib.log1p(MU * x) / math.log1p(MU)


def raw_features(data: dict) -> np.ndarray:
    """[N, 4] float32: per voxel the mean albedo over the views whose coverage has a non-zero texel
    and T(mean phase) over those views and all bins (0 for a voxel no view hits)."""
    cov = np.asarray(data["coverage"], np.float32)
    hit = (cov.reshape(cov.shape[0], cov.shape[1], -1) > 0).any(-1).astype(np.float64)      # [N, V]
    count = np.maximum(hit.sum(1), 1.0)
    albedo = (np.asarray(data["albedo"], np.float64) * hit[..., None]).sum(1) / count[:, None]
    phase = (np.asarray(data["phase"], np.float64).mean(-1) * hit).sum(1) / count
    return np.concatenate([albedo, compress(phase)[:, None]], 1).astype(np.float32)


def _xavier(layer: Dense, gen: torch.Generator) -> Dense:
    w = layer.linear.weight
    std = math.sqrt(2.0 / (w.shape[0] + w.shape[1]))
    with torch.no_grad():
        w.copy_(torch.randn(w.shape, generator=gen) * std)
        if layer.linear.bias is not None:
            layer.linear.bias.zero_()
    return layer


def _dense(g: GraphModule, node: str, inputs, out: int, gen) -> str:
    inputs = [inputs] if isinstance(inputs, str) else inputs
    return g.add(node, _xavier(Dense(sum(g.dim(s) for s in inputs), out), gen), inputs)


def _trunk(g: GraphModule, name: str, inputs, width: int, blocks: int, gen, reads=None) -> str:
    """dense(in -> W) -> blocks x residual (relu, dense, relu, dense, add) -> relu; the last node id.
    ``reads``: bool [in] lanes the first layer may read (the others' weights zero, kept zero)."""
    h = _dense(g, f"{name}_in", inputs, width, gen)
    if reads is not None:
        _restrict(g.nodes[h], reads, gen)
    for k in range(blocks):
        a = g.add(f"{name}_r{k}a", ReLU(), h)
        a = _dense(g, f"{name}_r{k}d0", a, width, gen)
        a = g.add(f"{name}_r{k}b", ReLU(), a)
        a = _dense(g, f"{name}_r{k}d1", a, width, gen)
        h = g.add(f"{name}_r{k}", Add(), [h, a])
    return g.add(f"{name}_out", ReLU(), h)


def _restrict(layer: Dense, reads: np.ndarray, gen: torch.Generator) -> None:
    """Xavier-normal weights over the lanes the layer reads (fan-in = their count), zero elsewhere,
    and a gradient mask that keeps them zero."""
    w = layer.linear.weight
    keep = torch.from_numpy(np.asarray(reads, np.float32))[None, :]
    std = math.sqrt(2.0 / (w.shape[0] + int(keep.sum())))
    with torch.no_grad():
        w.copy_(torch.randn(w.shape, generator=gen) * std * keep)
    w.register_hook(lambda grad: grad * keep.to(grad.device))


def latent_split(latent: int) -> tuple[int, int, int]:
    """Learned latent lanes of (coverage, albedo, phase): 3/7, 1/7 and the rest."""
    cov = (3 * latent) // 7
    alb = max(latent // 7, 1 if latent >= 3 else 0)
    return cov, alb, latent - cov - alb


def _voxel_table(voxels, cells, spheres, latent: int, raw: int, gen) -> np.ndarray:
    """[N, latent + raw] initial latent rows: N(0, 0.01^2) learned lanes (DeepSDF's auto-decoder
    init), then the raw lanes: from `voxels` = the baked data dict (raw_features), an array [N, raw],
    or None / an int (zeros)."""
    n = int(np.asarray(cells).shape[0])
    if isinstance(voxels, dict):
        fixed = raw_features(voxels)[:, :raw]
    elif voxels is None or isinstance(voxels, (int, np.integer)):
        fixed = np.zeros((n, raw), np.float32)
    else:
        fixed = np.asarray(voxels, np.float32)
    if fixed.shape != (n, raw):
        raise ValueError(f"voxels: raw features of shape {list(fixed.shape)}, expected {[n, raw]} "
                         f"(one row of {raw} per cell)")
    learned = (torch.randn((n, latent), generator=gen) * 0.01).numpy()
    return np.concatenate([learned, fixed], 1).astype(np.float32)


def build_decoders(voxels, cells, spheres, *, latent: int = 28, raw: int = RAW, width: int = 32, blocks: int = 3,
                   mask: int = 8, bins: int = 32, view_freqs: int = 4, light_freqs: int = 4,
                   precision: str = "f16", scale_min: int | None = None, scale_max: int | None = None,
                   seed: int = 0) -> GraphModule:
    """The decoder graph (module docstring). ``voxels``: the baked data dict (raw lanes from it), an
    array [N, raw] of raw lanes, or None (zeros). ``latent + raw`` must be a multiple of 4 (4..64);
    the scale range defaults to the cells' own."""
    cells = np.asarray(cells)
    if (latent + raw) % 4 or not 4 <= latent + raw <= 64 or latent < 0 or raw < 0:
        raise ValueError(f"latent + raw: {latent} + {raw} must be a multiple of 4 from 4 to 64 (RGBA texels)")
    gen = torch.Generator().manual_seed(seed)
    table = _voxel_table(voxels, cells, spheres, latent, raw, gen)
    smin = int(cells[:, 0].min()) if scale_min is None else scale_min
    smax = int(cells[:, 0].max()) if scale_max is None else scale_max
    g = GraphModule([("slot", 1, "voxel_slot", "uint"), ("view", 3, "direction"), ("light", 3, "direction")])
    vox = SparseVoxels(cells, spheres, latent + raw, smin, smax, precision, latents=table, index="bricks",
                       brick=best_brick(cells, smin, smax))
    if raw:   # the raw lanes are data, not parameters: no gradient ever reaches them
        keep = torch.ones(latent + raw)
        keep[latent:] = 0.0
        vox.latents.register_hook(lambda grad: grad * keep.to(grad.device))
    g.add("vox", vox, "slot")
    g.add("venc", Frequency(view_freqs), "view")
    g.add("lenc", Frequency(light_freqs), "light")
    src = ["vox", "venc"]
    z, enc = latent + raw, g.dim("venc")
    n_cov, n_alb, _ = latent_split(latent)
    lanes = np.arange(z + enc)
    own = {"cov": lanes < n_cov,
           "alb": ((lanes >= n_cov) & (lanes < n_cov + n_alb)) | ((lanes >= latent) & (lanes < latent + min(raw, 3))),
           "ph": ((lanes >= n_cov + n_alb) & (lanes < latent)) | ((lanes >= latent + 3) & (lanes < z))}
    reads = {k: v | (lanes >= z) for k, v in own.items()}
    cov = _dense(g, "cov_head", _trunk(g, "cov", src, width, blocks, gen, reads["cov"]), mask * mask, gen)
    g.add("coverage", Sigmoid(), cov)
    _dense(g, "albedo", _trunk(g, "alb", src, width, blocks, gen, reads["alb"]), 3, gen)
    trunk = _trunk(g, "ph", src, width, blocks, gen, reads["ph"])
    _dense(g, "slice", trunk, bins, gen)
    h = g.add("phase_h0a", ReLU(), _dense(g, "phase_h0", [trunk, "lenc"], width, gen))
    h = g.add("phase_h1a", ReLU(), _dense(g, "phase_h1", h, width, gen))
    _dense(g, "phase", h, 1, gen)
    for name in OUTPUTS:
        g.output(name, name, f"dap_{name}")
    return g


def split_outputs(y: torch.Tensor, mask: int, bins: int) -> dict:
    """The concatenated outputs [..., M*M + 3 + 1 + B] as named tensors."""
    m2 = mask * mask
    return {"coverage": y[..., :m2], "albedo": y[..., m2:m2 + 3], "phase": y[..., m2 + 3],
            "slice": y[..., m2 + 4:m2 + 4 + bins]}


def losses(pred: dict, coverage, albedo, phase, phase_bins) -> dict:
    """Eq. 19 on a batch of (voxel, view) samples: coverage [n, M*M], albedo [n, 3], phase [n] (the
    point target at the queried light), phase_bins [n, B] (all bins of that view). Returns the terms
    and "total" (means over the batch; the masked terms over the samples whose coverage is not empty)."""
    bins = phase_bins.shape[-1]
    hit = (coverage > 0).any(-1).to(coverage.dtype)
    count = hit.sum().clamp_min(1.0)
    l_cov = (pred["coverage"] - coverage).square().mean()
    rel = (pred["phase"] - phase).square() / (pred["phase"].detach().abs() + EPS).square()
    l_phase = (rel * hit).sum() / count
    l_albedo = ((pred["albedo"] - albedo).abs().mean(-1) * hit).sum() / count
    target = phase_bins * (4.0 * math.pi / bins)
    l_slice = ((pred["slice"] - target).square().mean(-1) * hit).sum() / count
    return {"coverage": l_cov, "phase": l_phase, "albedo": l_albedo, "slice": l_slice,
            "total": l_cov + l_phase + l_albedo + l_slice}
