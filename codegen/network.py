"""Bundle -> one GLSL chunk with a stable signature, its resources and a plan.

    #define NET_IN_DIM ... / NET_IN_BLOCKS / NET_OUT_DIM / NET_OUT_BLOCKS
    void net_eval(in vec4 x[NET_IN_BLOCKS], out vec4 y[NET_OUT_BLOCKS]);

`net` is the prefix (one per network in a program). Inputs arrive concatenated in the
bundle's declaration order, four lanes per vec4; outputs likewise. Same bundle and options
-> same bytes.

A bundle with "uint" inputs (``"dtype": "uint"``, e.g. a triangle id) takes them in their own
array, concatenated in declaration order, and the float inputs as before (NET_IN_DIM counts
float lanes only; NET_IN_BLOCKS is at least 1):

    #define NET_IN_UINT_DIM ... / NET_IN_UINT_BLOCKS
    void net_eval(in uvec4 xu[NET_IN_UINT_BLOCKS], in vec4 x[NET_IN_BLOCKS], out vec4 y[NET_OUT_BLOCKS]);
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from inshade.bundle import Bundle
from inshade.components import registry as component_registry
from inshade.components.dense.spec import OPENGL_STORAGE_MODES, STORAGE_MODES, TEXTURE_FORMATS
from inshade.components.lookup_array.spec import FILTERS
from inshade.envelope import analyse

from .glsl import (EmitContext, PlanRow, StorageBufferResource, TextureResource, UniformBlockResource, blocks,
                   resource_bindings)
from .limits import STORAGE_BUFFERS_RESERVED, LimitError, limit, source
from .plan import Plan
from .registry import EMITTERS, LOWERED, NETWORK_STEPS, OPTIONS, SEPARATE_INPUTS, resolve_options
from . import ir
from .printers.base import Module
from .targets import GL_TARGETS, TARGETS, TargetError, planning_limits
from .targets import target as find_target
from .values import Value, gather

component_registry.load("glsl")

# Short names of the most used options (CLI flags, scene settings): name -> (component type, option).
SHORTHANDS = {"storage": ("dense", "storage"), "lut_filter": ("lookup_array", "filter"),
              "texture_format": ("dense", "texture_format"), "arithmetic": ("dense", "arithmetic")}


@dataclass
class Generated:
    chunk: str            # GLSL text: includes, declarations, the eval function
    function: str         # e.g. "net_eval"
    prefix: str
    in_dim: int
    out_dim: int
    resources: list       # TextureResource | UniformBlockResource, in binding order
    plan: Plan
    uint_lanes: tuple = ()   # lanes of the concatenated input that are uint inputs (argument xu)
    library: tuple = ()      # the library chunks the code includes (beyond OpenGL: pastes)
    module: object = None    # what the printer printed (printers/base.py Module), to print it another way

    @property
    def float_in_dim(self) -> int:
        return self.in_dim - len(self.uint_lanes)

    @property
    def in_blocks(self) -> int:
        return max(1, blocks(self.float_in_dim))

    @property
    def in_uint_blocks(self) -> int:
        return blocks(len(self.uint_lanes))

    @property
    def out_blocks(self) -> int:
        return blocks(self.out_dim)


def generate(bundle: Bundle, *, options: dict | None = None, target: str = "330", prefix: str = "net",
             limits: dict | None = None, calls: int = 1, **shorthands) -> Generated:
    """The bundle's GLSL function, resources and plan.

    ``options``: per component type, e.g. ``{"dense": {"storage": "ubo"}, "lookup_array": {"filter":
    "fast"}}`` (the types and options the emitters declare: ``codegen.registry.OPTIONS``).
    ``storage=``, ``lut_filter=``, ``texture_format=`` are shorthands for the same (``SHORTHANDS``).
    ``limits``: the GL limits to plan against (``auto`` storage chooses by them; every resource is
    laid out to fit them, else LimitError): a dict, e.g. this machine's
    (``runtime.context.machine_limits()``), a context's ``gl_info`` or a target GPU's
    (``{"GL_MAX_TEXTURE_SIZE": 4096}``). A missing limit means the GL 3.3 minimum
    (``codegen.limits.GL33_MINIMUMS``: 16 KiB uniform blocks, 1024-texel textures), so code
    generated without limits runs on every GL 3.3 driver; the plan records each limit's use, value
    and source. ``calls``: how many times one pixel evaluates the function in the caller's loop
    (a march's steps), for a driver that caps a pixel's loop iterations (``limits.loop_iteration_cap``).
    """
    lang = find_target(target)
    merged = {t: dict(v) for t, v in (options or {}).items()}
    for name, value in shorthands.items():
        if name not in SHORTHANDS:
            raise TypeError(f"generate() got an unexpected keyword argument {name!r}")
        component, option = SHORTHANDS[name]
        merged.setdefault(component, {})[option] = value
    options = resolve_options(merged)
    storage, lut_filter = options["dense"]["storage"], options["lookup_array"]["filter"]
    limits = dict(limits or {}) if lang.opengl else planning_limits(lang, limits)
    if not lang.opengl:
        refuse_unlowered(bundle, target)
    ctx = EmitContext(prefix, target, options, limits)
    ctx.periodic_args = analyse(bundle).periodic_args
    fused = {}
    for step in NETWORK_STEPS.values():
        fused.update(step.begin(ctx, bundle, calls))
    inner = {i for f in fused.values() for i in f.ids}

    values, off, uint_lanes, lane = {}, {"float": 0, "uint": 0}, [], 0
    for p in bundle.inputs:
        values[p.name] = Value("x" if p.dtype == "float" else "xu", off[p.dtype], p.dim, p.dtype)
        off[p.dtype] += p.dim
        uint_lanes += range(lane, lane + p.dim) if p.dtype == "uint" else []
        lane += p.dim
    for node in bundle.nodes:
        if node.id in inner and node.id not in fused:
            continue   # emitted with its first node (nothing outside reads the nodes inside)
        sources = [values[s] for s in node.inputs]
        src = sources if node.type in SEPARATE_INPUTS else gather(ctx, f"c_{node.id}", sources)
        if node.id in fused:
            values[fused[node.id].output] = fused[node.id].emit(ctx, src, bundle)
        else:
            values[node.id] = EMITTERS[node.type](ctx, node, src, bundle)
    result = gather(ctx, "r_out", [values[p.node] for p in bundle.outputs])
    for step in NETWORK_STEPS.values():
        step.end(ctx)

    n_uint = len(uint_lanes)
    up = prefix.upper()
    ins = ", ".join(f"{p.name}[{p.dim}]" + (" uint" if p.dtype == "uint" else "") for p in bundle.inputs)
    outs = ", ".join(f"{p.name}[{p.dim}] <- {p.node}" for p in bundle.outputs)
    module = Module(
        prefix, [f"// inshade network '{bundle.name}' (kind {bundle.kind}), generated by inshade.codegen",
                 f"// inputs: {ins}; outputs: {outs}",
                 f"// target {target}, storage {storage}, lookup filter {lut_filter}"
                 + (f", arithmetic {options['dense']['arithmetic']}" if ctx.enables else "")],
        [(f"{up}_IN_DIM", bundle.in_dim - n_uint), (f"{up}_IN_BLOCKS", max(1, blocks(bundle.in_dim - n_uint))),
         *([(f"{up}_IN_UINT_DIM", n_uint), (f"{up}_IN_UINT_BLOCKS", blocks(n_uint))] if n_uint else []),
         (f"{up}_OUT_DIM", bundle.out_dim), (f"{up}_OUT_BLOCKS", blocks(bundle.out_dim))],
        ctx.includes, ctx.globals, ctx.body, max(1, blocks(bundle.in_dim - n_uint)), blocks(bundle.out_dim),
        blocks(n_uint), result.array, resource_bindings(ctx.resources), tuple(sorted(ctx.enables)))
    text = lang.printer.module(module)
    textures = [g.name for g in ctx.globals if isinstance(g, ir.Texture)]
    plan = Plan(bundle.name, target, ctx.plan, ctx.resources, check_limits(ctx.resources, text.splitlines(), limits,
                                                                           textures), calls)
    return Generated(text, f"{prefix}_eval", prefix, bundle.in_dim, bundle.out_dim, ctx.resources, plan,
                     tuple(uint_lanes), tuple(ctx.includes), module)


def refuse_unlowered(bundle: Bundle, target: str) -> None:
    """A target other than OpenGL's GLSL takes only components lowered for every printer: one line
    naming the first node that is not, and what is."""
    for node in bundle.nodes:
        if node.type not in LOWERED:
            raise TargetError(f"node {node.id}: component {node.type!r} has no {target} lowering yet "
                              f"(lowered for every target: {', '.join(sorted(LOWERED))}); "
                              "targets 330, 450 and es300 take every component")


_SAMPLER = re.compile(r"^\s*uniform\s+(\w*sampler\w*)\s+(\w+)")


def check_limits(resources: list, lines: list[str], limits: dict, textures: list[str] = ()) -> dict:
    """What the generated code uses of each GL limit it depends on, checked: every texture side,
    every uniform block, the number of blocks and of samplers (every sampler the code declares).
    Returns {limit: {"uses", "limit", "source"}} for the plan; raises LimitError on the first
    limit exceeded (emitters choose layouts that fit, so this is the last line of defence)."""
    tex2 = [r for r in resources if isinstance(r, TextureResource) and r.dims == 2]
    tex3 = [r for r in resources if isinstance(r, TextureResource) and r.dims == 3]
    ubos = [r for r in resources if isinstance(r, UniformBlockResource)]
    samplers = list(dict.fromkeys([m.group(2) for line in lines for m in [_SAMPLER.match(line)] if m] + list(textures)))
    side = lambda r: max(r.data.shape[int(r.array):-1])  # noqa: E731  (an array's layers are no side)
    layers = [r for r in tex2 if r.array]
    uses = {
        "GL_MAX_TEXTURE_SIZE": (max(tex2, key=side, default=None), max((side(r) for r in tex2), default=0),
                                "texture side"),
        "GL_MAX_3D_TEXTURE_SIZE": (max(tex3, key=side, default=None), max((side(r) for r in tex3), default=0),
                                   "3D texture side"),
        "GL_MAX_ARRAY_TEXTURE_LAYERS": (max(layers, key=lambda r: r.data.shape[0], default=None),
                                        max((r.data.shape[0] for r in layers), default=0), "array layers"),
        "GL_MAX_UNIFORM_BLOCK_SIZE": (max(ubos, key=lambda r: r.nbytes, default=None),
                                      max((r.nbytes for r in ubos), default=0), "uniform block bytes"),
        "GL_MAX_FRAGMENT_UNIFORM_BLOCKS": (None, len(ubos), "uniform blocks"),
        "GL_MAX_TEXTURE_IMAGE_UNITS": (None, len(samplers), "samplers"),
        "GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS": (None, len(samplers), "samplers"),
        # only samplers (opaque) live in the default uniform block; weights are literals, blocks or textures
        "GL_MAX_FRAGMENT_UNIFORM_COMPONENTS": (None, 0, "default-block uniform components"),
    }
    ssbos = [r for r in resources if isinstance(r, StorageBufferResource)]
    if ssbos:   # only where the language has them (codegen/targets.py)
        uses["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"] = (max(ssbos, key=lambda r: r.nbytes), max(r.nbytes for r in ssbos),
                                                    "storage buffer bytes")
        uses["GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS"] = (None, len(ssbos) + STORAGE_BUFFERS_RESERVED,
                                                         f"storage buffers ({STORAGE_BUFFERS_RESERVED} for the caller's "
                                                         "inputs and outputs)")
    out = {}
    for name, (res, used, what) in uses.items():
        cap = limit(limits, name)
        if used > cap:
            who = f"resource {res.name}" if res is not None else (
                f"samplers {', '.join(samplers)}" if "sampler" in what else what)
            shape = f" ({'x'.join(map(str, res.data.shape[-2::-1]))})" if isinstance(res, TextureResource) else ""
            raise LimitError(f"{who}{shape}: needs {what} {used}; {name} is {cap} ({source(limits, name)})")
        out[name] = {"uses": used, "limit": cap, "source": source(limits, name)}
    return out


__all__ = ["generate", "Generated", "TARGETS", "GL_TARGETS", "STORAGE_MODES", "OPENGL_STORAGE_MODES", "FILTERS", "TEXTURE_FORMATS", "OPTIONS",
           "SHORTHANDS", "PlanRow", "LimitError"]
