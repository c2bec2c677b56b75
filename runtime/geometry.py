"""Triangle-mesh geometry on the GPU: the G-buffer pass that deferred mesh shading (PRT, PBR sets) reads.

``MeshGBuffer(ctx, mesh)`` uploads a trimesh mesh's positions, shading normals (geometry/mesh.py
``shading_normals``: welded across uv seams), uv and tangents once; ``draw(view, proj, model,
width, height)`` rasterises it with depth testing (common/mesh.vert + passes/mesh_gbuffer.frag)
into five RGBA32F textures (``GBUFFER``), NEAREST-filtered, data orientation (texel (x, y) is
pixel (x, y), as runtime/render.py ``read_rgba_raw``):

- ``position``: world position, w = 1 where the mesh covers the pixel, all 0 in the background;
- ``normal``: unit interpolated vertex normal (inverse-transpose of ``model``), w = 1 / 0 likewise;
  a mesh's own normals and tangents (``vertex_attributes`` "normal", "tangent": a glTF file's,
  geometry/gltf.py) are drawn as given, others are made here;
- ``uv``: interpolated texture coordinates (0 for a mesh without uv), z = the face's material (a
  glTF mesh's ``vertex_attributes["material"]``, geometry/gltf.py; 0 otherwise), w = 1 / 0;
- ``tangent``: interpolated world tangent (not renormalised: the shading pass orthonormalises it
  against the normal) and its handedness in w (+-1; 0 in the background or without uv);
- ``uv_grad``: the uv footprint (dFdx(uv), dFdy(uv)), uv change per pixel along +x and +y, for
  picking a mip level; taken in this pass because derivatives in the deferred pass would
  difference neighbours across triangle edges and uv seams; 0 in the background.

With ``visibility=True`` (a program whose spec asks for it, ProgramSpec.visibility) the pass also
writes a visibility buffer, with no vendor extension:

- ``primitive`` (R32UI, a ``usampler2D``): the face index (``gl_VertexID / 3`` of the de-indexed draw, faces in the mesh's
  order, one draw), meaningful where ``position.w`` = 1 (coverage is read from ``position`` only);
- ``barycentric`` (RG32F): the perspective-correct barycentrics (t0, t1) of face vertices 0 and 1
  (t2 = 1 - t0 - t1), interpolated from per-corner attributes: the mesh is drawn de-indexed
  (three vertices per face) so that each corner carries its own unit vector.

Matrices follow scene/camera.py: numpy 4x4 in pyrr's row-vector layout (``v @ view @ proj``),
i.e. exactly ``camera.view_matrix()`` and ``camera.projection(width, height)``; their C-order
float32 bytes are GLSL's column-major ``M * v``. ``model`` defaults to the identity.
A consumer pass (e.g. mesh PRT) samples the textures it needs with ``texelFetch`` at
``ivec2(gl_FragCoord.xy)`` on a target of the same size, and skips pixels whose w is 0.
"""
from __future__ import annotations

import moderngl
import numpy as np

from inshade.geometry.mesh import mesh_uv, shading_normals, vertex_tangents

from .programs import ProgramCache
from .render import TARGET_FORMATS, float_target, read_rgba_raw, release_target

VERTEX = "common/mesh.vert"
FRAGMENT = "passes/mesh_gbuffer.frag"
GBUFFER = ("position", "normal", "uv", "tangent", "uv_grad")   # attachment order; sampler u_gbuffer_<name>
VISIBILITY = ("primitive", "barycentric")                      # after GBUFFER with visibility=True
VISIBILITY_FORMATS = ("r32ui", "rg32f")
UV1 = ("uv1", "uv1_dy")                                        # last, where a texture reads TEXCOORD_1


def gbuffer_layout(mesh, visibility: bool = False) -> tuple[tuple, tuple, dict]:
    """The G-buffer targets of a mesh: (names, formats, defines for the pass and its readers).
    ``GBUFFER``, then ``VISIBILITY`` when asked, then ``UV1`` where the mesh carries a second uv set
    (a glTF texture reads TEXCOORD_1, geometry/gltf.py ``vertex_attributes["uv1"]``)."""
    names = GBUFFER + (VISIBILITY if visibility else ())
    formats = ("rgba32f",) * len(GBUFFER) + (VISIBILITY_FORMATS if visibility else ())
    defines = {"GBUFFER_VISIBILITY": 1} if visibility else {}
    if "uv1" in mesh.vertex_attributes:
        defines.update(GBUFFER_UV1=len(names), GBUFFER_UV1_DY=len(names) + 1)
        names, formats = names + UV1, formats + ("rgba32f",) * len(UV1)
    return names, formats, defines


def _mat_bytes(m) -> bytes:
    m = np.asarray(m, np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise ValueError(f"expected a finite 4x4 matrix, got shape {m.shape}")
    return m.astype("f4").tobytes()


def gbuffer_attributes(mesh, visibility: bool = False) -> tuple[dict, np.ndarray, bool]:
    """What the G-buffer pass draws: ({attribute: (float32 array [N, k], layout)}, faces int32
    [F, 3], whether the mesh has uv). With ``visibility`` the attributes are de-indexed (corner c of
    face f is vertex 3f + c, carrying barycentric e_c) and the faces are only counted."""
    faces = np.asarray(mesh.faces, np.int32)
    own = mesh.vertex_attributes
    normals = own["normal"] if "normal" in own else shading_normals(mesh)
    uv = mesh_uv(mesh)
    has_uv = uv is not None
    tangents = (own["tangent"] if "tangent" in own else vertex_tangents(mesh, normals) if has_uv
                else np.zeros((len(mesh.vertices), 4)))
    uv = uv if has_uv else np.zeros((len(mesh.vertices), 2))
    material = np.reshape(own["material"], (-1, 1)) if "material" in own else np.zeros((len(mesh.vertices), 1))
    attributes = {"in_position": (mesh.vertices, "3f"), "in_normal": (normals, "3f"), "in_uv": (uv, "2f"),
                  "in_tangent": (tangents, "4f"), "in_material": (material, "1f")}
    if "uv1" in own:
        attributes["in_uv1"] = (own["uv1"], "2f")
    if visibility:
        attributes = {name: (np.asarray(a)[faces.reshape(-1)], layout) for name, (a, layout) in attributes.items()}
        attributes["in_barycentric"] = (np.tile(np.eye(3, dtype=np.float32)[:, :2], (len(faces), 1)), "2f")
    return ({name: (np.ascontiguousarray(a, np.float32), layout) for name, (a, layout) in attributes.items()},
            faces, has_uv)


class GeometryLimitError(ValueError):
    """The G-buffer would exceed a queried GL limit (the message names both)."""


def cutout_chunks(masked: bool) -> dict:
    """The G-buffer pass's <gbuffer_cutout>: lib/gltf_cutout where a glTF mesh's alpha-masked or
    blended materials are bound to it, else lib/gbuffer_opaque (nothing cut)."""
    return {"gbuffer_cutout": f"#include <{'lib/gltf_cutout' if masked else 'lib/gbuffer_opaque'}>"}


class MeshGBuffer:
    """A mesh's G-buffer pass: ``draw`` -> (position texture, normal texture)."""

    def __init__(self, ctx: moderngl.Context, mesh, cache: ProgramCache | None = None, *, version: str = "330",
                 visibility: bool = False, materials=None, peel: bool = False):
        """``materials``: the glTF mesh's ``MaterialTextures``; where a material is alpha MASK, its
        surface is cut out below alphaCutoff here, so every pass after sees what lies behind.
        ``peel``: BLEND surfaces are left out of ``draw`` for ``draw_layer`` to peel; else they are
        drawn as opaque ones."""
        self.peel = bool(peel)
        self.ctx = ctx
        self.cache = cache if cache is not None else ProgramCache(ctx)
        self.visibility = bool(visibility)
        self.names, self.formats, self.defines = gbuffer_layout(mesh, self.visibility)
        limit = ctx.info["GL_MAX_DRAW_BUFFERS"]
        if len(self.names) > limit:
            raise GeometryLimitError(f"the G-buffer needs {len(self.names)} targets ({', '.join(self.names)}); "
                                     f"this driver draws to {limit} at once (GL_MAX_DRAW_BUFFERS)")
        self.materials = materials if materials is not None and (materials.masked or materials.blended) else None
        self.layers: dict[int, moderngl.Framebuffer] = {}   # peeled BLEND layers' targets (draw_layer)
        self.program = self.cache.get(VERTEX, FRAGMENT, version=version, defines=self.defines or None,
                                      chunks=cutout_chunks(self.materials is not None))
        attributes, faces, self.has_uv = gbuffer_attributes(mesh, self.visibility)
        vertices = attributes["in_position"][0]
        self.bounds = (vertices.min(0), vertices.max(0))
        self.face_count = len(faces)
        # as render.MeshPass, but owning its buffers so release() frees them
        self.buffers = [ctx.buffer(a.tobytes()) for a, _ in attributes.values()]
        self.index_buffer = None if self.visibility else ctx.buffer(np.ascontiguousarray(faces).tobytes())
        content = [(b, layout, name) for b, (name, (_, layout)) in zip(self.buffers, attributes.items())
                   if name in self.program]
        self.vao = (ctx.vertex_array(self.program, content) if self.visibility else
                    ctx.vertex_array(self.program, content, index_buffer=self.index_buffer, index_element_size=4))
        self.fbo: moderngl.Framebuffer | None = None

    @property
    def size(self) -> tuple[int, int] | None:
        return self.fbo.size if self.fbo is not None else None

    def _target(self, width: int, height: int) -> moderngl.Framebuffer:
        if self.fbo is None or self.fbo.size != (width, height):
            self._release_target()
            self.fbo = float_target(self.ctx, width, height, depth=True, formats=self.formats)
        return self.fbo

    def draw(self, view, proj, model=None, width: int = 512, height: int = 512):
        """Rasterise into the (reused) target of this size; returns its textures in GBUFFER order
        (a glTF mesh's BLEND surfaces left out when they are peeled: ``draw_layer``)."""
        return self._draw(self._target(int(width), int(height)), view, proj, model, width, height,
                          0 if self.peel else -1)

    def draw_layer(self, layer: int, view, proj, model=None, width: int = 512, height: int = 512):
        """Depth peeling of a glTF mesh's BLEND surfaces: layer k >= 1 holds, per pixel, the k-th
        nearest BLEND surface in front of ``draw``'s opaque one (lib/gltf_cutout); call ``draw``
        first, then the layers in order. Returns the layer's textures (two targets, alternating)."""
        w, h = int(width), int(height)
        slot = 1 + (layer - 1) % 2
        fbo = self.layers.get(slot)
        if fbo is None or fbo.size != (w, h):
            if fbo is not None:
                release_target(fbo)
            fbo = self.layers[slot] = float_target(self.ctx, w, h, depth=True, formats=self.formats)
        previous = self.fbo if layer == 1 else self.layers[1 + (layer - 2) % 2]
        units = len(self.materials.textures)
        self.fbo.color_attachments[0].use(location=units)
        previous.color_attachments[0].use(location=units + 1)
        self.program["u_peel_back"].value = units
        self.program["u_peel_front"].value = units + 1
        return self._draw(fbo, view, proj, model, w, h, layer)

    def _draw(self, fbo, view, proj, model, width, height, layer: int):
        fbo.use()
        self.ctx.viewport = (0, 0, int(width), int(height))
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        self.ctx.enable(moderngl.DEPTH_TEST)
        model = np.eye(4) if model is None else model
        for name, m in (("u_view", view), ("u_proj", proj), ("u_model", model)):
            self.program[name].write(_mat_bytes(m))
        if self.materials is not None:
            for unit, (name, tex) in enumerate(self.materials.textures.items()):
                tex.use(location=unit)
                self.program[name].value = unit
            self.program["u_gbuffer_layer"].value = layer
        self.vao.render(moderngl.TRIANGLES)
        return tuple(fbo.color_attachments)

    def draw_camera(self, camera, width: int, height: int, model=None):
        """``draw`` with a viewer.camera 3D camera's matrices."""
        return self.draw(camera.view_matrix(), camera.projection(width, height), model, width, height)

    def read(self) -> tuple[np.ndarray, ...]:
        """The last draw's textures in ``names`` order, data orientation (row 0 = GL y 0):
        (position, normal, uv, tangent, uv_grad) as [H, W, 4] float32, then with visibility
        primitive [H, W] uint32 and barycentric [H, W, 2] float32."""
        if self.fbo is None:
            raise RuntimeError("MeshGBuffer.read before draw")
        out = []
        for i, f in enumerate(self.formats):
            if f == "rgba32f":
                out.append(read_rgba_raw(self.fbo, i))
                continue
            components, dtype = TARGET_FORMATS[f]
            w, h = self.fbo.size
            raw = self.fbo.read(components=components, dtype=dtype, attachment=i)
            a = np.frombuffer(raw, np.uint32 if dtype == "u4" else np.float32).reshape(h, w, components).copy()
            out.append(a[..., 0] if components == 1 else a)
        return tuple(out)

    def _release_target(self) -> None:
        for fbo in self.layers.values():
            release_target(fbo)
        self.layers = {}
        if self.fbo is not None:
            for a in self.fbo.color_attachments:
                a.release()
            if self.fbo.depth_attachment is not None:
                self.fbo.depth_attachment.release()
            self.fbo.release()
            self.fbo = None

    def release(self) -> None:
        """GL objects of this pass (the program stays in the cache, whose owner releases it)."""
        self._release_target()
        self.vao.release()
        for b in [*self.buffers, *([self.index_buffer] if self.index_buffer is not None else [])]:
            b.release()
        self.buffers = []
