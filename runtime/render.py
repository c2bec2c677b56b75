"""Passes, float render targets, and moving float data in and out of GL.

Two orientations, kept apart on purpose:

- **Images** (``read_rgba``): row 0 is the *top* of the picture. GL's window origin is the
  bottom-left, so read-back flips rows. Use this for anything written to PNG/EXR.
- **Data** (``upload_float_texture``, ``read_rgba_raw``): no flip anywhere. Texel (x, y) is
  ``array[y, x]``, fetched as ``texelFetch(tex, ivec2(x, y), 0)``; and pixel (x, y) of a target,
  i.e. ``gl_FragCoord.xy == (x + 0.5, y + 0.5)``, comes back as ``read_rgba_raw(fbo)[y, x]``. So a
  pass that computes ``out[y, x] = f(in[y, x])`` on the GPU reads like numpy on both ends.
"""

from __future__ import annotations

import logging
from typing import Mapping

import moderngl
import numpy as np


def _bind(program: moderngl.Program, uniforms: Mapping | None, textures: Mapping | None) -> None:
    """Set uniforms and bind ``{sampler name: texture}`` to units 0, 1, ... in order.

    A ``bytes`` value is written raw (e.g. a matrix as ``M.T.astype("f4").tobytes()``: GLSL
    matrices are column-major, so a numpy matrix used as ``M @ v`` is passed transposed);
    anything else goes through moderngl's ``Uniform.value``.
    """
    # Names the linker removed (e.g. the inputs of a network that ignores them) are skipped.
    for name, value in (uniforms or {}).items():
        if name not in program:
            continue
        if isinstance(value, bytes):
            program[name].write(value)
        else:
            program[name].value = value
    for unit, (name, texture) in enumerate((textures or {}).items()):
        if name in program:
            texture.use(location=unit)
            program[name].value = unit


class FullscreenPass:
    """Draws the full-screen triangle of ``common/fullscreen.vert`` (no vertex buffers)."""

    def __init__(self, ctx: moderngl.Context, program: moderngl.Program):
        self.ctx = ctx
        self.program = program
        self.vao = ctx.vertex_array(program, [])

    def render(self, fbo: moderngl.Framebuffer, *, uniforms: Mapping | None = None,
               textures: Mapping | None = None) -> None:
        """Shade every pixel of ``fbo`` once (no depth test, no blending)."""
        fbo.use()
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND | moderngl.CULL_FACE)
        _bind(self.program, uniforms, textures)
        self.vao.render(moderngl.TRIANGLES, vertices=3)


class MeshPass:
    """Draws an indexed triangle mesh through ``common/mesh.vert`` with depth testing.

    Attributes the linker optimised away (e.g. normals unused by the fragment shader) are skipped,
    since moderngl refuses to bind buffers to inactive attributes.
    """

    def __init__(self, ctx: moderngl.Context, program: moderngl.Program, vertices: np.ndarray,
                 normals: np.ndarray, uvs: np.ndarray, indices: np.ndarray):
        self.ctx = ctx
        self.program = program
        attributes = {"in_position": (vertices, "3f"), "in_normal": (normals, "3f"), "in_uv": (uvs, "2f")}
        content = [
            (ctx.buffer(np.ascontiguousarray(data, dtype="f4").tobytes()), layout, name)
            for name, (data, layout) in attributes.items() if name in program
        ]
        index_buffer = ctx.buffer(np.ascontiguousarray(indices, dtype="i4").tobytes())
        self.vao = ctx.vertex_array(program, content, index_buffer=index_buffer, index_element_size=4)

    def render(self, fbo: moderngl.Framebuffer, *, uniforms: Mapping | None = None,
               textures: Mapping | None = None) -> None:
        """Draw the mesh into ``fbo`` with depth test (LESS), no blending, no culling."""
        fbo.use()
        self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        self.ctx.enable(moderngl.DEPTH_TEST)
        _bind(self.program, uniforms, textures)
        self.vao.render(moderngl.TRIANGLES)


def clear_gl_error(ctx: moderngl.Context, what: str) -> None:
    """Clear a GL error left by earlier calls (logged, not blamed on ``what``)."""
    err = ctx.error
    if err != "GL_NO_ERROR":
        logging.getLogger("inshade").warning("GL error %s was pending before %s", err, what)


def check_gl_error(ctx: moderngl.Context, what: str) -> None:
    """Raise RuntimeError naming ``what`` if the driver recorded a GL error (reading clears it)."""
    err = ctx.error
    if err != "GL_NO_ERROR":
        raise RuntimeError(f"{what}: the driver reported {err}")


# render-target formats: name -> (components, moderngl dtype); "r32ui" is read with a usampler2D
TARGET_FORMATS = {"rgba32f": (4, "f4"), "rg32f": (2, "f4"), "r32f": (1, "f4"), "r32ui": (1, "u4"),
                  "rgba32ui": (4, "u4")}


def float_target(ctx: moderngl.Context, width: int, height: int, attachments: int = 1,
                 depth: bool = False, formats: tuple[str, ...] | None = None) -> moderngl.Framebuffer:
    """A framebuffer of ``attachments`` RGBA32F colour textures (MRT), plus a depth buffer if asked.
    ``formats`` (names in ``TARGET_FORMATS``, one per attachment) replaces RGBA32F, e.g. a visibility
    buffer's ("rgba32f", "r32ui", "rg32f"): a fragment output is then a uint / vec2 at that location.

    Colour textures use NEAREST filtering so a later pass can read them as exact data.
    """
    formats = tuple(formats) if formats is not None else ("rgba32f",) * attachments
    attachments = len(formats)
    limit = ctx.info["GL_MAX_DRAW_BUFFERS"]
    if not 1 <= attachments <= limit:
        raise ValueError(f"{attachments} colour attachments requested; this driver allows 1..{limit}")
    unknown = [f for f in formats if f not in TARGET_FORMATS]
    if unknown:
        raise ValueError(f"unknown render-target format {unknown[0]!r} (known: {', '.join(TARGET_FORMATS)})")
    clear_gl_error(ctx, "creating a float target")
    colours = []
    for f in formats:
        components, dtype = TARGET_FORMATS[f]
        texture = ctx.texture((width, height), components, dtype=dtype)
        texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        colours.append(texture)
    depth_attachment = ctx.depth_renderbuffer((width, height)) if depth else None
    # the attachments are checked; moderngl checks the framebuffer's completeness itself (and its
    # creation leaves a benign GL_INVALID_OPERATION on Mesa with several attachments, or when the
    # framebuffer it restores afterwards was released, e.g. by an earlier renderer)
    check_gl_error(ctx, f"render target {width}x{height}: {', '.join(f.upper() for f in formats)}")
    fbo = ctx.framebuffer(color_attachments=colours, depth_attachment=depth_attachment)
    ctx.error   # consume that benign error so it is not blamed on a later resource
    return fbo


def release_target(fbo: moderngl.Framebuffer) -> None:
    """Release a framebuffer made by ``float_target`` with its attachments."""
    for a in fbo.color_attachments:
        a.release()
    if fbo.depth_attachment is not None:
        fbo.depth_attachment.release()
    fbo.release()


def read_rgba_raw(fbo: moderngl.Framebuffer, attachment: int = 0) -> np.ndarray:
    """Read a colour attachment as float32 ``[H, W, 4]`` in data orientation (row 0 = GL y 0)."""
    width, height = fbo.size
    data = fbo.read(components=4, dtype="f4", attachment=attachment)
    return np.frombuffer(data, dtype=np.float32).reshape(height, width, 4).copy()


def read_rgba(fbo: moderngl.Framebuffer, attachment: int = 0) -> np.ndarray:
    """Read a colour attachment as float32 ``[H, W, 4]`` in image orientation (row 0 = top)."""
    return np.ascontiguousarray(read_rgba_raw(fbo, attachment)[::-1])


def upload_float_texture(ctx: moderngl.Context, array: np.ndarray, dtype: str = "f4") -> moderngl.Texture:
    """Upload ``[H, W]`` or ``[H, W, C]`` (C in 1..4) as a float32 data texture, without flipping
    (``dtype="u4"``: a uint32 one, R32UI..RGBA32UI, read by a ``usampler2D``).

    Texel (x, y) holds ``array[y, x]``. NEAREST filtering, no mipmaps, clamp-to-edge.
    """
    array = np.asarray(array, dtype=np.uint32 if dtype == "u4" else np.float32)
    if array.ndim == 2:
        array = array[:, :, None]
    if array.ndim != 3 or not 1 <= array.shape[2] <= 4:
        raise ValueError(f"expected [H, W] or [H, W, 1..4], got shape {array.shape}")
    height, width, channels = array.shape
    clear_gl_error(ctx, "uploading a float data texture")
    texture = ctx.texture((width, height), channels, np.ascontiguousarray(array).tobytes(), dtype=dtype)
    texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
    texture.repeat_x = texture.repeat_y = False
    try:
        check_gl_error(ctx, f"{dtype} data texture {width}x{height}x{channels}")
    except RuntimeError:
        texture.release()
        raise
    return texture
