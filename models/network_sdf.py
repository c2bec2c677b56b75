"""Torch reference for network SDFs: any graph with 3 inputs and 1 output (an MLP fitted to a
mesh, models/mlp_sdf_fit.py; a lookup-array cascade, Differentiable Indirection) used as a scene
by models/sdf.py's ``trace`` / ``normals`` / ``render`` and, after export, by the GLSL of
codegen/network_sdf.py (the same operations in the same float32 order).

The contract (documented in full in codegen/network_sdf.py): the graph sees
``q = (p - center) * float32(1 / radius)``; its output times ``radius`` is the world-space
distance; the bundle carries ``render.sdf = {"center", "radius", "trace", "albedo"}``.
"""
from __future__ import annotations

import torch

from inshade.bundle import Bundle
from inshade.codegen.network_sdf import NetworkSdfScene
from inshade.geometry.sdf import DEFAULT_ALBEDO

from .graph import GraphModule

KIND = "network_sdf"


class NetworkSdfModule(torch.nn.Module):
    """Distance [N] (and constant albedo [N, 3]) of a network SDF at points p [N, 3].

    ``graph_or_bundle``: a GraphModule ([.., 3] -> [.., 1]) or a Bundle (its graph is rebuilt;
    use ``from_bundle`` to take the frame from the bundle's ``render.sdf`` too).
    ``.scene`` exposes ``trace`` / ``center`` / ``radius`` / ``name`` as an analytic SdfScene does.
    """

    def __init__(self, graph_or_bundle, trace: dict | None = None, center=(0.0, 0.0, 0.0), radius: float = 1.0,
                 albedo=DEFAULT_ALBEDO, name: str = ""):
        super().__init__()
        graph = GraphModule.from_bundle(graph_or_bundle) if isinstance(graph_or_bundle, Bundle) else graph_or_bundle
        in_dim = sum(d for _, d, _ in graph.inputs)
        out_dim = sum(graph.dim(node) for _, node, _ in graph.outputs)
        if in_dim != 3 or out_dim != 1:
            raise ValueError(f"a network SDF maps 3 inputs to 1 output, this graph has {in_dim} -> {out_dim}")
        self.graph = graph
        self.scene = NetworkSdfScene(center, radius, dict(trace or {}), albedo, name)
        self.register_buffer("_center", torch.tensor(self.scene.center, dtype=torch.float32), persistent=False)

    @classmethod
    def from_bundle(cls, bundle: Bundle) -> "NetworkSdfModule":
        s = NetworkSdfScene.from_bundle(bundle)
        return cls(GraphModule.from_bundle(bundle), s.trace, s.center, s.radius, s.albedo, s.name)

    def normalise(self, p: torch.Tensor) -> torch.Tensor:
        """(p - center) * (1 / radius), float32, as scene_sdf computes it."""
        return (p.float() - self._center) * self.scene.inv_radius

    def forward(self, p: torch.Tensor) -> torch.Tensor:
        return self.graph(self.normalise(p))[..., 0] * self.scene.radius

    def albedo(self, p: torch.Tensor) -> torch.Tensor:
        return torch.tensor(self.scene.albedo, dtype=torch.float32).expand(p.shape[0], 3)

    def evaluate(self, p: torch.Tensor):
        """(distance [N], albedo [N, 3]), as SdfModule.evaluate."""
        return self(p), self.albedo(p)

    def render_meta(self) -> dict:
        """The bundle's ``render`` metadata: {"sdf": {center, radius, trace, albedo}}."""
        return {"sdf": self.scene.to_dict()}

    def export(self, kind: str = KIND, name: str = "", provenance: dict | None = None,
               metrics: dict | None = None) -> Bundle:
        """The graph as a bundle carrying this module's ``render.sdf``."""
        return self.graph.export(kind, name or self.scene.name or kind, provenance, metrics, render=self.render_meta())
