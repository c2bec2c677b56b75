"""The dense layer: the plan of a network's dense layers -- where each layer's weights live (storage),
which layers loop and how many output blocks a pass of a loop does, the weights packed as mat4 blocks,
std140 blocks and the weight texture. Why the numbers below: emit.py.
"""
from __future__ import annotations

import numpy as np

from inshade.codegen.glsl import TextureResource, blocks
from inshade.components.dense.spec import I8_TEXELS
from inshade.codegen.limits import STORAGE_BUFFERS_RESERVED, LimitError, limit, loop_iteration_cap, source

UBO_UNROLL_MAX_BLOCKS = 32   # ubo layers with more mat4 blocks loop (llvmpipe JIT time explodes
                             # on unrolled UBO gathers: 32x3 took minutes); GPUs don't mind loops
LOOP_CHUNK = {"ubo": 2, "ssbo": 2, "texture": 1}  # output blocks unrolled inside a loop (measured best)
# On a software renderer a looped layer's inputs are written out up to this many blocks (1024 lanes),
# not looped over: an array read at a loop index is a per-lane gather on llvmpipe (a 512-wide layer's
# check took 168 s to compile looping over its inputs, 13 s with them written out). GPU compilers
# unroll such loops as they see fit, and Chromium's SwiftShader WebGL2 loses its context on the
# written-out form of a 91 -> 32 x 7 UBO network that it runs looped.
INPUTS_WRITTEN_MAX = 256
UNROLL_MAX_BLOCKS = 4096     # inline layers beyond this loop over a const array instead
# auto: whole networks at most this many floats become literals. On GPUs (4096, ~ 32 wide x 3)
# UBOs are as fast as literals and compile in a fraction of the time. On software renderers
# (llvmpipe) literals are 10-20x faster than UBO/texture gathers and their JIT (a few seconds
# for 64x4, ~14k floats) is no slower than the UBO JIT, so literals go up to ~64x5; beyond
# that the JIT grows superlinearly (128x3: over a minute) and texture loops win.
# Cold first draws (empty Mesa shader cache, llvmpipe 2 cores) of the shipped assets keep this rule:
# a 64x4 image net inline 6 s / ubo 16 s / texture 6 s; 64x5 nets inside ray-marched lit scenes
# inline 49-62 s / ubo 118->300 s / texture 26-60 s with 3-7x slower frames; so the runtime says
# "compiling ..." before such a draw rather than trading frame time for a shorter first one.
INLINE_MAX_FLOATS = 4096
INLINE_MAX_FLOATS_SOFTWARE = 20000
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "lavapipe")
UBO_RESERVED_BLOCKS = 2      # auto: blocks left for the host program's own uniforms



def pack(weight: np.ndarray, bias: np.ndarray | None):
    """[out, in] weights -> blocks [OB, IB, 4, 4] (torch layout per block), bias [OB, 4]."""
    out_dim, in_dim = weight.shape
    ob, ib = blocks(out_dim), blocks(in_dim)
    w = np.zeros((ob * 4, ib * 4), np.float32)
    w[:out_dim, :in_dim] = weight
    b = np.zeros(ob * 4, np.float32)
    if bias is not None:
        b[:out_dim] = bias
    return w.reshape(ob, 4, ib, 4).transpose(0, 2, 1, 3), b.reshape(ob, 4)


def pack_rows(values: np.ndarray, ob: int) -> np.ndarray:
    """A value per output row [out] -> [OB, 4] (padding rows 0)."""
    v = np.zeros(ob * 4, np.float32)
    v[:len(values)] = values
    return v.reshape(ob, 4)


def std140(wblocks: np.ndarray, bias: np.ndarray) -> bytes:
    """mat4 W[OB*IB] (column-major, 64 B each) followed by vec4 b[OB]."""
    cols = np.ascontiguousarray(wblocks.transpose(0, 1, 3, 2))  # [OB, IB, col, row]
    return cols.astype("<f4").tobytes() + bias.astype("<f4").tobytes()


def is_software(limits: dict) -> bool:
    """Whether the plan is for a software renderer (llvmpipe and the like), by the limits' own say or
    the renderer's name."""
    renderer = str(limits.get("renderer", limits.get("GL_RENDERER", ""))).lower()
    return bool(limits.get("software", any(s in renderer for s in SOFTWARE_RENDERERS)))


def inputs_written_max(limits: dict) -> int:
    """Input blocks a looped layer writes out rather than loops over (INPUTS_WRITTEN_MAX)."""
    return INPUTS_WRITTEN_MAX if is_software(limits) else 0


def looped(mode: str, ob: int, ib: int) -> bool:
    """Whether a layer of ob x ib mat4 blocks stored as ``mode`` loops rather than unrolls."""
    return (mode == "texture" or (mode in BLOCK_LIMITS and ob * ib > UBO_UNROLL_MAX_BLOCKS)
            or (mode == "inline" and ob * ib > UNROLL_MAX_BLOCKS))


def choose_storage(bundle, requested: str, limits: dict) -> dict[str, tuple[str, str]]:
    """Storage per dense node, with the reason the plan report prints."""
    dense = [n for n in bundle.nodes if n.type == "dense"]
    if requested in BLOCK_LIMITS:
        _check_blocks(dense, requested, limits)
    if requested != "auto":
        return {n.id: (requested, "requested") for n in dense}
    floats = sum(blocks(n.in_dim) * blocks(n.out_dim) * 16 + blocks(n.out_dim) * 4 for n in dense)
    software = is_software(limits)
    inline_max = INLINE_MAX_FLOATS_SOFTWARE if software else INLINE_MAX_FLOATS
    if floats <= inline_max:
        why = (f"network has {floats} floats <= {inline_max}: literals compile quickly"
               + (" and run 10x+ faster than gathers on a software renderer" if software else ""))
        return {n.id: ("inline", why) for n in dense}
    max_bytes = limit(limits, "GL_MAX_UNIFORM_BLOCK_SIZE")
    free_blocks = limit(limits, "GL_MAX_FRAGMENT_UNIFORM_BLOCKS") - UBO_RESERVED_BLOCKS
    out = {}
    if software:  # UBO loads are per-lane gathers with a slow JIT there; texture loops are leaner
        return {n.id: ("texture", f"network has {floats} floats > {inline_max}; software renderer: "
                                  "texture loops JIT fastest") for n in dense}
    for n in dense:
        size = ubo_bytes(n)
        if size <= max_bytes and free_blocks > 0:
            free_blocks -= 1
            out[n.id] = ("ubo", f"{size} B fits GL_MAX_UNIFORM_BLOCK_SIZE={max_bytes}")
        elif size > max_bytes:
            out[n.id] = ("texture", f"{size} B exceeds GL_MAX_UNIFORM_BLOCK_SIZE={max_bytes}")
        else:
            out[n.id] = ("texture", "no uniform block binding left (GL_MAX_FRAGMENT_UNIFORM_BLOCKS)")
    return out


def loop_chunks(bundle, storage: dict, limits: dict, calls: int = 1) -> dict[str, tuple[int, str]]:
    """Output blocks per iteration of each looped dense layer, and why. A driver that caps a
    pixel's loop iterations (limits.loop_iteration_cap) must fit ``calls`` evaluations (a march's
    steps, each one iteration of the caller's loop) of every loop here: the layers with the most
    iterations unroll more (chunk x2, up to no loop over outputs) until they fit, else LimitError.
    Runs folded into a loop over layers add an iteration a layer: emit_layer_loop.fold_runs folds
    only while those fit the same budget."""
    chunks, shapes = {}, {}
    for n in bundle.nodes:
        if n.type != "dense":
            continue
        mode = storage[n.id][0]
        ob, ib = blocks(n.out_dim), blocks(n.in_dim)
        if looped(mode, ob, ib):
            chunk = LOOP_CHUNK.get(mode, 1)
            chunks[n.id], shapes[n.id] = (chunk if ob % chunk == 0 else 1), (ob, ib)
    cap = loop_iteration_cap(limits)
    if cap is None or not chunks:
        return {k: (c, "") for k, c in chunks.items()}

    def count(k):
        return loop_iterations(*shapes[k], chunks[k], inputs_written_max(limits))
    budget, base = loop_budget(cap, calls), dict(chunks)
    while sum(count(k) for k in chunks) > budget:
        open_ = [k for k in chunks if chunks[k] < shapes[k][0]]
        if not open_:
            raise LimitError(f"nodes {', '.join(chunks)}: {sum(count(k) for k in chunks)} loop iterations per "
                             f"evaluation x {calls} evaluations per pixel exceed this driver's {cap} (it ends "
                             f"every loop of a pixel there); use fewer march steps or a narrower network")
        k = max(open_, key=count)
        ob = shapes[k][0]
        chunks[k] = chunks[k] * 2 if ob % (chunks[k] * 2) == 0 else ob
    why = (f"; unrolled x{{}}: this driver ends a pixel's loops after {cap} iterations in all, "
           f"and the caller evaluates this network {calls} times")
    return {k: (c, why.format(c) if c != base[k] else "") for k, c in chunks.items()}


def loop_iterations(ob: int, ib: int, chunk: int, written: int) -> int:
    """A looped layer's iterations per evaluation: the loop over outputs (unless one pass does
    them all), and per pass the loop over inputs unless they are ``written`` out (emit_products.loop_statement)."""
    passes = max(1, ob // chunk)
    return (passes if ob > chunk else 0) + passes * (ib if ib > written else 0)


def loop_budget(cap: int, calls: int) -> int:
    """Loop iterations one evaluation may take when the caller's loop runs it ``calls`` times
    (each of the caller's iterations counts too)."""
    return max(0, (cap - calls) // calls)


def ubo_bytes(node) -> int:
    """Size of a dense layer's std140 block: mat4 W[OB*IB] + vec4 b[OB] (f16: two uvec4 a mat4 block;
    i8: one, and the row scales vec4 s[OB]: emit_packed.py)."""
    precision = node.params.get("precision", "f32")
    ob, ib = blocks(node.out_dim), blocks(node.in_dim)
    return ob * ib * {"f32": 64, "f16": 32, "i8": 16}[precision] + ob * (32 if precision == "i8" else 16)


# a layer in a block of its own, by storage: (the block's size limit, the blocks-per-stage limit, what
# the block is (one, several), blocks the stage keeps for the caller)
BLOCK_LIMITS = {
    "ubo": ("GL_MAX_UNIFORM_BLOCK_SIZE", "GL_MAX_FRAGMENT_UNIFORM_BLOCKS", ("a uniform block", "uniform blocks"), 0),
    "ssbo": ("GL_MAX_SHADER_STORAGE_BLOCK_SIZE", "GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS",
             ("a storage buffer", "storage buffers"), STORAGE_BUFFERS_RESERVED),
}


def _check_blocks(dense, mode: str, limits: dict) -> None:
    """Explicit `ubo` / `ssbo` storage: every block within its size limit, and no more blocks (one per
    layer, beside those the caller keeps) than a stage binds."""
    size_name, count_name, (one, several), reserved = BLOCK_LIMITS[mode]
    max_bytes = limit(limits, size_name)
    for n in dense:
        size = ubo_bytes(n)
        if size > max_bytes:
            raise LimitError(f"node {n.id}: dense {n.in_dim} -> {n.out_dim} as {one} needs {size} B; "
                             f"{size_name} is {max_bytes} ({source(limits, size_name)}); use storage 'texture' or 'auto'")
    max_blocks = limit(limits, count_name)
    if len(dense) + reserved > max_blocks:
        kept = f" beside the {reserved} the caller keeps" if reserved else ""
        raise LimitError(f"nodes {', '.join(n.id for n in dense)}: {len(dense)} dense layers as {several} "
                         f"need {len(dense)} blocks{kept}; {count_name} is {max_blocks} ({source(limits, count_name)}); "
                         "use storage 'texture' or 'auto'")


# the weight texture's texel format by the layer's precision (f32: the texture_format option's)
PRECISION_FORMATS = {"f16": "f2", "i8": "i8"}
I8_OFFSET = 128   # an i8 code q is stored as the byte q + 128 (spec.I8_TEXELS says in which texels)


def weight_format(ctx, node) -> str:
    """The texture a layer stored as texture rows goes in: f4 / f2 (float rows, the bias first) or i8
    (its codes, offset to unsigned: the bias and row scales are literals)."""
    return PRECISION_FORMATS.get(node.params.get("precision", "f32"), ctx.option("dense", "texture_format"))


def weight_texture(ctx, fmt: str) -> "WeightTexture":
    """The network's weight texture of format ``fmt`` (made on first use): the texture_format option's is
    ``weights``, another ``weights_<fmt>``."""
    if fmt not in ctx.weight_textures:
        own = fmt == ctx.option("dense", "texture_format")
        ctx.weight_textures[fmt] = WeightTexture(ctx, fmt, "weights" if own else f"weights_{fmt}")
    return ctx.weight_textures[fmt]


class WeightTexture:
    """A texture of the network's texture-stored layers of one format, a row per output block:
    float rows (f4, f2): texel 0 = bias, texels 1 + 4*i .. 4 + 4*i = the columns of block (o, i);
    i8 rows: texels 4*i .. 3 + 4*i = the columns of block (o, i) as codes + 128 (bytes: RGBA8UI or
    RGBA8 unorm, the dense option i8_texels), and in a float texture beside it (``<name>_rows``,
    RGBA32F) the row's bias (texel 0) and scales (texel 1): read from a texture, not literal arrays,
    whose indexing in a loop llvmpipe compiles many times slower."""

    def __init__(self, ctx, fmt: str = "f4", name: str = "weights"):
        self.ctx, self.fmt, self.rows, self.nodes, self.side = ctx, fmt, [], [], []
        self.name = ctx.name(name)
        self.side_name = f"{self.name}_rows"

    @property
    def bias_texels(self) -> int:
        return 0 if self.fmt == "i8" else 1

    def add(self, wblocks, bias, node_id: str = "?", scale=None) -> int:
        """The layer's rows (i8: ``wblocks`` are the dequantized weights and ``scale`` their rows'
        scales [OB, 4], of which the codes are taken); returns its first row."""
        self.nodes.append(node_id)
        row0 = len(self.rows)
        for o in range(wblocks.shape[0]):
            cols = wblocks[o].transpose(0, 2, 1).reshape(-1, 4)  # [IB*4 columns, 4 rows]
            if self.fmt == "i8":
                self.rows.append(np.rint(cols / np.where(scale[o] > 0, scale[o], 1.0)) + I8_OFFSET)
                self.side.append(np.stack([bias[o], scale[o]]))
            else:
                self.rows.append(np.concatenate([bias[o][None], cols], 0))
        return row0

    def resource(self) -> TextureResource | None:
        if not self.rows:
            return None
        width = max(len(r) for r in self.rows)
        limits = getattr(self.ctx, "limits", {})
        name, cap = "GL_MAX_TEXTURE_SIZE", limit(limits, "GL_MAX_TEXTURE_SIZE")
        if width > cap or len(self.rows) > cap:
            layers = ", ".join(self.nodes)
            raise LimitError(f"node(s) {layers}: the dense weight texture needs {width}x{len(self.rows)} texels "
                             f"({self.bias_texels} + 4 per input block wide, a row per output block); {name} is "
                             f"{cap} ({source(limits, name)}); use storage 'inline' or 'ubo' for some layers")
        dtype = {"f4": np.float32, "f2": np.float16, "i8": np.uint8}[self.fmt]
        data = np.full((len(self.rows), width, 4), I8_OFFSET if self.fmt == "i8" else 0, dtype)
        for y, r in enumerate(self.rows):
            data[y, : len(r)] = r
        dtype = I8_TEXELS[self.ctx.option("dense", "i8_texels")] if self.fmt == "i8" else self.fmt
        return TextureResource(self.name, data, dtype, "nearest")

    def side_resource(self) -> TextureResource | None:
        """The i8 rows' biases and scales (RGBA32F, [rows, 2]); None for float rows."""
        if not self.side:
            return None
        return TextureResource(self.side_name, np.asarray(self.side, np.float32), "f4", "nearest")
