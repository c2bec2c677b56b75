"""An MLP network SDF (models/network_sdf.py contract): the builder with geometric initialisation,
the smooth activation it trains with and its folding into plain softplus, the Lipschitz bound of
a chain graph and the safe sphere-tracing settings that bound gives.

Safe step. Sphere tracing advances by ``d * step_scale`` and never overshoots the surface if
``step_scale <= 1/L``, L the network's Lipschitz constant in world units (radius cancels: input
and output are scaled by it). ``lipschitz_bound`` gives an upper bound from the weights: the
product over the chain of each dense layer's spectral norm, each activation's constant
(relu/softplus/tanh 1, sigmoid 1/4, leaky_relu max(1, |slope|), sin omega0) and the frequency
encoding's exact constant sqrt([x kept] + sum_k (2^k pi)^2). Unconstrained fits reach bounds of
~20-30 (true max |grad| ~1.3), which would need ~1000 steps per ray; so the fit
(models/mlp_sdf_fit.py) penalises the bound (spectral norms are differentiable) and the exported
``trace.step_scale = min(0.9, 1/L)`` is a guarantee, not a guess.

Activation: ``softplus`` trains as softplus(100 x) / 100 (``SmoothReLU``: SAL's geometric
initialisation works as for relu, shading normals are smooth) and is exported with the 100s
folded into the weights (``fold_beta``), so codegen sees a plain softplus MLP.
"""
from __future__ import annotations

import math

import torch

from inshade.components.encodings import torch_twin as _enc
from inshade.geometry.sdf import f32

from inshade.components.elementwise import torch_twin as _act
from .graph import GraphModule

ACTIVATIONS = ("softplus", "relu", "leaky_relu", "tanh")


class SmoothReLU(_act.Softplus):
    """Training-time activation softplus(beta x) / beta: 1-Lipschitz and ~relu (within
    log(2) / beta), so the SAL geometric initialisation holds, but smooth (shaded normals
    without facets). Not exported as such: ``fold_beta`` turns the graph into plain softplus."""

    def __init__(self, beta: float = 100.0):
        super().__init__()
        self.beta = float(beta)

    def forward(self, x):
        z = x * self.beta
        return (torch.clamp_min(z, 0) + torch.log1p(torch.exp(-z.abs()))) * (1.0 / self.beta)


def build(width: int = 32, layers: int = 3, freqs: int = 0, activation: str = "softplus",
          beta: float = 100.0) -> GraphModule:
    """q[3] -> [frequency(freqs)] -> (dense width -> activation) * layers -> dense 1, with the
    geometric initialisation of SAL (Atzmon & Lipman 2020): the net starts as |q| - 0.5, a sphere
    (without it, an L1 fit from a default init collapses to the median, ~0 everywhere).
    ``softplus`` trains with ``SmoothReLU(beta)``; export through ``fold_beta``."""
    if activation not in ACTIVATIONS:
        raise ValueError(f"unknown activation {activation!r} (choose from {', '.join(ACTIVATIONS)})")
    g = GraphModule([("position", 3, "position")])
    src = "position"
    if freqs:
        src = g.add("enc", _enc.Frequency(freqs, include_input=True), src)
    for i in range(layers):
        src = g.dense(f"l{i}", src, width)
        act = {"softplus": lambda: SmoothReLU(beta), "relu": _act.ReLU, "leaky_relu": _act.LeakyReLU,
               "tanh": _act.Tanh}[activation]
        src = g.add(f"a{i}", act(), src)
    src = g.dense(f"l{layers}", src, 1)
    g.output("distance", src, "sdf")
    if activation != "tanh":
        _geometric_init(g, layers, width)
    return g


def _geometric_init(g: GraphModule, layers: int, width: int) -> None:
    with torch.no_grad():
        for i in range(layers):
            lin = g.nodes[f"l{i}"].linear
            torch.nn.init.normal_(lin.weight, 0.0, math.sqrt(2.0) / math.sqrt(width))
            torch.nn.init.zeros_(lin.bias)
        last = g.nodes[f"l{layers}"].linear
        torch.nn.init.normal_(last.weight, math.sqrt(math.pi) / math.sqrt(width), 1e-4)
        torch.nn.init.constant_(last.bias, -0.5)


def fold_beta(graph: GraphModule) -> GraphModule:
    """The same function with plain softplus (what codegen emits): softplus(beta z) / beta per
    hidden layer, the betas folded into the weights. First layer (W, b) -> (beta W, beta b);
    later hidden layers (W, b) -> (W, beta b) (their input is already beta times larger); the output
    layer W -> W / beta. The spectral-norm product, hence the Lipschitz bound, is unchanged.
    Graphs without SmoothReLU come back as an exact copy."""
    out = GraphModule([(n, d, s) for n, d, s in graph.inputs])
    pending = 1.0           # the factor the current activations carry (beta after a SmoothReLU)
    for node_id, comp in graph.nodes.items():
        inputs = graph.wiring[node_id]
        if isinstance(comp, SmoothReLU):
            out.add(node_id, _act.Softplus(), inputs)
            pending = comp.beta
            continue
        if comp.type == "dense":
            nxt = _next_activation(graph, node_id)
            beta = nxt.beta if isinstance(nxt, SmoothReLU) else 1.0
            new = out.dense(node_id, inputs, comp.linear.out_features, comp.linear.bias is not None)
            with torch.no_grad():
                # input scaled by `pending`, output wanted scaled by `beta`
                new_lin = out.nodes[new].linear
                new_lin.weight.copy_(comp.linear.weight * (beta / pending))
                if comp.linear.bias is not None:
                    new_lin.bias.copy_(comp.linear.bias * beta)
            pending = 1.0 if beta == 1.0 else pending
            continue
        out.add(node_id, type(comp)(**comp.params()), inputs)
    for name, node, sem in graph.outputs:
        out.output(name, node, sem)
    return out


def _next_activation(graph: GraphModule, node_id: str):
    ids = list(graph.nodes)
    i = ids.index(node_id)
    if i + 1 < len(ids) and graph.wiring[ids[i + 1]] == [node_id]:
        return graph.nodes[ids[i + 1]]
    return None


def _activation_lipschitz(comp) -> float:
    t = comp.type
    if t in ("relu", "softplus", "tanh", "identity"):
        return 1.0
    if t == "sigmoid":
        return 0.25
    if t == "leaky_relu":
        return max(1.0, abs(comp.slope))
    if t == "sin":
        return abs(comp.omega0)
    if t == "frequency":
        s = sum(((2.0 ** k) * math.pi) ** 2 for k in range(comp.n_freqs))
        return math.sqrt(s + (1.0 if comp.include_input else 0.0))
    return math.inf


def lipschitz_bound(graph: GraphModule, differentiable: bool = False):
    """Upper bound on the Lipschitz constant (L2 -> L2) of a chain graph: product of the dense
    layers' spectral norms and the other components' constants (inf for what has no bound here,
    e.g. exp, lookup arrays, or a graph that is not a chain). A tensor if ``differentiable``."""
    total = torch.ones(()) if differentiable else 1.0
    prev = [graph.inputs[0][0]] if len(graph.inputs) == 1 else None
    for node_id, comp in graph.nodes.items():
        if prev is None or graph.wiring[node_id] != prev:
            return math.inf
        if comp.type == "dense":
            s = torch.linalg.matrix_norm(comp.linear.weight, ord=2)
            total = total * (s if differentiable else float(s.detach()))
        else:
            total = total * _activation_lipschitz(comp)
        prev = [node_id]
    return total


def trace_settings(lipschitz: float, radius: float, hit_eps: float) -> dict:
    """``render.sdf.trace`` from the bound: step_scale = min(0.9, 1 / L); max_steps enough for
    ~2 bound diameters of free-space stepping at typical distances (~0.1 radius) plus the slow
    approach to the surface, capped at 512."""
    step = min(0.9, 1.0 / lipschitz) if math.isfinite(lipschitz) and lipschitz > 0 else 0.1
    steps = int(min(512, max(64, math.ceil(48 / step))))
    return {"max_steps": steps, "step_scale": f32(step), "hit_eps": f32(hit_eps * radius),
            "normal_eps": f32(hit_eps * radius)}
