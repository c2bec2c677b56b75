"""What a well-formed node of a component type looks like: its parameters, output width and
tensor shapes -- the numpy-level description every executor shares.

Each component folder's ``spec.py`` registers its types here; the torch twins (``inshade.models``)
and the GLSL emitters (``inshade.codegen``) register under the same names (components/registry.py).
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from . import registry

MAX_WIDTH = 4096          # widest layer a bundle may declare
I8_MAX = 127              # int8 weight codes are symmetric: [-127, 127] (inshade/quantize.py)


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
    # values must survive a round trip through this dtype (e.g. "float16" for latents stored in
    # RGBA16F textures): the bundle then holds exactly what the GPU will see
    representable: str | None = None
    # each row is int8 codes in [-127, 127] times that row's scale, the node's tensor of this slot
    # (inshade/quantize.py i8_codes): the shader rebuilds the same float32 values from the codes
    scaled_by: str | None = None


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


def register(spec: ComponentSpec) -> ComponentSpec:
    """File a component type's spec (a name registered twice is refused)."""
    registry.add("spec", spec.type, spec, where=f"{sys._getframe(1).f_globals['__name__']}")
    return spec


# type name -> spec of every registered type (the registry's own table)
COMPONENTS: dict[str, ComponentSpec] = registry.entries("spec")


def pos_int(limit):
    return lambda v: isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= limit


def finite(v):
    return np.isfinite(float(v))


def same_width(p, d):
    return d


def float32(v) -> np.float32:
    """v as the float32 both executors compute with (inf beyond float32's range)."""
    with np.errstate(over="ignore"):
        return np.float32(v)


def finite32(v):
    return bool(np.isfinite(float32(v)))



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
        if name not in params or params[name] is None and p.default is None:
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
            why = f" (must be {p.doc})" if p.doc else ""
            raise ComponentError(f"param '{name}' of {node_type} has an invalid value {v!r}{why}")
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


def i8_codes(weight: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """int8 [out, in]: the codes q with q * scale == weight (float32), or ValueError naming the first
    weight that is not one."""
    w, s = np.asarray(weight, np.float32), np.asarray(scale, np.float32)
    if not (np.isfinite(s).all() and (s > 0).all()):
        raise ValueError("every row's scale must be finite and > 0")
    q = np.rint(w / s[:, None])
    ok = (np.abs(q) <= I8_MAX) & ((q.astype(np.float32) * s[:, None]) == w)
    if not ok.all():
        o, i = (int(v) for v in np.argwhere(~ok)[0])
        raise ValueError(f"value {float(w[o, i]):.9g} at [{o}, {i}] is not an int8 code in [-{I8_MAX}, {I8_MAX}] "
                         f"times its row's scale {float(s[o]):.9g}")
    return q.astype(np.int8)
