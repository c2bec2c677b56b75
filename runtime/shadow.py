"""Shadow maps of directional lights: the depth of a triangle mesh seen from one or more light
directions (orthographic), one layer per direction of ONE R32F 2D texture array, read in GLSL by
``shaders/lib/shadow_map.glsl`` (``shadow_visibility``) and in numpy by ``shadow_visibility_np``.

Conventions (shared by the GL pass, the GLSL chunk and the numpy twin):

- a direction ``d`` is a unit vector pointing FROM the scene TOWARD the light;
- its light frame: up = (0, 1, 0) unless |d.y| > 0.999, then (1, 0, 0); x = normalize(cross(up, d)),
  y = cross(d, x); the orthographic frustum is fitted to the caster's bounding sphere (centre c =
  the bounding box's centre, radius r = the farthest vertex, padded by 1%), so the whole caster is
  inside: ``matrices[l]`` (world -> light clip, w = 1) maps p to ((p - c).x / r, (p - c).y / r,
  -(p - c).d / r); clip z -1 is the sphere's point nearest the light;
- a texel stores the depth ``z * 0.5 + 0.5`` in [0, 1] of the nearest surface (1.0 where none),
  both faces drawn (no culling: a thin two-sided card casts a shadow). Stored as R32F colour (the
  fragment's gl_FragCoord.z), not a depth attachment: moderngl cannot attach one layer of an array,
  so each layer is drawn into a scratch target and copied into the array (glCopyTexSubImage3D);
- ``bias`` is in those depth units: a world distance t along the light is ``t * depth_scale``
  (``depth_scale = 1 / (2 r)``, per request).

GL objects (created on the first ``update``, reused while size and layer count stay the same):
the R32F array ``u_shadow_map`` (size x size x L, NEAREST, clamp), a scratch R32F texture + depth
renderbuffer + framebuffer, the depth program (PROGRAM's chunks through ``assemble``) and the
caster's vertex/index buffers + vertex array.
"""
from __future__ import annotations

import ctypes

import moderngl
import numpy as np

from inshade.technique import ShadowRequest

from .programs import ProgramCache
from .render import check_gl_error, clear_gl_error

# the light frame's up vector switches away from +y near the poles (same rule as the GLSL side)
POLE = 0.999
PAD = 1.01           # the fitted sphere is 1% larger than the caster's: vertices stay strictly inside

PROGRAM = ("common/shadow_depth.vert", "passes/shadow_depth.frag")   # the depth pass's chunks


def light_frame(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) of a direction's light frame (float64), see the module docstring."""
    d = np.asarray(direction, np.float64)
    up = np.array([1.0, 0.0, 0.0]) if abs(d[1]) > POLE else np.array([0.0, 1.0, 0.0])
    x = np.cross(up, d)
    x /= np.linalg.norm(x)
    return x, np.cross(d, x)


def bounding_sphere(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """(centre, radius) of the fitted sphere: bounding-box centre, farthest vertex padded by PAD."""
    v = np.asarray(vertices, np.float64)
    c = 0.5 * (v.min(0) + v.max(0))
    r = float(np.linalg.norm(v - c, axis=1).max()) * PAD
    return c, max(r, 1e-6)


def light_matrices(vertices: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """[L, 4, 4] float32 world -> light clip matrices (numpy convention: clip = M @ (p, 1))."""
    c, r = bounding_sphere(vertices)
    out = np.zeros((len(directions), 4, 4))
    for k, d in enumerate(np.asarray(directions, np.float64)):
        d = d / np.linalg.norm(d)
        x, y = light_frame(d)
        for row, axis in enumerate((x, y, -d)):
            out[k, row, :3] = axis / r
            out[k, row, 3] = -axis @ c / r
        out[k, 3, 3] = 1.0
    return out.astype(np.float32)


def shadow_visibility_np(depth: np.ndarray, matrices: np.ndarray, points: np.ndarray, layer: int,
                         bias: float) -> np.ndarray:
    """The numpy twin of GLSL ``shadow_visibility`` for ``points`` [N, 3] -> [N] in [0, 1]:
    1.0 outside the map (|clip x|, |clip y| or |clip z| > 1) or for a layer not in the map; else a
    2x2 PCF on texel centres: each of the four texels around the point (clamped to the map) is lit
    when the point's depth - bias <= its stored depth, mixed with bilinear weights."""
    depth = np.asarray(depth, np.float32)
    points = np.asarray(points, np.float64)
    if not 0 <= layer < len(depth):
        return np.ones(len(points))
    m = np.asarray(matrices, np.float64)[layer]
    ndc = points @ m[:3, :3].T + m[:3, 3]
    h, w = depth.shape[1:]
    z = ndc[:, 2] * 0.5 + 0.5 - bias
    st = (ndc[:, :2] * 0.5 + 0.5) * np.array([w, h]) - 0.5
    base = np.floor(st)
    f = st - base
    i0 = np.clip(base.astype(np.int64), 0, [w - 1, h - 1])
    i1 = np.clip(base.astype(np.int64) + 1, 0, [w - 1, h - 1])
    lit = lambda ix, iy: (z <= depth[layer, iy, ix]).astype(np.float64)  # noqa: E731
    l00, l10 = lit(i0[:, 0], i0[:, 1]), lit(i1[:, 0], i0[:, 1])
    l01, l11 = lit(i0[:, 0], i1[:, 1]), lit(i1[:, 0], i1[:, 1])
    fx, fy = f[:, 0], f[:, 1]
    out = (l00 * (1 - fx) + l10 * fx) * (1 - fy) + (l01 * (1 - fx) + l11 * fx) * fy
    return np.where((np.abs(ndc) > 1.0).any(1), 1.0, out)


class ShadowMaps:
    """The GL side: ``update(request)`` (re)draws the maps when the request's key, directions or
    size changed (returns whether it drew); ``bind(program, unit)`` binds ``u_shadow_map``,
    ``u_shadow_matrix`` and ``u_shadow_layers`` where the program has them and returns the next
    free unit; ``clear()`` leaves no layers (visibility 1 everywhere); ``release()``.
    ``version`` counts redraws (a renderer keys its redraws on it)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.texture = None          # R32F array [size, size, L]
        self.matrices = np.zeros((0, 4, 4), np.float32)
        self.depth_scale = 1.0       # depth units per world unit along the light (1 / (2 r))
        self.layers = 0
        self.version = 0
        self._state = None           # (key, directions bytes, size) last drawn
        self._mesh_key = None
        self._programs = self._program = self._vao = self._buffers = None
        self._scratch = None         # (colour texture, depth renderbuffer, framebuffer)

    # drawing ---------------------------------------------------------------------------------------
    def update(self, request: ShadowRequest) -> bool:
        state = (request.key, request.directions.tobytes(), request.size)
        if state == self._state:
            return False
        self._check_limits(request)
        clear_gl_error(self.ctx, "drawing shadow maps")
        if self._program is None:
            self._programs = ProgramCache(self.ctx)
            self._program = self._programs.get(*PROGRAM)
        if request.key != self._mesh_key or self._vao is None:
            self._upload_mesh(request)
        layers, size = len(request.directions), request.size
        if self.texture is None or self.texture.size != (size, size, layers):
            self._allocate(size, layers)
        self.matrices = light_matrices(request.vertices, request.directions)
        self.depth_scale = 1.0 / (2.0 * bounding_sphere(request.vertices)[1])
        self._draw(size)
        self.layers = layers
        self._state = state
        self.version += 1
        return True

    def clear(self) -> None:
        """No shadows: ``u_shadow_layers`` 0 (the GL objects stay for the next update)."""
        if self.layers or self._state is not None:
            self.version += 1
        self.layers, self._state = 0, None

    def _check_limits(self, request: ShadowRequest) -> None:
        info = self.ctx.info
        side, layers = int(info["GL_MAX_TEXTURE_SIZE"]), int(info["GL_MAX_ARRAY_TEXTURE_LAYERS"])
        if request.size > side:
            raise ValueError(f"ShadowRequest.size: {request.size} texels; this context's GL_MAX_TEXTURE_SIZE is {side}")
        if len(request.directions) > layers:
            raise ValueError(f"ShadowRequest.directions: {len(request.directions)} layers; this context's "
                             f"GL_MAX_ARRAY_TEXTURE_LAYERS is {layers}")

    def _upload_mesh(self, request: ShadowRequest) -> None:
        self._release_mesh()
        vbo = self.ctx.buffer(request.vertices.tobytes())
        ibo = self.ctx.buffer(request.faces.astype(np.uint32).tobytes())
        self._vao = self.ctx.vertex_array(self._program, [(vbo, "3f", "in_position")], index_buffer=ibo,
                                          index_element_size=4)
        self._buffers = (vbo, ibo)
        self._mesh_key = request.key

    def _allocate(self, size: int, layers: int) -> None:
        self._release_maps()
        self.texture = self.ctx.texture_array((size, size, layers), 1, dtype="f4")
        self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.texture.repeat_x = self.texture.repeat_y = False
        colour = self.ctx.texture((size, size), 1, dtype="f4")
        depth = self.ctx.depth_renderbuffer((size, size))
        check_gl_error(self.ctx, f"shadow maps: R32F array {size}x{size}x{layers} and its scratch target")
        self._scratch = (colour, depth, self.ctx.framebuffer([colour], depth))
        self.ctx.error   # moderngl's benign error when the framebuffer it restores was released (render.py)

    def _draw(self, size: int) -> None:
        from .network import gl_function

        ctx = self.ctx
        i, u = ctypes.c_int, ctypes.c_uint
        copy = gl_function(ctx, "glCopyTexSubImage3D", None, u, i, i, i, i, i, i, i, i)
        read_buffer = gl_function(ctx, "glReadBuffer", None, u)
        fbo = self._scratch[2]
        scissor, viewport = ctx.scissor, ctx.viewport
        ctx.scissor = None
        ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)   # both faces: two-sided cards cast shadows
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.depth_func = "<"
        try:
            for layer, m in enumerate(self.matrices):
                fbo.use()
                ctx.viewport = (0, 0, size, size)
                fbo.clear(1.0, 1.0, 1.0, 1.0, depth=1.0)
                self._program["u_matrix"].write(np.ascontiguousarray(m.T).tobytes())   # column-major
                self._vao.render(moderngl.TRIANGLES)
                # the scratch target's colour -> this layer of the array (both bound by moderngl calls)
                read_buffer(0x8CE0)                                   # GL_COLOR_ATTACHMENT0
                self.texture.use(location=ctx.default_texture_unit)
                copy(0x8C1A, 0, 0, 0, layer, 0, 0, size, size)        # GL_TEXTURE_2D_ARRAY
        finally:
            ctx.disable(moderngl.DEPTH_TEST)
            ctx.scissor, ctx.viewport = scissor, viewport
        check_gl_error(ctx, f"shadow maps ({size}x{size}, {len(self.matrices)} layers)")

    # binding ---------------------------------------------------------------------------------------
    def bind(self, program, unit: int) -> int:
        """Binds what ``program`` uses of lib/shadow_map.glsl; returns the next free texture unit.
        Before any update (or after ``clear``) the map is a 1x1 layer and ``u_shadow_layers`` is 0."""
        if "u_shadow_map" in program:
            if self.texture is None:
                self._allocate(1, 1)
                self.texture.write(np.ones(1, np.float32).tobytes())
            self.texture.use(location=unit)
            program["u_shadow_map"].value = unit
            unit += 1
        if "u_shadow_matrix" in program:
            slots = program["u_shadow_matrix"].array_length
            if self.layers > slots:
                raise ValueError(f"shadow maps: {self.layers} layers, but the program's u_shadow_matrix holds "
                                 f"{slots} (define SHADOW_MAX_LAYERS before including lib/shadow_map)")
            mats = np.zeros((slots, 4, 4), np.float32)
            mats[: self.layers] = self.matrices[: self.layers].transpose(0, 2, 1)   # column-major
            program["u_shadow_matrix"].write(mats.tobytes())
        if "u_shadow_layers" in program:
            program["u_shadow_layers"].value = self.layers
        return unit

    # reading (tests, debugging) --------------------------------------------------------------------
    def read(self) -> np.ndarray:
        """The maps as float32 [L, size, size] (texel (x, y) of layer l = out[l, y, x])."""
        if self.texture is None or not self.layers:
            return np.zeros((0, 0, 0), np.float32)
        w, h, n = self.texture.size
        return np.frombuffer(self.texture.read(), np.float32).reshape(n, h, w)[: self.layers].copy()

    # releasing -------------------------------------------------------------------------------------
    def _release_mesh(self) -> None:
        if self._vao is not None:
            self._vao.release()
            for b in self._buffers:
                b.release()
        self._vao = self._buffers = self._mesh_key = None

    def _release_maps(self) -> None:
        if self.texture is not None:
            self.texture.release()
            for obj in self._scratch:
                obj.release()
        self.texture = self._scratch = None

    def release(self) -> None:
        self._release_mesh()
        self._release_maps()
        if self._program is not None:
            self._programs.release()
            self._program = self._programs = None
        self.layers, self._state = 0, None
