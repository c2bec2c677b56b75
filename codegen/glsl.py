"""GLSL literal formatting and the per-network emission context."""
from __future__ import annotations

import math

from dataclasses import dataclass, field

import numpy as np


def flt(v) -> str:
    """A float32 value as a GLSL float literal that round-trips (%.9g)."""
    v = float(np.float32(v))
    if not np.isfinite(v):
        raise ValueError(f"non-finite value {v} cannot be written as GLSL")
    s = "%.9g" % v
    if not any(ch in s for ch in ".e"):
        s += ".0"
    return s


def vec4(values) -> str:
    return "vec4(" + ", ".join(flt(v) for v in values) + ")"


def mat4(block: np.ndarray) -> str:
    """A torch-layout [out=4, in=4] block as a column-major GLSL mat4 (block.T flattened)."""
    return "mat4(" + ", ".join(flt(v) for v in np.asarray(block, np.float32).T.reshape(-1)) + ")"


def blocks(dim: int) -> int:
    return (dim + 3) // 4


def lane(array: str, index: int) -> str:
    return f"{array}[{index // 4}].{'xyzw'[index % 4]}"


INTEGER_DTYPES = ("u4", "u1")   # texture dtypes whose texels are uints


@dataclass
class TextureResource:
    """A texture the generated code samples: data [H, W, C] (2D) or [D, H, W, C] (3D), C = 1..4
    (R, RG, RGB, RGBA), moderngl dtype ('f4', 'f2' = half float, 'f1' = unorm8, 'nu2' = unorm16,
    'u4' / 'u1' = unsigned integer R32UI..RGBA32UI / R8UI..RGBA8UI, declared ``usampler*``, read with
    texelFetch, always nearest), filter 'nearest'|'linear' (within a level), ``wrap`` 'clamp'|'repeat'.

    ``mips``: levels 1.. of a mip chain (level k is [H >> k, W >> k, C] in 2D, [D >> k, H >> k,
    W >> k, C] in 3D, floor, at least 1; same dtype), uploaded as given (never GL-built, so torch
    and GLSL see the same texels); with mips the minification filter picks the nearest level
    (``textureLod`` at an integer level = bilinear within it; ``texelFetch(t, p, k)`` reads level k).

    ``array``: data [L, H, W, C] is a 2D texture array of L layers (``sampler2DArray`` /
    ``usampler2DArray``, layer = the third coordinate); mips then halve H and W only, per layer."""

    name: str
    data: np.ndarray
    dtype: str
    filter: str = "nearest"
    mips: tuple = ()
    wrap: str = "clamp"
    array: bool = False

    def __post_init__(self):
        if self.dtype in INTEGER_DTYPES and self.filter != "nearest":
            raise ValueError(f"texture {self.name}: integer ({self.dtype}) textures are read unfiltered: filter must be "
                             "'nearest'")
        if self.array and np.ndim(self.data) != 4:
            raise ValueError(f"texture {self.name}: a texture array's data is [L, H, W, C], got {list(np.shape(self.data))}")

    @property
    def dims(self) -> int:
        """2 for 2D textures and 2D texture arrays, 3 for 3D textures."""
        return self.data.ndim - 1 - int(self.array)

    @property
    def layers(self) -> int:
        """Layers of a texture array (1 otherwise)."""
        return self.data.shape[0] if self.array else 1

    @property
    def levels(self) -> int:
        return 1 + len(self.mips)

    @property
    def nbytes(self) -> int:
        size = {"f4": 4, "f2": 2, "f1": 1, "nu2": 2, "u4": 4, "u1": 1}[self.dtype]
        return sum(int(np.prod(a.shape)) * size for a in (self.data, *self.mips))


@dataclass
class UniformBlockResource:
    """A std140 uniform block: the bytes to upload and the block's name in the program; ``instance``
    and ``members`` ((type, name, count), ...) say how the code names it and its arrays (for a
    driver that binds a block by its members rather than its bytes)."""

    name: str
    data: bytes
    instance: str = ""
    members: tuple = ()

    @property
    def nbytes(self) -> int:
        return len(self.data)


@dataclass
class StorageBufferResource:
    """A read-only storage buffer (std430; for the vec4 / mat4 arrays it holds, the same bytes as
    std140): what a uniform block holds, past a uniform block's size cap, where the language has
    storage buffers (Vulkan, WebGPU, D3D's StructuredBuffer)."""

    name: str
    data: bytes
    instance: str = ""
    members: tuple = ()

    @property
    def nbytes(self) -> int:
        return len(self.data)


SAMPLER_SUFFIX = "_sampler"   # a filtered texture's sampler, where a language keeps samplers apart


def resource_bindings(resources: list) -> dict:
    """Where each resource is bound in a language with explicit bindings (Vulkan, WebGPU, D3D): the
    resources in order, then a sampler for each linearly filtered texture (``<texture>_sampler``:
    its filter and wrap), in the same order."""
    out = {r.name: i for i, r in enumerate(resources)}
    filtered = [r.name for r in resources if isinstance(r, TextureResource) and r.filter == "linear"]
    out.update({name + SAMPLER_SUFFIX: len(resources) + i for i, name in enumerate(filtered)})
    return out


@dataclass
class PlanRow:
    node: str
    type: str
    shape: str
    storage: str = "-"
    why: str = ""
    params: int = 0
    flops: int = 0
    fetches: int = 0
    uniform_bytes: int = 0
    texture_bytes: int = 0


@dataclass
class EmitContext:
    prefix: str
    target: str
    options: dict              # component type -> option -> value (registry.resolve_options)
    limits: dict
    globals: list[str] = field(default_factory=list)
    body: list[str] = field(default_factory=list)
    includes: list[str] = field(default_factory=list)
    resources: list = field(default_factory=list)
    plan: list[PlanRow] = field(default_factory=list)
    storage: dict = field(default_factory=dict)   # dense node id -> (mode, why)
    loop_chunks: dict = field(default_factory=dict)   # looped dense node id -> (blocks per iteration, why)
    periodic_args: dict = field(default_factory=dict)  # sin/cos/frequency node id -> |argument| bounds (envelope)
    enables: set = field(default_factory=set)   # language features the code needs ("f16": float16 arithmetic)

    def periodic(self, fn: str, node_id: str, group: int = 0) -> str:
        """``fn`` ("sin" / "cos") as this call should spell it: the range-reduced form
        (lib/activations) where the plan's bound of the argument passes pi, else the built-in."""
        bounds = self.periodic_args.get(node_id)
        bound = bounds[group] if bounds else math.inf
        if not bound <= math.pi:   # nan / inf: unbounded
            self.include("lib/activations")
            return f"inshade_{fn}"
        return fn

    def option(self, component_type: str, name: str):
        return self.options[component_type][name]

    def include(self, chunk: str) -> None:
        if chunk not in self.includes:
            self.includes.append(chunk)

    def name(self, *parts: str) -> str:
        return "_".join((self.prefix,) + parts)
