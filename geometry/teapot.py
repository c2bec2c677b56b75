"""The Utah (Newell) teapot: Martin Newell's 1975 bicubic Bezier patches, and their tessellation.

The data is the classic public-domain table: 306 control points (``VERTICES``, Newell's frame:
z up, spout towards +x, handle towards -x; four points, 205, 206, 216 and 223 in the table's
1-based numbering, are unused near-duplicates of the lid's top that the table has always carried)
and 32 patches (``PATCHES``, 16 one-based indices each, row-major: four rows of four). The groups:

====================  =========  ==================================================================
group                 patches    rows (index i) / columns (index j)
====================  =========  ==================================================================
rim                   0-3        i: inner edge -> outer edge of the lip; j: a quarter turn
body                  4-11       i: top -> bottom (two rows of four patches); j: a quarter turn
handle                12-15      i: body end at the top -> body end at the bottom; j: half the tube
spout                 16-19      i: body -> tip; j: half the tube
lid                   20-27      i: knob top (a pole) -> lid edge (two rows); j: a quarter turn
bottom                28-31      i: centre (a pole) -> body's lower edge; j: a quarter turn
====================  =========  ==================================================================

The rotational groups turn from +x towards -y (quarters 0..3), the bottom the other way (+x to +y).
The teapot is not closed: the spout's tip is open, the lid does not meet the rim (a thin ring of
gap, as in the original), and handle and spout pierce the body without being stitched to it.

``tessellate(segments)`` turns the patches into a uv-mapped triangle mesh in inshade's frame
(y up: Newell's (x, y, z) -> (x, z, -y); the axis of revolution is the y axis, the base at y = 0,
Newell units: 3.15 high, x from -3 to 3.525). The uv atlas:

- rotational parts (lid, rim, body, bottom), v in [0.25, 1]: u from the quarter and t, the
  patch's Bezier parameter around the axis (Newell's quarter circles are close to uniform in
  angle: u = angle / 2 pi to within 0.002), 0 -> 1 once around, counter-clockwise seen from above
  (+x towards -z), starting at +x (the spout's side); v along the profile, 0.25 at the bottom's
  centre up to 1 at the knob's top, each profile segment (bottom, lower and upper body, rim, lid,
  knob) getting a share of v proportional to its arc length (linear in its parameter inside). A texture that repeats in u and v therefore flows continuously around the body, the lid and
  down the profile; the u = 0 / 1 seam is split (duplicated vertices).
- handle, [0, 0.49] x [0, 0.24]; spout, [0.51, 1] x [0, 0.24] (charts 0.01 apart): u along the
  part (from the upper body end to the lower one for the handle, from the body to the tip for the
  spout), v once around the tube. Everywhere the tangent frame (+u, +v, outward normal) is
  right-handed: a texture is never mirrored.

Vertices are shared where the positions and the uv agree (patch edges inside a group), split on
uv seams and at the poles (one vertex per pole triangle, each with its own u); triangles that a
pole collapses to zero area are dropped. Every face is wound counter-clockwise seen from outside.
numpy only; deterministic (the same arrays every run).
"""
from __future__ import annotations

import numpy as np

# Newell's control points, 1-based in PATCHES (VERTICES[k - 1]); z is up.
VERTICES = np.array([
    # rim (1-48)
    (1.4, 0.0, 2.4), (1.4, -0.784, 2.4), (0.784, -1.4, 2.4), (0.0, -1.4, 2.4),
    (1.3375, 0.0, 2.53125), (1.3375, -0.749, 2.53125), (0.749, -1.3375, 2.53125), (0.0, -1.3375, 2.53125),
    (1.4375, 0.0, 2.53125), (1.4375, -0.805, 2.53125), (0.805, -1.4375, 2.53125), (0.0, -1.4375, 2.53125),
    (1.5, 0.0, 2.4), (1.5, -0.84, 2.4), (0.84, -1.5, 2.4), (0.0, -1.5, 2.4),
    (-0.784, -1.4, 2.4), (-1.4, -0.784, 2.4), (-1.4, 0.0, 2.4),
    (-0.749, -1.3375, 2.53125), (-1.3375, -0.749, 2.53125), (-1.3375, 0.0, 2.53125),
    (-0.805, -1.4375, 2.53125), (-1.4375, -0.805, 2.53125), (-1.4375, 0.0, 2.53125),
    (-0.84, -1.5, 2.4), (-1.5, -0.84, 2.4), (-1.5, 0.0, 2.4),
    (-1.4, 0.784, 2.4), (-0.784, 1.4, 2.4), (0.0, 1.4, 2.4),
    (-1.3375, 0.749, 2.53125), (-0.749, 1.3375, 2.53125), (0.0, 1.3375, 2.53125),
    (-1.4375, 0.805, 2.53125), (-0.805, 1.4375, 2.53125), (0.0, 1.4375, 2.53125),
    (-1.5, 0.84, 2.4), (-0.84, 1.5, 2.4), (0.0, 1.5, 2.4),
    (0.784, 1.4, 2.4), (1.4, 0.784, 2.4),
    (0.749, 1.3375, 2.53125), (1.3375, 0.749, 2.53125),
    (0.805, 1.4375, 2.53125), (1.4375, 0.805, 2.53125),
    (0.84, 1.5, 2.4), (1.5, 0.84, 2.4),
    # body (49-120)
    (1.75, 0.0, 1.875), (1.75, -0.98, 1.875), (0.98, -1.75, 1.875), (0.0, -1.75, 1.875),
    (2.0, 0.0, 1.35), (2.0, -1.12, 1.35), (1.12, -2.0, 1.35), (0.0, -2.0, 1.35),
    (2.0, 0.0, 0.9), (2.0, -1.12, 0.9), (1.12, -2.0, 0.9), (0.0, -2.0, 0.9),
    (-0.98, -1.75, 1.875), (-1.75, -0.98, 1.875), (-1.75, 0.0, 1.875),
    (-1.12, -2.0, 1.35), (-2.0, -1.12, 1.35), (-2.0, 0.0, 1.35),
    (-1.12, -2.0, 0.9), (-2.0, -1.12, 0.9), (-2.0, 0.0, 0.9),
    (-1.75, 0.98, 1.875), (-0.98, 1.75, 1.875), (0.0, 1.75, 1.875),
    (-2.0, 1.12, 1.35), (-1.12, 2.0, 1.35), (0.0, 2.0, 1.35),
    (-2.0, 1.12, 0.9), (-1.12, 2.0, 0.9), (0.0, 2.0, 0.9),
    (0.98, 1.75, 1.875), (1.75, 0.98, 1.875),
    (1.12, 2.0, 1.35), (2.0, 1.12, 1.35),
    (1.12, 2.0, 0.9), (2.0, 1.12, 0.9),
    (2.0, 0.0, 0.45), (2.0, -1.12, 0.45), (1.12, -2.0, 0.45), (0.0, -2.0, 0.45),
    (1.5, 0.0, 0.225), (1.5, -0.84, 0.225), (0.84, -1.5, 0.225), (0.0, -1.5, 0.225),
    (1.5, 0.0, 0.15), (1.5, -0.84, 0.15), (0.84, -1.5, 0.15), (0.0, -1.5, 0.15),
    (-1.12, -2.0, 0.45), (-2.0, -1.12, 0.45), (-2.0, 0.0, 0.45),
    (-0.84, -1.5, 0.225), (-1.5, -0.84, 0.225), (-1.5, 0.0, 0.225),
    (-0.84, -1.5, 0.15), (-1.5, -0.84, 0.15), (-1.5, 0.0, 0.15),
    (-2.0, 1.12, 0.45), (-1.12, 2.0, 0.45), (0.0, 2.0, 0.45),
    (-1.5, 0.84, 0.225), (-0.84, 1.5, 0.225), (0.0, 1.5, 0.225),
    (-1.5, 0.84, 0.15), (-0.84, 1.5, 0.15), (0.0, 1.5, 0.15),
    (1.12, 2.0, 0.45), (2.0, 1.12, 0.45),
    (0.84, 1.5, 0.225), (1.5, 0.84, 0.225),
    (0.84, 1.5, 0.15), (1.5, 0.84, 0.15),
    # handle (121-161)
    (-1.6, 0.0, 2.025), (-1.6, -0.3, 2.025), (-1.5, -0.3, 2.25), (-1.5, 0.0, 2.25),
    (-2.3, 0.0, 2.025), (-2.3, -0.3, 2.025), (-2.5, -0.3, 2.25), (-2.5, 0.0, 2.25),
    (-2.7, 0.0, 2.025), (-2.7, -0.3, 2.025), (-3.0, -0.3, 2.25), (-3.0, 0.0, 2.25),
    (-2.7, 0.0, 1.8), (-2.7, -0.3, 1.8), (-3.0, -0.3, 1.8), (-3.0, 0.0, 1.8),
    (-1.5, 0.3, 2.25), (-1.6, 0.3, 2.025), (-2.5, 0.3, 2.25), (-2.3, 0.3, 2.025),
    (-3.0, 0.3, 2.25), (-2.7, 0.3, 2.025), (-3.0, 0.3, 1.8), (-2.7, 0.3, 1.8),
    (-2.7, 0.0, 1.575), (-2.7, -0.3, 1.575), (-3.0, -0.3, 1.35), (-3.0, 0.0, 1.35),
    (-2.5, 0.0, 1.125), (-2.5, -0.3, 1.125), (-2.65, -0.3, 0.9375), (-2.65, 0.0, 0.9375),
    (-2.0, -0.3, 0.9), (-1.9, -0.3, 0.6), (-1.9, 0.0, 0.6),
    (-3.0, 0.3, 1.35), (-2.7, 0.3, 1.575), (-2.65, 0.3, 0.9375), (-2.5, 0.3, 1.125),
    (-1.9, 0.3, 0.6), (-2.0, 0.3, 0.9),
    # spout (162-203)
    (1.7, 0.0, 1.425), (1.7, -0.66, 1.425), (1.7, -0.66, 0.6), (1.7, 0.0, 0.6),
    (2.6, 0.0, 1.425), (2.6, -0.66, 1.425), (3.1, -0.66, 0.825), (3.1, 0.0, 0.825),
    (2.3, 0.0, 2.1), (2.3, -0.25, 2.1), (2.4, -0.25, 2.025), (2.4, 0.0, 2.025),
    (2.7, 0.0, 2.4), (2.7, -0.25, 2.4), (3.3, -0.25, 2.4), (3.3, 0.0, 2.4),
    (1.7, 0.66, 0.6), (1.7, 0.66, 1.425), (3.1, 0.66, 0.825), (2.6, 0.66, 1.425),
    (2.4, 0.25, 2.025), (2.3, 0.25, 2.1), (3.3, 0.25, 2.4), (2.7, 0.25, 2.4),
    (2.8, 0.0, 2.475), (2.8, -0.25, 2.475), (3.525, -0.25, 2.49375), (3.525, 0.0, 2.49375),
    (2.9, 0.0, 2.475), (2.9, -0.15, 2.475), (3.45, -0.15, 2.5125), (3.45, 0.0, 2.5125),
    (2.8, 0.0, 2.4), (2.8, -0.15, 2.4), (3.2, -0.15, 2.4), (3.2, 0.0, 2.4),
    (3.525, 0.25, 2.49375), (2.8, 0.25, 2.475), (3.45, 0.15, 2.5125), (2.9, 0.15, 2.475),
    (3.2, 0.15, 2.4), (2.8, 0.15, 2.4),
    # lid (204-269)
    (0.0, 0.0, 3.15), (0.0, -0.002, 3.15), (0.002, 0.0, 3.15),
    (0.8, 0.0, 3.15), (0.8, -0.45, 3.15), (0.45, -0.8, 3.15), (0.0, -0.8, 3.15),
    (0.0, 0.0, 2.85),
    (0.2, 0.0, 2.7), (0.2, -0.112, 2.7), (0.112, -0.2, 2.7), (0.0, -0.2, 2.7),
    (0.002, 0.0, 3.15), (-0.45, -0.8, 3.15), (-0.8, -0.45, 3.15), (-0.8, 0.0, 3.15),
    (-0.112, -0.2, 2.7), (-0.2, -0.112, 2.7), (-0.2, 0.0, 2.7),
    (0.0, 0.002, 3.15), (-0.8, 0.45, 3.15), (-0.45, 0.8, 3.15), (0.0, 0.8, 3.15),
    (-0.2, 0.112, 2.7), (-0.112, 0.2, 2.7), (0.0, 0.2, 2.7),
    (0.45, 0.8, 3.15), (0.8, 0.45, 3.15),
    (0.112, 0.2, 2.7), (0.2, 0.112, 2.7),
    (0.4, 0.0, 2.55), (0.4, -0.224, 2.55), (0.224, -0.4, 2.55), (0.0, -0.4, 2.55),
    (1.3, 0.0, 2.55), (1.3, -0.728, 2.55), (0.728, -1.3, 2.55), (0.0, -1.3, 2.55),
    (1.3, 0.0, 2.4), (1.3, -0.728, 2.4), (0.728, -1.3, 2.4), (0.0, -1.3, 2.4),
    (-0.224, -0.4, 2.55), (-0.4, -0.224, 2.55), (-0.4, 0.0, 2.55),
    (-0.728, -1.3, 2.55), (-1.3, -0.728, 2.55), (-1.3, 0.0, 2.55),
    (-0.728, -1.3, 2.4), (-1.3, -0.728, 2.4), (-1.3, 0.0, 2.4),
    (-0.4, 0.224, 2.55), (-0.224, 0.4, 2.55), (0.0, 0.4, 2.55),
    (-1.3, 0.728, 2.55), (-0.728, 1.3, 2.55), (0.0, 1.3, 2.55),
    (-1.3, 0.728, 2.4), (-0.728, 1.3, 2.4), (0.0, 1.3, 2.4),
    (0.224, 0.4, 2.55), (0.4, 0.224, 2.55),
    (0.728, 1.3, 2.55), (1.3, 0.728, 2.55),
    (0.728, 1.3, 2.4), (1.3, 0.728, 2.4),
    # bottom (270-306)
    (0.0, 0.0, 0.0),
    (1.5, 0.0, 0.15), (1.5, 0.84, 0.15), (0.84, 1.5, 0.15), (0.0, 1.5, 0.15),
    (1.5, 0.0, 0.075), (1.5, 0.84, 0.075), (0.84, 1.5, 0.075), (0.0, 1.5, 0.075),
    (1.425, 0.0, 0.0), (1.425, 0.798, 0.0), (0.798, 1.425, 0.0), (0.0, 1.425, 0.0),
    (-0.84, 1.5, 0.15), (-1.5, 0.84, 0.15), (-1.5, 0.0, 0.15),
    (-0.84, 1.5, 0.075), (-1.5, 0.84, 0.075), (-1.5, 0.0, 0.075),
    (-0.798, 1.425, 0.0), (-1.425, 0.798, 0.0), (-1.425, 0.0, 0.0),
    (-1.5, -0.84, 0.15), (-0.84, -1.5, 0.15), (0.0, -1.5, 0.15),
    (-1.5, -0.84, 0.075), (-0.84, -1.5, 0.075), (0.0, -1.5, 0.075),
    (-1.425, -0.798, 0.0), (-0.798, -1.425, 0.0), (0.0, -1.425, 0.0),
    (0.84, -1.5, 0.15), (1.5, -0.84, 0.15),
    (0.84, -1.5, 0.075), (1.5, -0.84, 0.075),
    (0.798, -1.425, 0.0), (1.425, -0.798, 0.0),
], np.float64)

PATCHES = np.array([
    # rim
    (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16),
    (4, 17, 18, 19, 8, 20, 21, 22, 12, 23, 24, 25, 16, 26, 27, 28),
    (19, 29, 30, 31, 22, 32, 33, 34, 25, 35, 36, 37, 28, 38, 39, 40),
    (31, 41, 42, 1, 34, 43, 44, 5, 37, 45, 46, 9, 40, 47, 48, 13),
    # body
    (13, 14, 15, 16, 49, 50, 51, 52, 53, 54, 55, 56, 57, 58, 59, 60),
    (16, 26, 27, 28, 52, 61, 62, 63, 56, 64, 65, 66, 60, 67, 68, 69),
    (28, 38, 39, 40, 63, 70, 71, 72, 66, 73, 74, 75, 69, 76, 77, 78),
    (40, 47, 48, 13, 72, 79, 80, 49, 75, 81, 82, 53, 78, 83, 84, 57),
    (57, 58, 59, 60, 85, 86, 87, 88, 89, 90, 91, 92, 93, 94, 95, 96),
    (60, 67, 68, 69, 88, 97, 98, 99, 92, 100, 101, 102, 96, 103, 104, 105),
    (69, 76, 77, 78, 99, 106, 107, 108, 102, 109, 110, 111, 105, 112, 113, 114),
    (78, 83, 84, 57, 108, 115, 116, 85, 111, 117, 118, 89, 114, 119, 120, 93),
    # handle
    (121, 122, 123, 124, 125, 126, 127, 128, 129, 130, 131, 132, 133, 134, 135, 136),
    (124, 137, 138, 121, 128, 139, 140, 125, 132, 141, 142, 129, 136, 143, 144, 133),
    (133, 134, 135, 136, 145, 146, 147, 148, 149, 150, 151, 152, 69, 153, 154, 155),
    (136, 143, 144, 133, 148, 156, 157, 145, 152, 158, 159, 149, 155, 160, 161, 69),
    # spout
    (162, 163, 164, 165, 166, 167, 168, 169, 170, 171, 172, 173, 174, 175, 176, 177),
    (165, 178, 179, 162, 169, 180, 181, 166, 173, 182, 183, 170, 177, 184, 185, 174),
    (174, 175, 176, 177, 186, 187, 188, 189, 190, 191, 192, 193, 194, 195, 196, 197),
    (177, 184, 185, 174, 189, 198, 199, 186, 193, 200, 201, 190, 197, 202, 203, 194),
    # lid
    (204, 204, 204, 204, 207, 208, 209, 210, 211, 211, 211, 211, 212, 213, 214, 215),
    (204, 204, 204, 204, 210, 217, 218, 219, 211, 211, 211, 211, 215, 220, 221, 222),
    (204, 204, 204, 204, 219, 224, 225, 226, 211, 211, 211, 211, 222, 227, 228, 229),
    (204, 204, 204, 204, 226, 230, 231, 207, 211, 211, 211, 211, 229, 232, 233, 212),
    (212, 213, 214, 215, 234, 235, 236, 237, 238, 239, 240, 241, 242, 243, 244, 245),
    (215, 220, 221, 222, 237, 246, 247, 248, 241, 249, 250, 251, 245, 252, 253, 254),
    (222, 227, 228, 229, 248, 255, 256, 257, 251, 258, 259, 260, 254, 261, 262, 263),
    (229, 232, 233, 212, 257, 264, 265, 234, 260, 266, 267, 238, 263, 268, 269, 242),
    # bottom
    (270, 270, 270, 270, 279, 280, 281, 282, 275, 276, 277, 278, 271, 272, 273, 274),
    (270, 270, 270, 270, 282, 289, 290, 291, 278, 286, 287, 288, 274, 283, 284, 285),
    (270, 270, 270, 270, 291, 298, 299, 300, 288, 295, 296, 297, 285, 292, 293, 294),
    (270, 270, 270, 270, 300, 305, 306, 279, 297, 303, 304, 275, 294, 301, 302, 271),
], np.int64)

GROUPS = {"rim": range(0, 4), "body": range(4, 12), "handle": range(12, 16), "spout": range(16, 20),
          "lid": range(20, 28), "bottom": range(28, 32)}
MAX_SEGMENTS = 64


def control_points(frame: str = "y_up") -> np.ndarray:
    """[32, 4, 4, 3] control points per patch (row i, column j), in Newell's frame ("z_up") or
    inshade's ("y_up": (x, y, z) -> (x, z, -y), a rotation, so windings and handedness keep)."""
    p = VERTICES[PATCHES - 1].reshape(32, 4, 4, 3)
    if frame == "z_up":
        return p
    if frame != "y_up":
        raise ValueError(f"frame: must be \"y_up\" or \"z_up\", got {frame!r}")
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], -1)


def bernstein(t: np.ndarray) -> np.ndarray:
    """[len(t), 4] cubic Bernstein weights (exactly (1,0,0,0) at 0 and (0,0,0,1) at 1)."""
    t = np.asarray(t, np.float64)[:, None]
    s = 1.0 - t
    return np.concatenate([s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t], 1)


def evaluate(patch: np.ndarray, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Points [len(s), len(t), 3] of one patch [4, 4, 3] on the grid s (rows, i) x t (columns, j)."""
    return np.einsum("ai,ijc,bj->abc", bernstein(s), patch, bernstein(t))


# The profile segments from the bottom's centre (v = 0.25) to the knob's top (v = 1):
_PROFILE = (   # (first patch of the ring, rows run upwards along the profile?)
    (28, True),    # bottom: centre -> body's lower edge
    (8, False),    # lower body: z 0.9 -> 0.15
    (4, False),    # upper body: z 2.4 -> 0.9
    (0, False),    # rim: inner (top) edge -> outer edge, which meets the body
    (24, False),   # lid: knob's foot -> lid edge
    (20, False),   # knob: top pole -> foot
)
ROTATIONAL_V = (0.25, 1.0)
# (u range, v range); 0.01 apart from each other and from the rotational chart (mipmap bleeding)
HANDLE_UV = ((0.0, 0.49), (0.0, 0.24))
SPOUT_UV = ((0.51, 1.0), (0.0, 0.24))


def _profile_lengths() -> list[float]:
    """Arc length of each profile segment (the patch's column j = 0, at angle 0)."""
    cp = control_points("y_up")
    s = np.linspace(0.0, 1.0, 2049)
    out = []
    for first, _ in _PROFILE:
        curve = evaluate(cp[first], s, np.zeros(1))[:, 0]
        out.append(float(np.linalg.norm(np.diff(curve, axis=0), axis=1).sum()))
    return out


def _patch_uv(index: int, s: np.ndarray, t: np.ndarray, lengths: list[float]) -> np.ndarray:
    """uv [len(s), len(t), 2] of patch ``index`` at its grid (see the module's atlas)."""
    ss, tt = np.meshgrid(s, t, indexing="ij")
    if index in GROUPS["handle"] or index in GROUPS["spout"]:
        first = 12 if index in GROUPS["handle"] else 16
        (u0, u1), (v0, v1) = HANDLE_UV if first == 12 else SPOUT_UV
        k = index - first
        along = (k // 2 + ss) / 2.0            # two patches along the part
        around = 1.0 - (k % 2 + tt) / 2.0      # two halves around the tube; this way round, handedness +1
        return np.stack([u0 + (u1 - u0) * along, v0 + (v1 - v0) * around], -1)
    for ring, (first, upward) in enumerate(_PROFILE):
        if first <= index < first + 4:
            break
    else:  # pragma: no cover - every patch index is in a group
        raise ValueError(f"patch {index}: not in any group")
    quarter = index - first
    # u turns counter-clockwise seen from above (+x towards -z, the right-hand turn about +y), so
    # that with v up a texture is not mirrored (tangent handedness +1); Newell's quarters run the
    # other way in the y-up frame, except the bottom's
    if first == 28:
        u = (quarter + tt) / 4.0
    else:
        u = 1.0 - (quarter + tt) / 4.0
    total = float(sum(lengths))
    start = float(sum(lengths[:ring]))
    along = ss if upward else 1.0 - ss
    v = (start + along * lengths[ring]) / total
    v0, v1 = ROTATIONAL_V
    return np.stack([u, v0 + (v1 - v0) * v], -1)


def tessellate(segments: int = 8) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices [V, 3], faces [F, 3], uv [V, 2]) of the teapot, ``segments`` x ``segments`` quads
    per patch, y up, outward winding, vertices shared where position and uv agree."""
    if isinstance(segments, bool) or not isinstance(segments, (int, np.integer)) \
            or not 1 <= segments <= MAX_SEGMENTS:
        raise ValueError(f"segments: must be an int in 1..{MAX_SEGMENTS}, got {segments!r}")
    n = int(segments)
    cp = control_points("y_up")
    lengths = _profile_lengths()
    grid = np.linspace(0.0, 1.0, n + 1)
    positions, uvs, faces = [], [], []
    base = 0
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    v00 = (i * (n + 1) + j).reshape(-1)
    v01, v10, v11 = v00 + 1, v00 + n + 1, v00 + n + 2
    for index in range(len(cp)):
        positions.append(evaluate(cp[index], grid, grid).reshape(-1, 3))
        uvs.append(_patch_uv(index, grid, grid, lengths).reshape(-1, 2))
        # (row i, column j) -> (v00, v11, v10): counter-clockwise seen from outside for all 32
        # of Newell's patches (tests/geometry/test_shapes.py checks the normals point out)
        faces.append(np.concatenate([np.stack([v00, v11, v10], 1), np.stack([v00, v01, v11], 1)]) + base)
        base += (n + 1) * (n + 1)
    pos = np.concatenate(positions)
    uv = np.concatenate(uvs)
    face = np.concatenate(faces)
    # one vertex per (position, uv): rounding makes the evaluations of a shared edge or pole
    # (equal up to the last bit) compare equal
    key = np.concatenate([np.round(pos, 9), np.round(uv, 9)], 1) + 0.0   # + 0.0: no -0.0 keys
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    order = np.argsort(first, kind="stable")            # keep the first-seen order (deterministic)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    pos = key[first[order], :3]
    uv = key[first[order], 3:]
    face = rank[inverse][face]
    # drop the triangles a pole or a collapsed edge reduces to (near) zero area
    area = 0.5 * np.linalg.norm(np.cross(pos[face[:, 1]] - pos[face[:, 0]], pos[face[:, 2]] - pos[face[:, 0]]), axis=1)
    face = face[area > 1e-12]
    used = np.zeros(len(pos), bool)
    used[face.reshape(-1)] = True
    remap = np.cumsum(used) - 1
    return pos[used], remap[face].astype(np.int64), uv[used]
