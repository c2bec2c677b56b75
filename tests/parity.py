"""Parity harness: the torch reference (what the bundle says) against the generated GLSL run
through the real driver, plus reusable hypothesis strategies that build random graphs.

THE TOLERANCE RULE (used by every parity test, fp32 paths):

    |glsl - torch| <= TOL * max(1, |torch|)   elementwise, TOL = 1e-5

i.e. "1e-5 absolute on outputs of unit scale, relative beyond". Both sides compute in fp32
but sum in different orders (torch's GEMM vs mat4 * vec4 blocks) and use different
transcendental implementations (llvmpipe's sin/exp/log are polynomial approximations), so
bit-exactness is not expected; 1e-5 is ~100 ulp at unit scale and holds for every
architecture the strategies below generate. Instead of loosening it, the generators bound
what would need a looser rule (see `mlp_specs`): pre-activations of `exp` and `sin(omega0 .)`
are kept small (SIREN-style init), `omega0 <= 30`, inputs lie in [-1, 1], and frequency
encodings use `n_freqs <= 8` (the argument 2^7 pi ~ 402 is where llvmpipe's sin argument
reduction still agrees with torch's to ~1e-6; beyond ~2^10 pi it does not).

Where the network itself is ill-conditioned (a lookup cascade whose second table is steep where the
first one's rounding lands, a SIREN), torch's fp32 answer is itself farther than the rule from the
exact one; such tests pass `conditioned=True`: the GLSL output then also passes when it is no farther
from the float64 answer (the module in double precision) than ``CONDITIONING`` times torch's fp32
answer is, the rule `inshade check` applies to imported networks.

Paths that are not fp32 state their own bound next to the test and say why: the fp16 weight
texture (compared with a reference whose weights are rounded to fp16 first, so the same rule
applies) and the hardware-filtered ("fast") lookup path (tests/components/test_lookup_array.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import torch
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from inshade.codegen import generate
from inshade.codegen.glsl import blocks
from inshade.components import ACTIVATIONS
from inshade.components.dense.torch_twin import Dense
from inshade.components.elementwise.torch_twin import (ELU, GELU, Abs, Clamp, Cos, Erf, Exp, Expm1, Identity, LeakyReLU,
                                                       ReLU, Sigmoid, SiLU, Sin, Softplus, Tanh)
from inshade.convert.check import CONDITIONING
from inshade.models import GraphModule

TOL = 1e-5

# Program compiles dominate run time on llvmpipe (the first draw JIT-compiles the shader), so
# every property test runs few examples; shrinking is cheap because examples are small.
PARITY_SETTINGS = dict(deadline=None, derandomize=False, print_blob=True,
                       suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                              HealthCheck.function_scoped_fixture])


def parity_settings(max_examples: int):
    return settings(max_examples=max_examples, **PARITY_SETTINGS)


# --- the rule ---------------------------------------------------------------------------------

def scaled_error(glsl: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """|glsl - torch| / max(1, |torch|), elementwise (NaN where either side is non-finite)."""
    glsl = np.asarray(glsl, np.float64)
    ref = np.asarray(ref, np.float64)
    err = np.abs(glsl - ref) / np.maximum(1.0, np.abs(ref))
    return np.where(np.isfinite(glsl) & np.isfinite(ref), err, np.nan)


def assert_parity(glsl: np.ndarray, ref: np.ndarray, tol: float = TOL, what: str = "") -> float:
    """Asserts the tolerance rule; returns the max scaled error. The message names the worst
    element, its two values and the max absolute error."""
    glsl, ref = np.asarray(glsl), np.asarray(ref)
    assert glsl.shape == ref.shape, f"{what}: shape {glsl.shape} != reference {ref.shape}"
    assert np.isfinite(ref).all(), f"{what}: the torch reference is not finite (bad generator)"
    err = scaled_error(glsl, ref)
    if np.isnan(err).any():
        bad = np.argwhere(np.isnan(err))[0]
        raise AssertionError(f"{what}: GLSL output not finite at {tuple(bad)}: {glsl[tuple(bad)]}")
    worst = np.unravel_index(np.argmax(err), err.shape) if err.size else ()
    max_err = float(err.max()) if err.size else 0.0
    max_abs = float(np.abs(glsl.astype(np.float64) - ref).max()) if err.size else 0.0
    assert max_err <= tol, (
        f"{what}: max |glsl - torch| / max(1, |torch|) = {max_err:.3g} > {tol:g} at {tuple(worst)} "
        f"(glsl {glsl[worst]!r}, torch {ref[worst]!r}); max abs error {max_abs:.3g}, "
        f"max |torch| {float(np.abs(ref).max()):.3g}")
    return max_err


# --- the two executors ------------------------------------------------------------------------

def torch_reference(bundle, x: np.ndarray, float64: bool = False) -> np.ndarray:
    """What the bundle says: the module rebuilt from the bundle (not the one that exported it),
    in double precision when `float64` (its fp32 weights widened exactly)."""
    module = GraphModule.from_bundle(bundle)
    dtype = torch.float64 if float64 else torch.float32
    with torch.no_grad():
        return module.to(dtype)(torch.from_numpy(np.asarray(x, np.float32)).to(dtype)).numpy()


def glsl_eval(ctx, bundle_or_generated, x: np.ndarray, *, version: str = "330", **gen) -> np.ndarray:
    """Generates (unless given a Generated) and runs `passes/evaluate.frag` over x [N, in_dim].
    Releases every GL object it made, the program included."""
    from inshade.runtime.network import NetworkEvaluator

    generated = bundle_or_generated
    if not hasattr(generated, "chunk"):
        generated = generate(bundle_or_generated, target=version, **gen)
    ev = NetworkEvaluator(ctx, generated, version=version)
    try:
        return ev(np.asarray(x, np.float32))
    finally:
        ev.release()
        ev.program.release()


def check_parity(ctx, bundle, x, *, tol: float = TOL, reference=None, what: str = "", conditioned: bool = False,
                 **gen) -> float:
    """torch (from the bundle, or `reference` if given) vs GLSL under the rule; returns max error.
    `conditioned`: past the rule, the conditioning rule decides (see the module's docstring)."""
    ref = torch_reference(bundle, x) if reference is None else reference
    out = glsl_eval(ctx, bundle, x, **gen)
    desc = what or f"{bundle.name} {gen}"
    if conditioned:
        return assert_conditioned(out, ref, bundle, x, tol, desc)
    return assert_parity(out, ref, tol, desc)


def assert_conditioned(out, ref, bundle, x, tol: float = TOL, what: str = "") -> float:
    """The rule, or past it the conditioning rule (the module's docstring); returns the max error
    against torch, or against float64 where the conditioning rule decided."""
    if scaled_error(out, ref).max() <= tol:
        return assert_parity(out, ref, tol, what)
    exact = torch_reference(bundle, x, float64=True)
    out_f64, torch_f64 = scaled_error(out, exact).max(), scaled_error(ref, exact).max()
    assert out_f64 <= CONDITIONING * torch_f64, (
        f"{what}: past the {tol:g} rule and |code - f64| = {out_f64:.3g} > {CONDITIONING:g} x "
        f"|torch - f64| = {torch_f64:.3g}")
    return float(out_f64)


def run_sample_pass(ctx, fragment: str, rows: np.ndarray, texels: int = 1, *, sampler: str = "u_inputs",
                    attachments: int = 1, uniforms=None, chunks=None, generated=None, width: int = 64) -> list:
    """A test pass with one sample per pixel: `rows` [N, 4 * texels] (or [N, 3] for one vec3
    texel) are laid out as `texels` texels side by side per pixel in the float texture `sampler`
    (data orientation); `fragment` runs over a ceil(N / width) x width grid, with the GL resources
    of a `generated` network bound when given. Returns the `attachments` outputs, [N, 4] each.
    Releases every GL object it made."""
    from inshade.runtime.network import NetworkResources
    from inshade.runtime.programs import ProgramCache
    from inshade.runtime.render import FullscreenPass, float_target, read_rgba_raw, release_target, upload_float_texture

    n, c = rows.shape[0], rows.shape[1] // texels
    w = min(n, width)
    h = (n + w - 1) // w
    grid = np.zeros((h * w, c * texels), np.float32)
    grid[:n] = rows
    cache = ProgramCache(ctx)
    prog = cache.get("common/fullscreen.vert", fragment, chunks=chunks)
    res = NetworkResources(ctx, generated) if generated is not None else None
    tex = upload_float_texture(ctx, grid.reshape(h, w * texels, c))
    fbo = float_target(ctx, w, h, attachments)
    pass_ = FullscreenPass(ctx, prog)
    ctx.viewport = (0, 0, w, h)
    try:
        if res is not None:
            res.bind(prog, first_unit=1)
        pass_.render(fbo, uniforms=uniforms, textures={sampler: tex})
        return [read_rgba_raw(fbo, i).reshape(-1, 4)[:n] for i in range(attachments)]
    finally:
        pass_.vao.release()
        if res is not None:
            res.release()
        tex.release()
        release_target(fbo)
        cache.release()


def node_values(graph: GraphModule, x: torch.Tensor) -> dict[str, torch.Tensor]:
    """Every node's torch output for the input ``x`` (its ports concatenated), by node id."""
    values = {"x": x}
    with torch.no_grad():
        for node_id, comp in graph.nodes.items():
            srcs = [values[s] for s in graph.wiring[node_id]]
            values[node_id] = comp(srcs[0] if len(srcs) == 1 else torch.cat(srcs, -1))
    return values


def uniform_inputs(seed: int, n: int, dim: int, lo: float = -1.0, hi: float = 1.0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(lo, hi, (n, dim)).astype(np.float32)


def unit_directions(seed: int, n: int) -> np.ndarray:
    v = np.random.default_rng(seed).normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return v.astype(np.float32)


# --- random MLP graphs ------------------------------------------------------------------------

@dataclass
class MLPSpec:
    """A printable description of a random MLP graph (hypothesis shows it on failure)."""

    inputs: list[int]                     # widths of the input ports, concatenated into l0
    widths: list[int]                     # hidden widths
    activations: list[tuple[str, dict]]   # one per hidden layer
    out_dim: int
    output_activation: tuple[str, dict] | None = None
    tap: int | None = None                # also output hidden activation `tap` (a second port)
    bias: list[bool] = field(default_factory=list)
    seed: int = 0

    def block_cost(self) -> int:
        dims = [sum(self.inputs), *self.widths, self.out_dim]
        return sum(blocks(a) * blocks(b) for a, b in zip(dims, dims[1:]))

    def param_count(self) -> int:
        dims = [sum(self.inputs), *self.widths, self.out_dim]
        return sum(a * b + (b if bias else 0) for a, b, bias in zip(dims, dims[1:], self.bias))


_ACT = {"relu": ReLU, "leaky_relu": LeakyReLU, "sigmoid": Sigmoid, "tanh": Tanh, "softplus": Softplus,
        "sin": Sin, "cos": Cos, "exp": Exp, "expm1": Expm1, "identity": Identity, "silu": SiLU, "gelu": GELU,
        "elu": ELU, "abs": Abs, "clamp": Clamp, "erf": Erf}
assert set(_ACT) == set(ACTIVATIONS)
_PARAMETRISED = ("leaky_relu", "sin", "cos", "softplus", "gelu", "elu", "clamp")


def activation_specs():
    """Every activation type, with its parameters (omega0 <= 30: see the module docstring)."""
    bound = st.one_of(st.none(), st.floats(-2.0, 2.0, width=32))
    return st.one_of(
        st.sampled_from([(a, {}) for a in ACTIVATIONS if a not in _PARAMETRISED]),
        st.builds(lambda s: ("leaky_relu", {"slope": s}), st.floats(-1.0, 1.0, width=32)),
        st.builds(lambda t, w: (t, {"omega0": w}), st.sampled_from(["sin", "cos"]), st.sampled_from([1.0, 3.0, 7.5, 30.0])),
        st.builds(lambda b, t: ("softplus", {"beta": b, "threshold": t}), st.sampled_from([1.0, 0.5, 2.0, 10.0]),
                  st.sampled_from([None, 20.0, 1.0])),
        st.builds(lambda a: ("gelu", {"approximate": a}), st.sampled_from(["none", "tanh"])),
        st.builds(lambda a: ("elu", {"alpha": a}), st.sampled_from([1.0, 0.5, 1.6732632])),
        st.builds(lambda lo, hi: ("clamp", {"min": lo, "max": max(lo, hi) if lo is not None else hi}),
                  bound, st.floats(-2.0, 2.0, width=32)),
    )


@st.composite
def mlp_specs(draw, *, max_depth: int = 6, max_width: int = 128, max_inputs: int = 3,
              max_out: int = 32, block_budget: int = 400, activations=None):
    """Random MLP architectures: depth 1..max_depth hidden layers of width 1..max_width (half
    the draws <= 16, so non-multiples of 4 are common), 1..max_inputs input ports, up to
    max_out outputs (> 4 means several output blocks; <= 32 = 8 draw buffers).

    `block_budget` caps the total number of mat4 blocks: llvmpipe's first-draw JIT time grows
    with it (~1 s per 250 unrolled blocks) and keeps the suite fast. Widths are drawn layer by
    layer under what is left of the budget."""
    n_in = draw(st.integers(1, max_inputs))
    inputs = [draw(st.integers(1, 6)) for _ in range(n_in)]
    depth = draw(st.integers(1, max_depth))
    out_dim = draw(st.one_of(st.integers(1, 8), st.integers(9, max_out)))
    remaining = block_budget - 8 * blocks(min(max_width, 128))  # keep room for the last layer
    prev, widths = sum(inputs), []
    for _ in range(depth):
        cap = max(1, min(max_width, 4 * (remaining // (2 * blocks(prev)))))
        w = draw(st.one_of(st.integers(1, min(16, cap)), st.integers(1, cap)))
        remaining -= blocks(prev) * blocks(w)
        widths.append(w)
        prev = w
    act_strategy = activations if activations is not None else activation_specs()
    acts = [draw(act_strategy) for _ in widths]
    out_act = draw(st.one_of(st.none(), st.sampled_from([("sigmoid", {}), ("identity", {}), ("relu", {})])))
    tappable = [i for i, w in enumerate(widths) if out_dim + w <= max_out]  # all outputs <= max_out
    tap = draw(st.one_of(st.none(), st.sampled_from(tappable))) if tappable else None
    bias = [draw(st.booleans()) for _ in range(depth + 1)]
    seed = draw(st.integers(0, 2**31 - 1))
    return MLPSpec(inputs, widths, acts, out_dim, out_act, tap, bias, seed)


def _init_dense(layer: Dense, next_act: tuple[str, dict] | None, gen: torch.Generator):
    """Weights that keep every pre-activation in the range the tolerance rule is stated for."""
    w, b = layer.linear.weight, layer.linear.bias
    n = w.shape[1]
    name, params = next_act or ("identity", {})
    with torch.no_grad():
        if name in ("sin", "cos"):   # SIREN init: omega0 * W x stays O(1) per unit of input
            bound = math.sqrt(6.0 / n) / params["omega0"]
        elif name in ("exp", "expm1"):   # row L1 norm <= 0.25: exp chains stay below ~2 (no overflow)
            bound = 0.25 / n
        else:                      # torch.nn.Linear's default scale
            bound = 1.0 / math.sqrt(n)
        w.copy_((torch.rand(w.shape, generator=gen) * 2 - 1) * bound)
        if b is not None:
            b.copy_((torch.rand(b.shape, generator=gen) * 2 - 1) * min(bound, 0.1 if name in ("exp", "expm1") else 1.0))


def build_mlp(spec: MLPSpec) -> GraphModule:
    """The GraphModule a spec describes: inputs x0..xk concatenated into l0, hidden
    (dense -> activation)*, a final dense [-> output activation]; output `y`, plus `h` (a hidden
    activation, so outputs are gathered from unaligned lanes) when spec.tap is set."""
    gen = torch.Generator().manual_seed(spec.seed)
    g = GraphModule([(f"x{i}", d) for i, d in enumerate(spec.inputs)])
    src: list[str] | str = [f"x{i}" for i in range(len(spec.inputs))]
    bias = spec.bias or [True] * (len(spec.widths) + 1)
    for i, (w, (act, params)) in enumerate(zip(spec.widths, spec.activations)):
        layer = Dense(sum(g.dim(s) for s in ([src] if isinstance(src, str) else src)), w, bias[i])
        _init_dense(layer, (act, params), gen)
        g.add(f"l{i}", layer, src)
        src = g.add(f"a{i}", _ACT[act](**params), f"l{i}")
    last = Dense(g.dim(src) if isinstance(src, str) else sum(g.dim(s) for s in src), spec.out_dim,
                 bias[len(spec.widths)])
    _init_dense(last, spec.output_activation, gen)
    src = g.add(f"l{len(spec.widths)}", last, src)
    if spec.output_activation is not None:
        act, params = spec.output_activation
        src = g.add("out_act", _ACT[act](**params), src)
    g.output("y", src)
    if spec.tap is not None:
        g.output("h", f"a{spec.tap}")
    return g


def spec_inputs(spec: MLPSpec, n: int) -> np.ndarray:
    return uniform_inputs(spec.seed + 1, n, sum(spec.inputs))


def round_weights_fp16(bundle):
    """A copy of the bundle whose dense weights/biases are rounded to fp16 (what an f2 weight
    texture holds), still stored as float32."""
    from inshade.bundle import Bundle

    tensors = {}
    for name, a in bundle.tensors.items():
        node = bundle.node(name.split(".")[0])
        tensors[name] = a.astype(np.float16).astype(np.float32) if node.type == "dense" else a
    return Bundle(bundle.meta, tensors)
