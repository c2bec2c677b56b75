"""Torch side of inshade: reference modules, export/import of bundles, data and training."""
from .graph import GraphModule, mlp_graph
from .registry import TORCH_COMPONENTS

__all__ = ["GraphModule", "mlp_graph", "TORCH_COMPONENTS"]
