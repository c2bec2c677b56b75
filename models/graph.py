"""A bundle's graph as a torch module: build, run, export to a Bundle, import from one."""
from __future__ import annotations

import torch

from inshade.bundle import FORMAT, VERSION, Bundle
from inshade.components import registry as component_registry

from .registry import TORCH_COMPONENTS, Component

component_registry.load("torch")


class GraphModule(torch.nn.Module):
    """Nodes wired by name. forward takes the inputs concatenated in declaration order
    ([..., in_dim]) and returns the outputs concatenated ([..., out_dim])."""

    def __init__(self, inputs: list[tuple[str, int] | tuple[str, int, str] | tuple[str, int, str, str]]):
        """``inputs``: (name, dim[, semantic[, dtype]]); dtype "uint" marks lanes that GLSL receives
        as uint (torch still takes them in the float input, as exact integers < 2^24)."""
        super().__init__()
        self.inputs = [(p[0], int(p[1]), p[2] if len(p) > 2 else "generic") for p in inputs]
        self.input_dtypes = {p[0]: (p[3] if len(p) > 3 else "float") for p in inputs}
        self.nodes = torch.nn.ModuleDict()
        self.wiring: dict[str, list[str]] = {}
        self.outputs: list[tuple[str, str, str]] = []
        self._dims = {name: dim for name, dim, _ in self.inputs}

    def add(self, node_id: str, component: Component, inputs: list[str] | str) -> str:
        inputs = [inputs] if isinstance(inputs, str) else list(inputs)
        for s in inputs:
            if s not in self._dims:
                raise KeyError(f"'{s}' is not an input or an earlier node")
        self.nodes[node_id] = component
        self.wiring[node_id] = inputs
        self._dims[node_id] = self._out_dim(component, sum(self._dims[s] for s in inputs))
        return node_id

    def dense(self, node_id, inputs, out, bias=True):
        """Shorthand: a Dense layer sized from its inputs."""
        inputs = [inputs] if isinstance(inputs, str) else inputs
        return self.add(node_id, TORCH_COMPONENTS["dense"](sum(self._dims[s] for s in inputs), out, bias), inputs)

    def output(self, name: str, node: str, semantic: str = "generic"):
        self.outputs.append((name, node, semantic))

    def dim(self, name: str) -> int:
        return self._dims[name]

    @staticmethod
    def _out_dim(component, in_dim):
        from inshade.components import check_node, resolve_params
        return check_node(component.type, resolve_params(component.type, component.params()), in_dim)

    def forward(self, *xs: torch.Tensor) -> torch.Tensor:
        """The inputs concatenated on the last axis, or one tensor per input in declaration order."""
        x = xs[0] if len(xs) == 1 else torch.cat(xs, -1)
        values, off = {}, 0
        for name, dim, _ in self.inputs:
            values[name] = x[..., off:off + dim]
            off += dim
        for node_id, comp in self.nodes.items():
            srcs = [values[s] for s in self.wiring[node_id]]
            values[node_id] = comp(srcs[0] if len(srcs) == 1 else torch.cat(srcs, -1))
        return torch.cat([values[node] for _, node, _ in self.outputs], -1)

    # bundle <-> module ---------------------------------------------------------------
    def export(self, kind: str, name: str = "", provenance: dict | None = None,
               metrics: dict | None = None, render: dict | None = None) -> Bundle:
        nodes, tensors = [], {}
        for node_id, comp in self.nodes.items():
            nodes.append({"id": node_id, "type": comp.type, "inputs": self.wiring[node_id],
                          "params": comp.params()})
            for slot, arr in comp.export_tensors().items():
                tensors[f"{node_id}.{slot}"] = arr
        meta = {
            "format": FORMAT, "version": VERSION, "kind": kind, "name": name or kind,
            "inputs": [{"name": n, "dim": d, "semantic": s,
                        **({"dtype": self.input_dtypes[n]} if self.input_dtypes[n] != "float" else {})}
                       for n, d, s in self.inputs],
            "nodes": nodes,
            "outputs": [{"name": n, "node": node, "semantic": s} for n, node, s in self.outputs],
            "provenance": provenance or {}, "metrics": metrics or {},
        }
        if render:
            meta["render"] = render
        return Bundle(meta, tensors)

    @classmethod
    def from_bundle(cls, bundle: Bundle) -> "GraphModule":
        g = cls([(p.name, p.dim, p.semantic, p.dtype) for p in bundle.inputs])
        for n in bundle.nodes:
            slots = {k[len(n.id) + 1:]: v for k, v in bundle.tensors.items() if k.startswith(n.id + ".")}
            comp = TORCH_COMPONENTS[n.type].from_node(n.params, n.in_dim, slots)
            g.add(n.id, comp, list(n.inputs))
        for p in bundle.outputs:
            g.output(p.name, p.node, p.semantic)
        return g


def mlp_graph(in_dim: int, widths: list[int], out_dim: int, activation: Component | str = "relu",
              encoding: Component | None = None, output_activation: Component | None = None,
              input_name: str = "x") -> GraphModule:
    """The common case: [encoding] -> (dense -> activation)* -> dense [-> output activation]."""
    g = GraphModule([(input_name, in_dim)])
    src = input_name
    if encoding is not None:
        src = g.add("enc", encoding, src)
    for i, w in enumerate(widths):
        src = g.dense(f"l{i}", src, w)
        act = TORCH_COMPONENTS[activation]() if isinstance(activation, str) else activation
        src = g.add(f"a{i}", act if i == 0 else _fresh(act), src)
    src = g.dense(f"l{len(widths)}", src, out_dim)
    if output_activation is not None:
        src = g.add("out_act", output_activation, src)
    g.output("y", src)
    return g


def _fresh(component: Component) -> Component:
    return type(component)(**component.params())
