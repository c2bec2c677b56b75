"""GL side of a generated network: its textures and uniform blocks, bound to a program, and
an evaluator that runs the network over a batch of inputs (parity tests, benchmarks)."""
from __future__ import annotations

import ctypes
import logging
import math

import moderngl
import numpy as np

from inshade.bundle import UINT_INPUT_RANGE
from inshade.codegen import generate
from inshade.codegen.glsl import INTEGER_DTYPES, TextureResource, UniformBlockResource
from inshade.codegen.limits import LimitError
from inshade.pixels import pixel_uvs

from .programs import ProgramCache
from .render import FullscreenPass, float_target, read_rgba_raw, upload_float_texture

log = logging.getLogger("inshade")
_COMPONENTS_DTYPE = {"f4": "f4", "f2": "f2", "f1": "f1", "nu2": "nu2"}


class GLResourceError(RuntimeError):
    """Creating or uploading a network's GL resource failed (the driver raised or set a GL error)."""


def _describe(res) -> str:
    if isinstance(res, TextureResource):
        return (f"texture {res.name} ({'x'.join(map(str, res.data.shape[-2::-1]))}, {res.data.shape[-1]} channels, "
                f"{res.dtype})")
    return f"uniform block {res.name} ({res.nbytes} B)"


def _check_fits(ctx: moderngl.Context, res) -> None:
    """The driver's own limits, checked before an upload (codegen may have planned with others)."""
    info = ctx.info
    if isinstance(res, TextureResource):
        if res.array:   # layers have their own limit; H and W are 2D sides
            cap = int(info["GL_MAX_ARRAY_TEXTURE_LAYERS"])
            if res.layers > cap:
                raise LimitError(f"{_describe(res)}: {res.layers} layers; this context's GL_MAX_ARRAY_TEXTURE_LAYERS "
                                 f"is {cap}")
        name = "GL_MAX_TEXTURE_SIZE" if res.dims == 2 else "GL_MAX_3D_TEXTURE_SIZE"
        cap, side = int(info[name]), max(res.data.shape[int(res.array):-1])
        if side > cap:
            raise LimitError(f"{_describe(res)}: a side of {side} texels; this context's {name} is {cap}")
    else:
        cap = int(info["GL_MAX_UNIFORM_BLOCK_SIZE"])
        if res.nbytes > cap:
            raise LimitError(f"{_describe(res)}: this context's GL_MAX_UNIFORM_BLOCK_SIZE is {cap}")


def _checked(ctx: moderngl.Context, res, make, new: bool = True):
    """Runs `make()` (a create/upload) and raises GLResourceError naming `res` if moderngl raised
    or the driver recorded a GL error; a new object that failed is released, never handed back."""
    stale = ctx.error   # reading clears it; an error from before belongs to earlier calls
    if stale != "GL_NO_ERROR":
        log.warning("GL error %s was pending before uploading %s", stale, res.name)
    try:
        obj = make()
    except moderngl.Error as exc:
        raise GLResourceError(f"{_describe(res)}: {exc}") from exc
    err = ctx.error
    if err != "GL_NO_ERROR":
        if new:
            obj.release()
        raise GLResourceError(f"{_describe(res)}: the driver reported {err} creating or uploading it")
    return obj


class NetworkResources:
    """GL objects for a Generated network's resources; `bind` uses units/bindings from `first_*`."""

    def __init__(self, ctx: moderngl.Context, generated):
        self.ctx = ctx
        self.textures: dict[str, moderngl.Texture | moderngl.Texture3D] = {}
        self.buffers: dict[str, moderngl.Buffer] = {}
        self.upload(generated)

    def upload(self, generated) -> None:
        """Creates or refreshes every resource; same-shaped uniform blocks are rewritten in
        place, so new weights need no recompile in `ubo` mode."""
        for res in generated.resources:
            if isinstance(res, (UniformBlockResource, TextureResource)):
                _check_fits(self.ctx, res)
            if isinstance(res, UniformBlockResource):
                buf = self.buffers.get(res.name)
                if buf is not None and buf.size == len(res.data):
                    _checked(self.ctx, res, lambda: (buf.write(res.data), buf)[1], new=False)
                else:
                    old = self.buffers.pop(res.name, None)
                    if old is not None:
                        old.release()
                    self.buffers[res.name] = _checked(self.ctx, res, lambda: self.ctx.buffer(res.data))
            elif isinstance(res, TextureResource):
                old = self.textures.pop(res.name, None)
                if old is not None:
                    old.release()
                self.textures[res.name] = _checked(self.ctx, res, lambda: _make_texture(self.ctx, res))

    def bind(self, program: moderngl.Program, first_unit: int = 0, first_block: int = 0) -> int:
        """Binds samplers to consecutive units and blocks to consecutive bindings.
        Returns the next free texture unit. Resources the linker removed are skipped."""
        unit = first_unit
        units = int(self.ctx.info["GL_MAX_TEXTURE_IMAGE_UNITS"])
        for name, tex in self.textures.items():
            if name in program:
                if unit >= units:
                    raise LimitError(f"sampler {name} needs texture unit {unit} (units {first_unit}.. are this "
                                     f"network's); this context's GL_MAX_TEXTURE_IMAGE_UNITS is {units}")
                tex.use(location=unit)
                program[name].value = unit
                unit += 1
        for k, (name, buf) in enumerate(self.buffers.items()):
            if name in program:
                program[name].binding = first_block + k
                buf.bind_to_uniform_block(first_block + k)
        return unit

    def release(self) -> None:
        for obj in [*self.textures.values(), *self.buffers.values()]:
            obj.release()
        self.textures.clear()
        self.buffers.clear()


_NUMPY_DTYPE = {"f4": np.float32, "f2": np.float16, "u4": np.uint32, "u1": np.uint8}   # the bytes GL reads are these


def texture_levels(res: TextureResource) -> list[np.ndarray]:
    """The arrays of every level of ``res`` (base first) as GL reads them; ValueError naming the
    resource and level for a chain that is not a valid mip chain (each level half the previous in
    every spatial axis, floor, at least 1; layers of an array kept; same channels; nothing after
    the 1x1(x1) level)."""
    if res.wrap not in ("clamp", "repeat"):
        raise ValueError(f"texture {res.name}: wrap must be 'clamp' or 'repeat', got {res.wrap!r}")
    lead = int(res.array)   # leading axes that do not halve (an array's layers)
    axes = ("L, " if res.array else "") + ("D, H, W, C" if res.dims == 3 else "H, W, C")
    cast = _NUMPY_DTYPE.get(res.dtype)
    levels = []
    for k, a in enumerate((res.data, *res.mips)):
        a = np.asarray(a)
        if k:
            prev = levels[-1].shape
            if all(n == 1 for n in prev[lead:-1]):
                raise ValueError(f"texture {res.name}: mip level {k}: the chain already ends at "
                                 f"{'x'.join(['1'] * res.dims)} (level {k - 1}); {len(res.mips) + 1} levels given, "
                                 f"at most {k}")
            want = (*prev[:lead], *(max(n // 2, 1) for n in prev[lead:-1]), prev[-1])
            if a.shape != want:
                raise ValueError(f"texture {res.name}: mip level {k} must be [{axes}] = {list(want)} (half of "
                                 f"level {k - 1}, {list(prev)}), got {list(a.shape)}")
            if a.dtype != levels[0].dtype and cast is None:
                raise ValueError(f"texture {res.name}: mip level {k} is {a.dtype}; level 0 is {levels[0].dtype}")
        levels.append(np.ascontiguousarray(a if cast is None else a.astype(cast, copy=False)))
    return levels


def _make_texture(ctx, res: TextureResource):
    levels = texture_levels(res)
    data = levels[0]
    comps = data.shape[-1]
    if res.array:
        layers, h, w = data.shape[:3]
        tex = ctx.texture_array((w, h, layers), comps, data.tobytes(), dtype=res.dtype, alignment=1)
    elif res.dims == 2:
        h, w = data.shape[:2]
        tex = ctx.texture((w, h), comps, data.tobytes(), dtype=res.dtype, alignment=1)
    else:
        dpt, h, w = data.shape[:3]
        tex = ctx.texture3d((w, h, dpt), comps, data.tobytes(), dtype=res.dtype, alignment=1)
        tex.repeat_z = False
    f = moderngl.LINEAR if res.filter == "linear" else moderngl.NEAREST
    if len(levels) > 1 and res.dims == 2 and not res.array and res.dtype not in INTEGER_DTYPES:
        # moderngl has no GL_TEXTURE_MAX_LEVEL setter: build_mipmaps sets base/max level (a chain
        # may stop before 1x1) and allocates the levels, which are then overwritten with ours
        tex.build_mipmaps(0, len(levels) - 1)
        for k, a in enumerate(levels[1:], 1):
            tex.write(a.tobytes(), level=k, alignment=1)
    elif len(levels) > 1:
        # moderngl cannot write a level > 0 of a 3D texture or an array, and build_mipmaps'
        # glGenerateMipmap refuses integer formats: each level is specified directly
        _upload_levels(ctx, tex, 0x8C1A if res.array else 0x806F if res.dims == 3 else 0x0DE1, levels, res.dtype)
    if len(levels) > 1:
        # nearest level, bilinear within it: textureLod(t, uv, k) at integer k reads level k only
        tex.filter = (moderngl.LINEAR_MIPMAP_NEAREST if f == moderngl.LINEAR else moderngl.NEAREST_MIPMAP_NEAREST, f)
    else:
        tex.filter = (f, f)
    tex.repeat_x = tex.repeat_y = res.wrap == "repeat"
    return tex


# GL enums for _upload_levels: pixel type per dtype, client format per channel count
_GL_TYPE = {"f4": 0x1406, "f2": 0x140B, "f1": 0x1401, "nu2": 0x1403, "u4": 0x1405, "u1": 0x1401}
_GL_FORMAT = {1: 0x1903, 2: 0x8227, 3: 0x1907, 4: 0x1908}            # GL_RED, GL_RG, GL_RGB, GL_RGBA
_GL_FORMAT_INT = {1: 0x8D94, 2: 0x8228, 3: 0x8D98, 4: 0x8D99}        # GL_RED_INTEGER ... GL_RGBA_INTEGER


def gl_function(ctx, name: str, restype, *argtypes):
    """A raw GL entry point for the current context: an OSMesa context's own loader, else glvnd's
    libOpenGL / libGL (which dispatch to the current EGL or GLX context), as context.py does."""
    proto = ctypes.CFUNCTYPE(restype, *argtypes)
    loader = ctx.extra.get("loader") if isinstance(ctx.extra, dict) else None
    if loader is not None:
        address = loader.load_opengl_function(name)
        if address:
            return proto(address)
    else:
        for lib in ("libOpenGL.so.0", "libGL.so.1"):
            try:
                return proto((name, ctypes.CDLL(lib)))
            except (OSError, AttributeError):
                continue
    raise GLResourceError(f"cannot load the GL entry point {name} (needed to upload mip levels)")


def _upload_levels(ctx, tex, target: int, levels: list[np.ndarray], dtype: str) -> None:
    """Specifies levels 1.. of a 3D texture (target GL_TEXTURE_3D, levels [D, H, W, C]), a 2D array
    (GL_TEXTURE_2D_ARRAY, [L, H, W, C]) or a 2D texture (GL_TEXTURE_2D, [H, W, C]) with
    glTexImage3D / 2D in the base level's internal format, and sets GL_TEXTURE_MAX_LEVEL to the
    last level (a chain may stop early)."""
    i, u, p = ctypes.c_int, ctypes.c_uint, ctypes.c_void_p
    if target == 0x0DE1:
        image2d = gl_function(ctx, "glTexImage2D", None, u, i, i, i, i, i, u, u, p)

        def tex_image(tgt, k, internal_format, w, h, d, border, fmt, typ, pixels):   # d == 1
            image2d(tgt, k, internal_format, w, h, border, fmt, typ, pixels)
    else:
        tex_image = gl_function(ctx, "glTexImage3D", None, u, i, i, i, i, i, i, u, u, p)
    parameter = gl_function(ctx, "glTexParameteri", None, u, u, i)
    level_parameter = gl_function(ctx, "glGetTexLevelParameteriv", None, u, i, u, ctypes.POINTER(i))
    store = gl_function(ctx, "glPixelStorei", None, u, i)
    bind_buffer = gl_function(ctx, "glBindBuffer", None, u, u)
    tex.use(location=ctx.default_texture_unit)   # binds it to `target` on moderngl's scratch unit
    internal = i()
    level_parameter(target, 0, 0x1003, ctypes.byref(internal))   # GL_TEXTURE_INTERNAL_FORMAT
    bind_buffer(0x88EC, 0)                                       # no GL_PIXEL_UNPACK_BUFFER: read client memory
    store(0x0CF5, 1)                                             # GL_UNPACK_ALIGNMENT
    fmt = (_GL_FORMAT_INT if dtype in INTEGER_DTYPES else _GL_FORMAT)[levels[0].shape[-1]]
    for k, a in enumerate(levels[1:], 1):
        d, h, w = (1, *a.shape[:2]) if a.ndim == 3 else a.shape[:3]
        tex_image(target, k, internal.value, w, h, d, 0, fmt, _GL_TYPE[dtype], a.ctypes.data)
    parameter(target, 0x813D, len(levels) - 1)                   # GL_TEXTURE_MAX_LEVEL


class NetworkEvaluator:
    """Runs `passes/evaluate.frag` over a batch: inputs [N, in_dim] -> outputs [N, out_dim]."""

    def __init__(self, ctx: moderngl.Context, generated, *, version: str = "330",
                 cache: ProgramCache | None = None, width: int = 256):
        if generated.prefix != "net":
            raise ValueError("the evaluate pass calls net_eval: generate with prefix='net'")
        if generated.out_blocks > ctx.info["GL_MAX_DRAW_BUFFERS"]:
            raise ValueError(f"{generated.out_dim} outputs need {generated.out_blocks} draw buffers; "
                             f"this driver has {ctx.info['GL_MAX_DRAW_BUFFERS']}")
        self.ctx, self.generated, self.width = ctx, generated, width
        self.cache = cache if cache is not None else ProgramCache(ctx)
        self.program = self.cache.get("common/fullscreen.vert", "passes/evaluate.frag",
                                      version=version, chunks={"network": generated.chunk})
        self.compile_seconds = self.cache.last_compile_seconds
        self.resources = NetworkResources(ctx, generated)
        self.pass_ = FullscreenPass(ctx, self.program)
        self._fbo = None

    def layout(self, n: int) -> tuple[int, int]:
        w = min(n, self.width)
        return w, math.ceil(n / w)

    def prepare(self, inputs: np.ndarray):
        """Uploads inputs and allocates the target; returns a callable that draws once."""
        inputs = np.asarray(inputs, np.float32)
        g = self.generated
        if inputs.ndim != 2 or inputs.shape[1] != g.in_dim:
            raise ValueError(f"inputs must be [N, {g.in_dim}], got {list(inputs.shape)}")
        n = inputs.shape[0]
        w, h = self.layout(n)
        uint = np.zeros(g.in_dim, bool)
        uint[list(g.uint_lanes)] = True
        padded = np.zeros((w * h, g.in_blocks * 4), np.float32)
        padded[:n, : g.float_in_dim] = inputs[:, ~uint]
        textures = {"u_inputs": upload_float_texture(self.ctx, padded.reshape(h, w * g.in_blocks, 4))}
        if uint.any():   # uint lanes arrive as exact float integers (torch's convention)
            ids = inputs[:, uint]
            if (ids < 0).any() or (ids >= UINT_INPUT_RANGE).any() or (ids != np.floor(ids)).any():
                raise ValueError(f"uint inputs must be integers in 0..{UINT_INPUT_RANGE - 1}")
            packed = np.zeros((w * h, g.in_uint_blocks * 4), np.uint32)
            packed[:n, : len(g.uint_lanes)] = ids.astype(np.uint32)
            textures["u_inputs_uint"] = upload_float_texture(self.ctx, packed.reshape(h, w * g.in_uint_blocks, 4),
                                                             dtype="u4")
        if self._fbo is None or self._fbo.size != (w, h):
            if self._fbo is not None:
                for a in self._fbo.color_attachments:
                    a.release()
                self._fbo.release()
            self._fbo = float_target(self.ctx, w, h, g.out_blocks)
        fbo = self._fbo

        def draw():
            self.ctx.viewport = (0, 0, w, h)
            unit = self.resources.bind(self.program, first_unit=len(textures))
            del unit
            self.pass_.render(fbo, textures=textures)

        draw.release = lambda: [t.release() for t in textures.values()]
        draw.n = n
        return draw

    def read(self, n: int) -> np.ndarray:
        g = self.generated
        outs = [read_rgba_raw(self._fbo, b).reshape(-1, 4) for b in range(g.out_blocks)]
        return np.concatenate(outs, 1)[:n, : g.out_dim]

    def __call__(self, inputs: np.ndarray) -> np.ndarray:
        draw = self.prepare(inputs)
        draw()
        out = self.read(draw.n)
        draw.release()
        return out

    def release(self) -> None:
        self.resources.release()
        if self._fbo is not None:
            for a in self._fbo.color_attachments:
                a.release()
            self._fbo.release()
        self.pass_.vao.release()


def evaluate_on_pixels(bundle, size: int, lut_filter: str = "exact", ctx=None) -> np.ndarray:
    """A 2D field bundle decoded by its generated GLSL through the driver (passes/evaluate.frag)
    at the pixel centres of a ``size`` x ``size`` picture: [H, W, out] float32, image orientation
    (``inshade.pixels``)."""
    from .context import shared_context

    ctx = shared_context() if ctx is None else ctx
    ev = NetworkEvaluator(ctx, generate(bundle, lut_filter=lut_filter), width=min(size, 1024))
    try:
        out = ev(pixel_uvs(size, size).reshape(-1, 2))
    finally:
        ev.release()
    return out.reshape(size, size, -1)
