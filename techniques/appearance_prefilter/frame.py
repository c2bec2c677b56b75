"""The view-local frame and the direction samplings of the per-voxel data (numpy twin of
shaders/lib/dap_frame.glsl; the torch side uses the same formulas).

``view_frame(w)``: w is a unit direction from the voxel TOWARD the viewer (w = -ray_dir).
up = (0, 1, 0) unless |w.y| > 0.999, then up = (1, 0, 0); t = normalize(cross(up, w)); b = cross(w, t).
Local coordinates of a direction d are (d.t, d.b, d.w).

Phase bins: B = BT x BP equal-area bins of the local sphere: bin (p, q) holds local
cos(theta) in [1 - 2(p+1)/BT, 1 - 2p/BT] (theta measured from w) and phi in
[2 pi q/BP, 2 pi (q+1)/BP] (from t toward b); index p*BP + q; solid angle 4 pi / B each.

numpy only.
"""
from __future__ import annotations

import math

import numpy as np

POLE = 0.999   # |w.y| above this switches the up vector to +x (cross(up, w) would vanish)


def view_frame(w):
    """(t, b, w) unit vectors [..., 3] each, for unit directions w [..., 3] (float64 or float32)."""
    w = np.asarray(w)
    up = np.zeros_like(w)
    pole = np.abs(w[..., 1]) > POLE
    up[..., 1] = np.where(pole, 0.0, 1.0)
    up[..., 0] = np.where(pole, 1.0, 0.0)
    t = np.cross(up, w)
    t = t / np.linalg.norm(t, axis=-1, keepdims=True)
    b = np.cross(w, t)
    return t, b, w


def to_local(d, w):
    """World directions d [..., 3] in the view-local frame of w [..., 3] (broadcast)."""
    t, b, w = view_frame(w)
    return np.stack([(d * t).sum(-1), (d * b).sum(-1), (d * w).sum(-1)], -1)


def to_world(local, w):
    """Inverse of ``to_local``: local [..., 3] (x = t, y = b, z = w) to world."""
    t, b, w = view_frame(w)
    return local[..., 0:1] * t + local[..., 1:2] * b + local[..., 2:3] * w


def _direction(cos_theta, phi):
    s = np.sqrt(np.clip(1.0 - cos_theta * cos_theta, 0.0, None))
    return np.stack([s * np.cos(phi), s * np.sin(phi), cos_theta], -1)


def bin_centres(bt: int, bp: int) -> np.ndarray:
    """Local unit directions [B, 3] of the bin centres (cos = 1 - (2p+1)/BT, phi = 2 pi (q+.5)/BP)."""
    p, q = np.meshgrid(np.arange(bt), np.arange(bp), indexing="ij")
    return _direction(1.0 - (2.0 * p.ravel() + 1.0) / bt, 2.0 * math.pi * (q.ravel() + 0.5) / bp)


def bin_index(local, bt: int, bp: int) -> np.ndarray:
    """The bin [...] (int) holding local unit directions [..., 3]."""
    p = np.clip(np.floor((1.0 - local[..., 2]) * 0.5 * bt), 0, bt - 1).astype(np.int64)
    phi = np.mod(np.arctan2(local[..., 1], local[..., 0]), 2.0 * math.pi)
    q = np.clip(np.floor(phi / (2.0 * math.pi) * bp), 0, bp - 1).astype(np.int64)
    return p * bp + q


def jittered_bins(bt: int, bp: int, u) -> np.ndarray:
    """One local direction per bin, jittered inside it: u [..., B, 2] uniform in [0, 1) -> [..., B, 3]."""
    p = np.repeat(np.arange(bt), bp)
    q = np.tile(np.arange(bp), bt)
    cos_theta = 1.0 - 2.0 * (p + u[..., 0]) / bt
    phi = 2.0 * math.pi * (q + u[..., 1]) / bp
    return _direction(cos_theta, phi)


def stratified_sphere(n: int, u) -> np.ndarray:
    """n unit directions [..., n, 3] stratified over the sphere: an equal-area grid of rows x cols
    strata (rows = the largest divisor of n not above sqrt(n)), one jittered sample u [..., n, 2]
    in each. Rows split z = cos(polar angle) evenly, so every stratum has solid angle 4 pi / n."""
    rows = max(d for d in range(1, int(math.isqrt(n)) + 1) if n % d == 0)
    cols = n // rows
    r = np.repeat(np.arange(rows), cols)
    c = np.tile(np.arange(cols), rows)
    z = 1.0 - 2.0 * (r + u[..., 0]) / rows
    phi = 2.0 * math.pi * (c + u[..., 1]) / cols
    d = _direction(z, phi)
    return d[..., [0, 2, 1]]     # the rows split world y (up): a band per height above the ground
