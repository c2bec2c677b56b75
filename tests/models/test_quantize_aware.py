"""The quantizer in the loop (models/quantize_aware.py): inside, a network computes with its dense
weights exactly as the exported bundle at that precision stores them; the gradient trains the float
weights straight through; outside, nothing of it is left."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from inshade.components.elementwise.torch_twin import Tanh
from inshade.models import GraphModule
from inshade.models.fit_loop import adam, fit
from inshade.models.quantize_aware import dense_layers, quantizer_in_loop
from inshade.quantize import quantized


def _net(seed: int = 3) -> GraphModule:
    torch.manual_seed(seed)
    g = GraphModule([("x", 5)])
    g.add("a0", Tanh(), g.dense("l0", "x", 24))
    g.output("y", g.dense("l1", "a0", 3))
    with torch.no_grad():
        g.nodes["l0"].linear.weight[0, 0] = 4.0   # a large weight stretches row 0's int8 scale
    return g


@pytest.mark.parametrize("precision", ["f16", "i8"])
def test_inside_the_network_computes_what_the_exported_bundle_stores(precision):
    net = _net()
    x = torch.rand(64, 5) * 2 - 1
    with quantizer_in_loop(net, precision):
        inside = net(x).detach()
    exported = GraphModule.from_bundle(quantized(net.export("mlp"), precision))(x).detach()
    assert torch.equal(inside, exported)
    assert not torch.equal(inside, net(x).detach())   # outside: the float weights again


def test_the_float_weights_train_straight_through_and_nothing_is_left():
    net = _net()
    keys = set(net.state_dict())
    before = [layer.weight.detach().clone() for layer in dense_layers(net)]
    x, y = torch.rand(256, 5) * 2 - 1, torch.rand(256, 3)
    with quantizer_in_loop(net, "i8"):
        opt = adam(net.parameters(), lr=1e-2)
        fit(opt, lambda step: torch.mean((net(x) - y) ** 2), 20, progress=False)
    after = [layer.weight.detach() for layer in dense_layers(net)]
    assert all(not torch.equal(a, b) for a, b in zip(before, after))
    # the float weights moved by less than a code would: not rounded, trained
    assert any(not np.array_equal(a.numpy(), quantized(net.export("mlp"), "i8").tensor(n, "weight"))
               for a, n in zip(after, [n for n in net.export("mlp").nodes if n.type == "dense"]))
    assert set(net.state_dict()) == keys and all(isinstance(layer.weight, torch.nn.Parameter)
                                                   for layer in dense_layers(net))
