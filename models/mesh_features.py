"""UV-free hashed per-triangle feature hierarchy (Walloner 2024): its rules in torch, which the
component's twin (components/mesh_features/torch_twin.py) and the trainers share; GLSL twins:
components/mesh_features/emit.py and shaders/lib/mesh_features.glsl.

A surface point is (triangle k, barycentrics t0, t1); t2 = 1 - t0 - t1; t_i belongs to face
vertex i (the face's index order). Per level l (R = 2^l), in float32:

    a0 = R*t0; a1 = R*t1                          (R*t is exact)
    i = clamp(floor(a0), 0, R-1); j = clamp(floor(a1), 0, R-1-i)
    f0 = a0 - i; f1 = a1 - j
    upright = (i + j == R-1) || (f0 + f1 <= 1.0)
    upright: sub-vertices (W0,W1) = (i,j), (i+1,j), (i,j+1); weights ((1-f0)-f1, f0, f1)
    rotated: (i+1,j+1), (i,j+1), (i+1,j); weights ((f0+f1)-1, 1-f0, 1-f1)
    W2 = R - W0 - W1

This is the thesis's sub-triangle rule written with two coordinates: equal to it inside
sub-triangles, and continuous on their boundaries (where a 3-floor form can name sub-vertices
off the grid). A sub-vertex (k, W) is canonicalised so every face sharing it names it alike:

    some W_s == R (first s): c = corners[k, s]; k' = c >> 2; W' = R at slot c & 3, 0 elsewhere
    else some W_s == 0 (first s): e = edges[k, s]; k' = e >> 4; a = (e >> 2) & 3; b = e & 3;
                                  W'[a] = W[(s+1)%3], W'[b] = W[(s+2)%3], W'[3-a-b] = 0
    else k' = k, W' = W

(tables from geometry/mesh_topology.py), then hashed with uint32 wrap-around arithmetic:

    h = (2654435761 * k') ^ W'0 ^ (805459861 * W'1) ^ (1094488767 * l)
    index = l * T + (h & (T - 1))

(1094488767 = the thesis's 5389456063 mod 2^32: notes §2.6). Level output =
((w0 * f[index0]) + w1 * f[index1]) + w2 * f[index2]; the output concatenates levels 0..L-1.
Barycentric gradients are not propagated (t is detached); gradients reach `table`.
precision "f16": the table is rounded to fp16 in forward (straight-through) and at export.
precision "u8": per feature lane c an affine 8-bit code, value = offset[c] + scale[c] * q / 255
(q = clamp(rint((table - offset) / scale * 255), 0, 255)); forward blends the unit values q / 255
(straight-through: gradients reach `table` as if unquantised) and applies offset + scale * blend
per level, the order the shader uses (unorm8 texels, the affine decode after the blend: it
commutes with the convex blend). The range (buffers `scale`, `offset`) is set by `calibrate()`
(per-lane min/max of the table: on construction and by `from_node` from the bundle's tensors);
export writes q with that range, so a quantisation-aware fit exports what it trained on.
"""
from __future__ import annotations

import torch

PRIME_K, PRIME_W1, PRIME_L = 2654435761, 805459861, 1094488767
_MASK = 0xFFFFFFFF


def subvertices(t0: torch.Tensor, t1: torch.Tensor, level: int):
    """float32 t0, t1 [...] -> (W0 [..., 3], W1 [..., 3]) int64 sub-vertex coordinates and
    weights [..., 3] float32, in the order the rule lists them."""
    r = float(1 << level)
    a0, a1 = t0.float() * r, t1.float() * r
    i = torch.clamp(torch.floor(a0), 0.0, r - 1.0)
    j = torch.minimum(torch.clamp(torch.floor(a1), min=0.0), (r - 1.0) - i)
    f0, f1 = a0 - i, a1 - j
    upright = (i + j == r - 1.0) | (f0 + f1 <= 1.0)
    i, j = i.long(), j.long()
    w0 = torch.where(upright[..., None], torch.stack([i, i + 1, i], -1), torch.stack([i + 1, i, i + 1], -1))
    w1 = torch.where(upright[..., None], torch.stack([j, j, j + 1], -1), torch.stack([j + 1, j + 1, j], -1))
    weights = torch.where(upright[..., None], torch.stack([(1.0 - f0) - f1, f0, f1], -1),
                          torch.stack([(f0 + f1) - 1.0, 1.0 - f0, 1.0 - f1], -1))
    return w0, w1, weights


def _first(mask: torch.Tensor) -> torch.Tensor:
    """Index of the first True along the last axis (0 where none)."""
    return torch.argmax(mask.to(torch.int8), dim=-1)


def canonical(k: torch.Tensor, w: torch.Tensor, corners: torch.Tensor, edges: torch.Tensor, level: int):
    """k [...] int64, w [..., 3] int64 (W0, W1, W2) -> (k', W'0, W'1) int64 [...] each.
    corners, edges: int64 [faces, 3] (the uint32 tables widened)."""
    r = 1 << level
    s_r = _first(w == r)
    c = corners[k, s_r]
    kc, slot = c >> 2, c & 3
    wc0, wc1 = torch.where(slot == 0, r, 0), torch.where(slot == 1, r, 0)

    s_0 = _first(w == 0)
    e = edges[k, s_0]
    ke, a, b = e >> 4, (e >> 2) & 3, e & 3
    wj = w.gather(-1, ((s_0 + 1) % 3)[..., None])[..., 0]
    wm = w.gather(-1, ((s_0 + 2) % 3)[..., None])[..., 0]
    zero = torch.zeros_like(wj)
    we0 = torch.where(a == 0, wj, torch.where(b == 0, wm, zero))
    we1 = torch.where(a == 1, wj, torch.where(b == 1, wm, zero))

    on_r, on_0 = (w == r).any(-1), (w == 0).any(-1)
    k2 = torch.where(on_r, kc, torch.where(on_0, ke, k))
    w0 = torch.where(on_r, wc0, torch.where(on_0, we0, w[..., 0]))
    w1 = torch.where(on_r, wc1, torch.where(on_0, we1, w[..., 1]))
    return k2, w0, w1


def hash_value(k: torch.Tensor, w0: torch.Tensor, w1: torch.Tensor, level: int) -> torch.Tensor:
    """The full 32-bit h of a canonical sub-vertex (uint32 arithmetic emulated in int64 with masks)."""
    return ((PRIME_K * k) & _MASK) ^ w0 ^ ((PRIME_W1 * w1) & _MASK) ^ ((PRIME_L * level) & _MASK)


def hash_index(k: torch.Tensor, w0: torch.Tensor, w1: torch.Tensor, level: int, table_size: int) -> torch.Tensor:
    """int64 row of the feature table: level * T + (h & (T - 1))."""
    return level * table_size + (hash_value(k, w0, w1, level) & (table_size - 1))

