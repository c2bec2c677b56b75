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
