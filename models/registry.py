"""Torch reference classes, registered under the bundle's component type names."""
from __future__ import annotations

import numpy as np
import torch

from inshade.components import registry

# type name -> torch twin class (models/__init__.py loads the component folders' twins into it)
TORCH_COMPONENTS: dict[str, type] = registry.entries("torch")


def register(cls):
    """File a torch twin under its ``type`` (a name registered twice is refused)."""
    registry.add("torch", cls.type, cls)
    return cls


class Component(torch.nn.Module):
    """A graph node's torch reference. Subclasses set `type` and implement the three hooks."""

    type = ""

    def params(self) -> dict:
        return {}

    def export_tensors(self) -> dict[str, np.ndarray]:
        return {}

    @classmethod
    def from_node(cls, params: dict, in_dim: int, tensors: dict[str, np.ndarray]) -> "Component":
        return cls(**params)


REQUIRED = object()   # a field's default in WithParams.fields: none, the value must be given


class WithParams(Component):
    """A component whose parameters are plain values, each kept as an attribute of its name. ``fields``
    names them in order, each with its conversion and default (``REQUIRED``: none); the constructor
    takes them by position or by name, converted (None stays None), and ``params()`` returns them."""

    fields: dict[str, tuple] = {}

    def __init__(self, *args, **kwargs):
        super().__init__()
        cls = type(self).__name__
        if len(args) > len(self.fields):
            raise TypeError(f"{cls}() takes at most {len(self.fields)} arguments ({len(args)} given)")
        given = dict(zip(self.fields, args))
        for name, value in kwargs.items():
            if name not in self.fields or name in given:
                raise TypeError(f"{cls}() got an unexpected or repeated argument {name!r}")
            given[name] = value
        for name, (convert, default) in self.fields.items():
            value = given.get(name, default)
            if value is REQUIRED:
                raise TypeError(f"{cls}() missing argument {name!r}")
            setattr(self, name, None if value is None else convert(value))

    def params(self):
        return {name: getattr(self, name) for name in self.fields}
