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


def test_at_i8_a_table_takes_its_u8_form_and_the_export_writes_the_codes_the_loop_saw():
    from inshade.components.grids.torch_twin import HashGrid

    torch.manual_seed(0)
    g = GraphModule([("x", 2)])
    g.add("grid", HashGrid(2, 3, 2, log2_table_size=8, base_resolution=4, precision="f16", init_scale=0.5), "x")
    g.output("y", g.dense("l0", "grid", 3))
    x, y = torch.rand(256, 2), torch.rand(256, 3)
    with quantizer_in_loop(g, "i8"):
        assert g.nodes["grid"].params()["precision"] == "u8"
        opt = adam(g.parameters(), lr=1e-2)
        fit(opt, lambda step: torch.mean((g(x) - y) ** 2), 20, progress=False)
        with torch.no_grad():
            inside = g(x)
    bundle = quantized(g.export("grid"), "i8")
    assert bundle.node("grid").params["precision"] == "u8"
    # the range the loop calibrated on entry, not one refitted to the trained values
    assert np.array_equal(bundle.tensors["grid.scale"], g.nodes["grid"].scale.numpy())
    assert torch.equal(GraphModule.from_bundle(bundle)(x).detach(), inside)
