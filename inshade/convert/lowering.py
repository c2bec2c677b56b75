"""Lowering a captured network onto bundle components (numpy only: shared by the torch and ONNX
importers).

An importer walks its graph once and calls these methods; what comes out is a ``Bundle``. Every
tensor the network computes is a ``Feat``: its shape with the batch axis held at size 1, and for
each element the *lane* that holds it. A lane is one float of a bundle value (an input port or a
node's output), numbered globally. Layout operations (view, permute, slice, cat, expand, ...)
only rearrange the lane array and emit nothing; a node is emitted only where a value is computed,
and a ``select`` node only where a computation needs lanes in an order no value has. Constants
(parameters, buffers, literals) stay numpy arrays until an operation combines them with a Feat:
then they become weights (dense), per-lane scales (affine) or cells (lookup arrays).

What a shader cannot do is refused with ``ConvertError`` before anything is written: the
importer adds the op, the module path and the user's source line to the message.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .lanes import ConvertError, Feat, Float64Unavailable, IntFeat
from .lowering_elementwise import ElementwiseLowering
from .lowering_ints import IntLowering
from .lowering_layers import LayerLowering
from .lowering_values import ValueGraph

__all__ = ["ConvertError", "Feat", "Float64Unavailable", "IntFeat", "Lowering"]


@dataclass
class Lowering(ValueGraph, ElementwiseLowering, LayerLowering, IntLowering):
    """Builds a bundle graph. ``lane_value[i]`` / ``lane_index[i]``: the value and lane of global
    lane i."""
    nodes: list = field(default_factory=list)
    tensors: dict = field(default_factory=dict)
    inputs: list = field(default_factory=list)
    outputs: list = field(default_factory=list)
    values: dict = field(default_factory=dict)       # value id -> (first global lane, width)
    int_program: list = field(default_factory=list)  # uint32 entries: ("lane", global lane), ("const", c), (op, a, b)
    _int_ids: dict = field(default_factory=dict)
    lane_value: list = field(default_factory=list)
    lane_index: list = field(default_factory=list)
    _counts: dict = field(default_factory=dict)
