"""The parity envelope's rules for encodings, lookup tables and periodic functions: each one bounds
its node's output from its input interval and reports what its input's discrepancy is amplified by
(the limits and their measurements: inshade/envelope.py)."""
from __future__ import annotations

import math

import numpy as np

from .components import grid_node_levels
from .envelope_base import GRID_GAIN, LOOKUP_GAIN, LOOKUP_GAIN_CHAINED, NOTE, TOL, Site, mag, rule, sin_range

# --- periodic --------------------------------------------------------------------------------


@rule("sin", "cos")
def _sin(s: Site):   # cos(t) = sin(t + pi/2)
    t, lo, hi = s.node.type, s.lo, s.hi
    w0 = s.params["omega0"]
    alo, ahi = np.minimum(w0 * lo, w0 * hi), np.maximum(w0 * lo, w0 * hi)
    s.walk.periodic_args[s.node.id] = [float(np.max(mag(alo, ahi)))]
    s.periodic(f"{t} argument |omega0 * x| (omega0 {w0:g})", s.walk.periodic_args[s.node.id][0])
    shift = math.pi / 2 if t == "cos" else 0.0
    return sin_range(alo + shift, ahi + shift)


@rule("frequency")
def _frequency(s: Site):
    n, p, lo, hi = s.node, s.params, s.lo, s.hi
    nf, d = p["n_freqs"], n.in_dim
    parts_lo, parts_hi = ([lo], [hi]) if p["include_input"] else ([], [])
    for fn in ("sin", "cos"):
        for k in range(nf):
            a = (2.0 ** k) * math.pi
            alo, ahi = a * lo, a * hi
            if fn == "cos":   # cos(t) = sin(t + pi/2)
                alo, ahi = alo + math.pi / 2, ahi + math.pi / 2
            slo, shi = sin_range(alo, ahi)
            parts_lo.append(slo)
            parts_hi.append(shi)
    bound = (2.0 ** (nf - 1)) * math.pi * float(np.max(mag(lo, hi)))
    s.walk.periodic_args[n.id] = [(2.0 ** k) * math.pi * float(np.max(mag(lo, hi))) for k in range(nf)]
    s.periodic(f"frequency argument 2^{nf - 1} pi |x| (n_freqs {nf})", bound)
    olo, ohi = np.concatenate(parts_lo), np.concatenate(parts_hi)
    assert olo.size == n.out_dim == d * (2 * nf + int(p["include_input"]))
    return olo, ohi


@rule("triangle_wave")
def _triangle_wave(s: Site):   # of an input: exact (power-of-two scale, mod 2), so only computed ones
    nf = s.params["n_freqs"]
    bound = (2.0 ** (nf - 1)) * float(np.max(mag(s.lo, s.hi)))
    s.periodic(f"triangle_wave argument 2^{nf - 1} |x| (n_freqs {nf})", bound, check_input=False)
    return np.zeros(s.node.out_dim), np.ones(s.node.out_dim)


@rule("spherical_harmonics")
def _spherical_harmonics(s: Site):
    deg = s.params["degree"]
    # real orthonormal SH: sum_m Y_lm^2 = (2l+1)/4pi on the unit sphere, so |Y_lm| <= that root
    m = np.concatenate([np.full(2 * l + 1, math.sqrt((2 * l + 1) / (4 * math.pi))) for l in range(deg)])
    return -m, m


@rule("one_blob")
def _one_blob(s: Site):   # bin masses of a unit blob
    p = s.params
    gain = 15.0 / 16.0 * p["n_bins"]
    if not s.src_exact and gain > LOOKUP_GAIN:
        s.warn(f"one_blob gain 15/16 n_bins (n_bins {p['n_bins']}, input computed)", gain, LOOKUP_GAIN,
               "an upstream discrepancy is multiplied by the blob's slope: measured ~2.9e-7 * gain "
               "(1.6e-5 at n_bins 64 after a 64-input dense)")
    return np.zeros(s.node.out_dim), np.ones(s.node.out_dim)


@rule("shading_frames")
def _shading_frames(s: Site):   # unit frame vectors dotted with unit directions
    return np.full(s.node.out_dim, -1.0), np.full(s.node.out_dim, 1.0)


@rule("proxy_params")
def _proxy_params(s: Site):
    """Output bounds of proxy_params (models/proxy_lobe.py): w in [0, 1], alpha in [alpha_min, 1],
    rho in [-0.99, 0.99], slopes mu = x (1 + |x| / 4) (monotone) of raw lanes 2, 3, 7, 8."""
    p, lo, hi = s.params, s.lo, s.hi
    olo = np.array([0.0, 0.0, 0.0, 0.0, p["alpha_min"], p["alpha_min"], -0.99, 0.0, 0.0])
    ohi = np.array([1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.99, 0.0, 0.0])
    if p["isotropic"]:
        ohi[6] = olo[6] = 0.0
    else:
        mu = lambda x: x * (1 + np.abs(x) / 4)  # noqa: E731
        for i in (2, 3, 7, 8):
            olo[i], ohi[i] = mu(lo[i]), mu(hi[i])
    return olo, ohi


# --- tables ----------------------------------------------------------------------------------

def _lut_cells(s: Site) -> np.ndarray:
    """The cells as the shader sees them, float64 [N_{d-1}, ..., N_0, C]."""
    cells = s.bundle.tensor(s.node, "cells")
    bits = s.params["bits"]
    if bits == 32:
        return cells.astype(np.float64)
    levels = float((1 << bits) - 1)
    return s.tensor("offset") + s.tensor("scale") * (cells.astype(np.float64) / levels)


@rule("lookup_array")
def _lookup_array(s: Site):
    n, lo, hi = s.node, s.lo, s.hi
    cells = _lut_cells(s)
    if np.any(lo < 0) or np.any(hi > 1):
        s.warn("lookup coordinate", float(np.max(np.maximum(-lo, hi - 1) + 1)), 1.0,
               "coordinates outside [0, 1] are clamped (same on both sides)", NOTE)
    if not s.src_exact:
        res = list(reversed(cells.shape[:-1]))    # N_0 .. N_{d-1}
        gain = 0.0
        for k, nk in enumerate(res):
            if nk > 1:
                axis = cells.ndim - 2 - k
                gain += (nk - 1) * float(np.abs(np.diff(cells, axis=axis)).max())
        gain /= max(1.0, float(np.abs(cells).max()))   # the rule is relative beyond 1
        chained = all(i in s.walk.lut_ids for i in n.inputs)
        limit = LOOKUP_GAIN_CHAINED if chained else LOOKUP_GAIN
        if gain > limit:
            src_kind = "another lookup array" if chained else "a computed value"
            s.warn(f"lookup gain sum_k (N_k - 1) max|cell step| / max(1, max|cell|) "
                   f"(coordinate from {src_kind})", gain, limit,
                   "an upstream coordinate discrepancy is multiplied by the gain: measured "
                   + ("~4.7e-8 * gain (shipped DI textures: 6.9e-6 at gain 147)" if chained
                      else "~2e-7 * gain scaled error (5e-5 at gain 252)"))
    s.walk.lut_ids.add(n.id)
    flat = cells.reshape(-1, cells.shape[-1])
    return flat.min(0), flat.max(0)


@rule("latent_pyramid")
def _latent_pyramid(s: Site):   # bilinear within a level: a convex combination of texels
    p = s.params
    levels = [s.bundle.tensor(s.node, f"level{k}").reshape(-1, p["channels"]) for k in range(p["levels"])]
    return np.min([lv.min(0) for lv in levels], 0), np.max([lv.max(0) for lv in levels], 0)


@rule("mesh_features")
def _mesh_features(s: Site):   # per level a barycentric (convex) blend of table rows
    b, n, p = s.bundle, s.node, s.params
    table = b.tensor(n, "table")
    if p["precision"] == "u8":   # value = offset + scale * q / 255 per lane
        table = b.tensor(n, "offset") + b.tensor(n, "scale") * (table / np.float32(255.0))
    return np.tile(table.min(0), p["levels"]), np.tile(table.max(0), p["levels"])


@rule("int_gather", keeps_exact=True)
def _int_gather(s: Site):   # table rows as stored (zeros past the table)
    table = s.tensor("table")
    olo = np.tile(np.minimum(table.min(0), 0.0), len(s.params["indices"]))
    ohi = np.tile(np.maximum(table.max(0), 0.0), len(s.params["indices"]))
    if not s.src_exact:
        s.warn("integer index from a computed value", float(np.max(mag(s.lo, s.hi))), math.nan,
               "exact on both sides, but a value one ulp across an integer picks another row", NOTE)
    return olo, ohi


@rule("sparse_voxels")
def _sparse_voxels(s: Site):   # one latent row per slot, fetched as stored
    latents = s.tensor("latents")
    return latents.min(0), latents.max(0)


# --- grid encodings ----------------------------------------------------------------------------

def _grid_steps(rows: np.ndarray, level, dims: int, wraps: bool) -> np.ndarray:
    """Per axis, the max |feature difference| between neighbouring vertices of a level: for a dense
    level row i against row (i + resolution^d) mod rows (every neighbour pair, the wrap-around and
    padding rows included); for a hashed level (or coordinates that wrap uint32) the features' spread."""
    if not level.dense or wraps:
        return np.full(dims, float((rows.max(0) - rows.min(0)).max()))
    return np.array([float(np.abs(rows - np.roll(rows, -level.resolution ** d, axis=0)).max()) for d in range(dims)])


@rule("hash_grid", "dense_grid")
def _grid(s: Site):
    """Per level a convex blend of the level's rows: output bounds per level, and what its position
    rounding amplifies."""
    n, lo, hi = s.node, s.lo, s.hi
    table = s.tensor("table")
    if np.any(lo < 0) or np.any(hi > 1):
        s.warn("grid coordinate", float(np.max(np.maximum(-lo, hi - 1) + 1)), 1.0,
               "coordinates outside [0, 1] wrap around the levels (the same on both sides)", NOTE)
    wraps = bool(np.any(lo < 0))          # negative vertices wrap uint32: no neighbour structure
    xmag = float(np.max(mag(lo, hi)))
    olo, ohi, fused, gain = [], [], (0.0, 0), (0.0, 0)
    for i, level in enumerate(grid_node_levels(n.type, n.params, n.in_dim)):
        rows = table[level.offset:level.offset + level.rows]
        olo.append(rows.min(0))
        ohi.append(rows.max(0))
        step = _grid_steps(rows, level, n.in_dim, wraps).sum() / max(1.0, float(np.abs(rows).max()))
        ulp = float(np.spacing(np.float32(float(level.scale) * xmag + 0.5)))
        fused, gain = max(fused, (ulp * step, i)), max(gain, (float(level.scale) * step, i))
    if fused[0] > TOL:
        s.warn(f"fused position: ulp(max p) * neighbour difference / max(1, max|feature|) (level {fused[1]})",
               fused[0], TOL, "where a driver fuses p = scale * x + 0.5 (tiny-cuda-nn's fmaf; llvmpipe and GLSL 4's "
               "precise do not) p moves by one ulp and the output by this much", NOTE)
    if not s.src_exact and gain[0] > GRID_GAIN:
        s.warn(f"grid gain sum_d scale * neighbour difference / max(1, max|feature|) (level {gain[1]}, "
               "coordinate computed)", gain[0], GRID_GAIN,
               "an upstream coordinate discrepancy is multiplied by the gain: measured ~8.2e-8 * gain at most "
               "(6.5e-5 at gain 1020)")
    return np.concatenate(olo), np.concatenate(ohi)
