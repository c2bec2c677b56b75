"""The uv footprint attachment of the mesh G-buffer (runtime/geometry.py GBUFFER "uv_grad",
passes/mesh_gbuffer.frag): a plane seen head-on has an analytically known uv change per pixel."""
from __future__ import annotations

import math

import numpy as np
import pyrr
import pytest
import trimesh

from inshade.runtime.geometry import GBUFFER, MeshGBuffer


def test_uv_grad_is_the_fifth_attachment():
    assert GBUFFER == ("position", "normal", "uv", "tangent", "uv_grad")


@pytest.mark.parametrize("distance, fov_y, width, height, uv_map", [
    (3.0, 45.0, 40, 32, ((0.5, 0.0), (0.0, 0.5))),      # uv = (x + 1) / 2, (y + 1) / 2
    (4.5, 30.0, 24, 36, ((0.0, -2.0), (3.0, 0.0))),     # rotated and scaled: u = -2 y, v = 3 x
    (2.5, 60.0, 33, 21, ((1.5, 0.25), (-0.75, 1.0))),   # a general affine map
])
def test_head_on_plane_gives_the_analytic_uv_gradient(gl, distance, fov_y, width, height, uv_map):
    """The quad [-1, 1]^2 in z = 0 with uv = A @ (x, y) seen from (0, 0, distance) down -z: a pixel
    spans p = 2 distance tan(fov_y / 2) / height world units in x and in y (square pixels), so
    dFdx(uv) = p A[:, 0] and dFdy(uv) = p A[:, 1] on every covered pixel, including those on the
    diagonal between the quad's two triangles; background pixels are 0."""
    a = np.array(uv_map, np.float64)
    xy = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    mesh = trimesh.Trimesh(np.c_[xy, np.zeros(4)], [[0, 1, 2], [0, 2, 3]], process=False,
                           visual=trimesh.visual.TextureVisuals(uv=xy @ a.T))
    view = pyrr.matrix44.create_look_at([0.0, 0.0, distance], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], dtype=np.float64)
    proj = pyrr.matrix44.create_perspective_projection(fov_y, width / height, 0.1, 100.0, dtype=np.float64)
    gb = MeshGBuffer(gl, mesh)
    try:
        gb.draw(view, proj, None, width, height)
        position, *_, uv_grad = gb.read()
    finally:
        gb.release()
    covered = position[..., 3] == 1.0
    assert 0.2 < covered.mean() < 0.95, "the quad must cover part of the view, with background around it"
    p = 2.0 * distance * math.tan(math.radians(fov_y) / 2) / height
    want = np.array([p * a[0, 0], p * a[1, 0], p * a[0, 1], p * a[1, 1]])
    # a derivative is a difference of two float32 interpolated uvs: absolute error of a few ulp of |uv|
    uv_ulp = float(np.spacing(np.float32(np.abs(xy @ a.T).max())))
    np.testing.assert_allclose(uv_grad[covered], np.broadcast_to(want, uv_grad[covered].shape),
                               rtol=1e-4, atol=4 * uv_ulp)
    assert (uv_grad[~covered] == 0).all()
