"""Component types of the bundle graph: parameters, output width and tensor shapes.

This is the numpy-level description every executor shares. The torch reference
(`inshade.models`) and the GLSL emitters (`inshade.codegen`) register classes under the
same type names; this module only says what a well-formed node of each type looks like.

New techniques (latent texture pyramids, hashed feature tables, voxel latents) arrive as
new entries in COMPONENTS, not as a new bundle format.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

MAX_WIDTH = 4096          # widest dense layer a bundle may declare
MAX_LUT_CELLS = 1 << 28   # cells x channels of one lookup array
MAX_FREQS = 16
SH_MAX_DEGREE = 5         # bands l = 0..4, i.e. "up to order 4"


class ComponentError(ValueError):
    """A node's parameters or inputs do not describe a valid component."""


@dataclass(frozen=True)
class Param:
    kind: type | tuple
    default: Any = ...
    check: Callable[[Any], bool] | None = None
    doc: str = ""


@dataclass(frozen=True)
class TensorSpec:
    shape: tuple[int, ...]
    dtype: str  # numpy dtype name


@dataclass(frozen=True)
class ComponentSpec:
    type: str
    doc: str
    params: dict[str, Param]
    out_dim: Callable[[dict, int], int]
    tensors: Callable[[dict, int], dict[str, TensorSpec]] = lambda p, d: {}
    in_dim: Callable[[dict, int], bool] | None = None   # accepts input width?
    category: str = "activation"
    extra_checks: Callable[[dict, int], None] | None = None
    tags: tuple[str, ...] = field(default_factory=tuple)


def _pos_int(limit):
    return lambda v: isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= limit


def _finite(v):
    return np.isfinite(float(v))


def _same(p, d):
    return d


ACTIVATIONS = ("relu", "leaky_relu", "sigmoid", "tanh", "softplus", "sin", "exp", "identity")

COMPONENTS: dict[str, ComponentSpec] = {}


def _register(spec: ComponentSpec) -> None:
    COMPONENTS[spec.type] = spec


_register(ComponentSpec(
    "dense", "y = W x + b, W stored [out, in] like torch.nn.Linear",
    {"out": Param(int, check=_pos_int(MAX_WIDTH)), "bias": Param(bool, True)},
    out_dim=lambda p, d: p["out"],
    tensors=lambda p, d: {"weight": TensorSpec((p["out"], d), "float32"),
                          **({"bias": TensorSpec((p["out"],), "float32")} if p["bias"] else {})},
    in_dim=lambda p, d: 1 <= d <= MAX_WIDTH,
    category="layer",
))
for _name in ("relu", "sigmoid", "tanh", "softplus", "exp", "identity"):
    _register(ComponentSpec(_name, f"elementwise {_name}", {}, out_dim=_same))
_register(ComponentSpec("leaky_relu", "x if x>0 else slope*x",
                        {"slope": Param(float, 0.01, _finite)}, out_dim=_same))
_register(ComponentSpec("sin", "sin(omega0 * x), SIREN's activation",
                        {"omega0": Param(float, 1.0, _finite)}, out_dim=_same))

_register(ComponentSpec(
    "frequency", "NeRF positional encoding: [x] + [sin(2^k pi x), cos(2^k pi x)] for k < n_freqs",
    {"n_freqs": Param(int, check=_pos_int(MAX_FREQS)), "include_input": Param(bool, True)},
    out_dim=lambda p, d: d * (2 * p["n_freqs"] + (1 if p["include_input"] else 0)),
    category="encoding",
))
_register(ComponentSpec(
    "triangle_wave", "tri(2^k x) for k < n_freqs, tri(t) = 1 - |mod(t, 2) - 1|",
    {"n_freqs": Param(int, check=_pos_int(MAX_FREQS))},
    out_dim=lambda p, d: d * p["n_freqs"],
    category="encoding",
))
_register(ComponentSpec(
    "spherical_harmonics", "real orthonormal SH basis of a unit direction, bands l < degree",
    {"degree": Param(int, check=_pos_int(SH_MAX_DEGREE))},
    out_dim=lambda p, d: p["degree"] ** 2,
    in_dim=lambda p, d: d == 3,
    category="encoding",
))

LUT_BITS = {8: "uint8", 16: "uint16", 32: "float32"}
LUT_BAKED = ("none", "triangle", "sinusoid")


def _lut_tensors(p, d):
    shape = tuple(reversed(p["resolution"])) + (p["channels"],)
    out = {"cells": TensorSpec(shape, LUT_BITS[p["bits"]])}
    if p["bits"] != 32:
        out["scale"] = TensorSpec((p["channels"],), "float32")
        out["offset"] = TensorSpec((p["channels"],), "float32")
    return out


def _lut_checks(p, d):
    res = p["resolution"]
    if not (isinstance(res, list) and 1 <= len(res) <= 4 and all(_pos_int(1 << 16)(n) for n in res)):
        raise ComponentError("resolution must be a list of 1 to 4 positive ints")
    if len(res) != d:
        raise ComponentError(f"a {len(res)}D lookup array needs a {len(res)}-wide input, got {d}")
    if int(np.prod(res)) * p["channels"] > MAX_LUT_CELLS:
        raise ComponentError(f"lookup array of {res} x {p['channels']} cells is absurdly large")


_register(ComponentSpec(
    "lookup_array",
    "Differentiable Indirection array: corner-aligned multilinear lookup of cells "
    "[N_{d-1},...,N_0, C]; input clamped to [0,1]; cells = offset + scale * q / (2^bits - 1) "
    "when quantised; the periodic non-linearity is already baked into the cells",
    {"resolution": Param(list), "channels": Param(int, check=_pos_int(64)),
     "bits": Param(int, check=lambda v: v in LUT_BITS),
     "baked": Param(str, "none", lambda v: v in LUT_BAKED)},
    out_dim=lambda p, d: p["channels"],
    tensors=_lut_tensors,
    category="lookup",
    extra_checks=_lut_checks,
))


def resolve_params(node_type: str, params: dict) -> dict:
    """Validated params with defaults filled in; raises ComponentError naming the field."""
    if node_type not in COMPONENTS:
        raise ComponentError(f"unknown component type: {node_type}")
    spec = COMPONENTS[node_type]
    if not isinstance(params, dict):
        raise ComponentError("params must be an object")
    extra = sorted(set(params) - set(spec.params))
    if extra:
        raise ComponentError(f"unknown params for {node_type}: {', '.join(extra)}")
    out = {}
    for name, p in spec.params.items():
        if name not in params:
            if p.default is ...:
                raise ComponentError(f"missing param '{name}' for {node_type}")
            out[name] = p.default
            continue
        v = params[name]
        if p.kind is float and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        if p.kind is int and isinstance(v, bool) or not isinstance(v, p.kind):
            raise ComponentError(f"param '{name}' of {node_type} must be {p.kind.__name__}, got {v!r}")
        if p.check is not None and not p.check(v):
            raise ComponentError(f"param '{name}' of {node_type} has an invalid value {v!r}")
        out[name] = v
    return out


def check_node(node_type: str, params: dict, in_dim: int) -> int:
    """Checks a resolved node against its input width and returns its output width."""
    spec = COMPONENTS[node_type]
    if spec.in_dim is not None and not spec.in_dim(params, in_dim):
        raise ComponentError(f"{node_type} cannot take a {in_dim}-wide input")
    if spec.extra_checks is not None:
        spec.extra_checks(params, in_dim)
    return spec.out_dim(params, in_dim)
