"""Unity and Unreal drop-ins: the text written, wrapped as each engine wraps it, through the HLSL
driver against torch; pins split past 4 lanes; several networks in one shader; refusals in one line."""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from inshade.codegen.targets import TargetError
from inshade.engines import ENGINES, check_drop_in, drop_in
from inshade.models import GraphModule
from inshade.models.registry import TORCH_COMPONENTS
from inshade.runtime.compute.run import spirv

from parity import torch_reference


@pytest.fixture(scope="module")
def zoo_bundles(tmp_path_factory):
    from zoo import exported

    return exported(lambda name: tmp_path_factory.mktemp(name) / "b")


@pytest.mark.parametrize("engine", ENGINES)
def test_the_zoo_in_each_engine(zoo_bundles, engine):
    """Every zoo network without textures, as the engine calls it, against the torch module it came from."""
    refused = []
    for name, (module, bundle, x) in zoo_bundles.items():
        try:
            d = drop_in(bundle, engine)
        except TargetError as e:
            refused.append(name)
            assert str(e).startswith(f"{engine}: {bundle.name} reads "), e
            continue
        result = check_drop_in(d, module, bundle, x)
        assert result.ok, (name, result.line())
    assert sorted(refused) == ["grid3d", "grid_texture"]   # lookup arrays: textures


def _wide_bundle():
    """Two inputs (6 + 1 lanes) and two outputs (3 + 5 lanes), the second a log of values in [1, 5]
    or [-5, -1] (finite or NaN, never near the log's pole)."""
    torch.manual_seed(4)
    g = GraphModule([("feat", 6, "generic"), ("t", 1, "generic")])
    h = g.add("a0", TORCH_COMPONENTS["tanh"](), g.dense("l0", ["feat", "t"], 8))
    g.output("rgb", g.dense("l1", h, 3), "linear_rgb")
    g.output("extra", g.add("lg", TORCH_COMPONENTS["log"](), g.dense("l2", h, 5)))
    with torch.no_grad():
        l2 = g.nodes["l2"].linear
        l2.weight.zero_()
        l2.weight[:, 0] = 2.0
        l2.bias.copy_(torch.tensor([3.0, -3.0, 3.0, -3.0, 3.0]))
    return g.export("wide", "wide")


@pytest.mark.parametrize("engine", ENGINES)
def test_pins_past_four_lanes_outputs_beyond_the_first_and_special_values(engine):
    bundle = _wide_bundle()
    d = drop_in(bundle, engine)
    assert [(p.name, p.dim) for p in d.inputs] == [("feat_0", 4), ("feat_1", 2), ("t", 1)]
    assert [(p.name, p.dim) for p in d.outputs] == [("rgb", 3), ("extra_0", 4), ("extra_1", 1)]
    x = np.random.default_rng(1).uniform(-2, 2, (512, 7)).astype(np.float32)
    ref = torch_reference(bundle, x)
    assert np.isnan(ref[:, 4]).all() and np.isfinite(ref[:, 3]).all()   # log of negatives: NaN, as torch
    result = check_drop_in(d, GraphModule.from_bundle(bundle), bundle, x)
    assert result.ok, result.line()
    if engine == "unreal":
        assert "Additional Outputs extra_0 (Float 4), extra_1 (Float 1); returns rgb" in d.node


def test_two_unity_networks_share_one_shader():
    """Two Custom Function files in one shader: the library functions both use are defined once."""
    a, b = _wide_bundle(), _wide_bundle()
    b.meta["name"] = "wide_too"
    da, db = drop_in(a, "unity"), drop_in(b, "unity")
    assert da.text.count("#ifndef INSHADE_LIB_LIB_ACTIVATIONS") == 1
    main = ("RWStructuredBuffer<float4> o : register(u0);\n[numthreads(1, 1, 1)] void main() {\n"
            "    float4 f0 = 1, f1 = 0; float t = 0.5; float3 r0, r1; float4 e0, e1; float g0, g1;\n"
            "    wide_float(f0, f1.xy, t, r0, e0, g0);\n    wide_too_float(f0, f1.xy, t, r1, e1, g1);\n"
            "    o[0] = float4(r0 + r1, g0 + g1);\n}\n")
    assert spirv(da.text + db.text + da.text + main, ["-D", "-V", "-S", "comp", "-e", "main"])


def test_refusals_are_one_line():
    g = GraphModule([("tri", 1, "generic", "uint"), ("uv", 2, "uv")])
    g.output("y", g.dense("l0", "uv", 3))
    with pytest.raises(TargetError, match=r"^unity: ids takes uint inputs \(tri\); a node's pins are floats$"):
        drop_in(g.export("ids", "ids"), "unity")
    with pytest.raises(ValueError, match=r"--prefix '2x': the node's function name needs a letter"):
        drop_in(_wide_bundle(), "unreal", "2x")


def test_cli(tmp_path, capsys):
    from inshade.cli import main

    _wide_bundle().save(tmp_path / "wide")
    out = tmp_path / "Wide.hlsl"
    assert main(["codegen", str(tmp_path / "wide"), "--target", "hlsl", "--engine", "unity", "--check",
                 "-o", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert "unity drop-in:" in stdout and "Name wide;" in stdout
    assert "max |hlsl (unity) - source| = " in stdout and "(rule 1e-05): ok" in stdout
    assert "void wide_float(float4 feat_0, float2 feat_1, float t, out float3 rgb, out float4 extra_0, " \
           "out float extra_1) {" in out.read_text()
    assert json.loads(out.with_suffix(".hlsl.json").read_text())["engine"] == "unity"
    assert main(["codegen", str(tmp_path / "wide"), "--target", "wgsl", "--engine", "unreal"]) == 2
    assert "--engine unreal: takes --target hlsl" in capsys.readouterr().err
