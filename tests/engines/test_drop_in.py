"""Unity and Unreal drop-ins: the text written, wrapped as each engine wraps it, through the HLSL
driver against torch; pins split past 4 lanes; several networks in one shader; refusals in one line."""
from __future__ import annotations

import json
import sys

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
    """Every zoo network, as the engine calls it, against the torch module it came from (a lookup table:
    an image file the engine imports, read back as the engine lays it in memory)."""
    refused = []
    for name, (module, bundle, x) in zoo_bundles.items():
        try:
            d = drop_in(bundle, engine)
        except TargetError as e:
            refused.append(name)
            assert str(e).startswith(f"{engine}: b_lookup_array0_t0: a 3D texture, which this drop-in does not "
                                     "import as an image file yet"), e
            continue
        assert bool(d.images) == (name == "grid_texture"), name
        result = check_drop_in(d, module, bundle, x)
        assert result.ok, (name, result.line())
    assert refused == ["grid3d"]


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


@pytest.fixture(scope="module")
def shipped():
    from inshade.bundle import load
    from inshade.scene.description import load_scene, resolve_asset

    return {a: load(load_scene(resolve_asset(a)).networks[0].bundle) for a in ("neural_image", "hash_grid_image")}


@pytest.mark.parametrize("engine", ENGINES)
def test_weights_as_image_files(shipped, engine):
    """Dense weights in a texture (float EXR), lookup arrays (8-bit PNG) and a hash table (half EXR) as the
    engine imports them: the files written, read back and laid in memory as the engine does, through the
    HLSL driver against torch."""
    x = np.random.default_rng(2).random((1024, 2)).astype(np.float32)
    for name, bundle in shipped.items():
        d = drop_in(bundle, engine, storage="texture")
        formats = {f.name[len(d.generated.prefix) + 1:]: f.format for f, _ in d.images}
        assert formats == ({"weights": "exr float", "grid0_t0": "png 8-bit", "grid1_t0": "png 8-bit",
                            "grid2_t0": "png 8-bit"} if name == "neural_image" else
                           {"weights": "exr float", "grid_table0": "exr half"}), formats
        assert all(f"{f.name} (Texture" in d.node for f, _ in d.images)
        result = check_drop_in(d, GraphModule.from_bundle(bundle), bundle, x)
        assert result.ok, (name, result.line())


@pytest.mark.parametrize("engine", ENGINES)
def test_int8_weights_as_an_image_file(shipped, engine):
    """An i8 network's codes as an 8-bit PNG (unorm texels: an engine imports image files, not integer
    textures), its rows' biases and scales as a float EXR, and its hash table's u8 codes as a PNG."""
    from inshade.quantize import quantized

    bundle = quantized(shipped["hash_grid_image"], "i8")
    d = drop_in(bundle, engine, storage="texture")
    formats = {f.name[len(d.generated.prefix) + 1:]: f.format for f, _ in d.images}
    assert formats == {"weights_i8": "png 8-bit", "weights_i8_rows": "exr float", "grid_table0": "png 8-bit"}, formats
    x = np.random.default_rng(3).random((1024, 2)).astype(np.float32)
    result = check_drop_in(d, GraphModule.from_bundle(bundle), bundle, x)
    assert result.ok, result.line()


def test_each_engine_lays_the_rows_its_own_way(shipped, monkeypatch):
    """Unity's files hold the rows bottom-up, Unreal's top-down; read with the other engine's convention,
    the check fails: it reads what the engine would."""
    from inshade.engines import textures

    bundle = shipped["neural_image"]
    unity, unreal = (drop_in(bundle, e, storage="texture") for e in ("unity", "unreal"))
    for (fa, a), (fb, b) in zip(unity.images, unreal.images):
        assert fa.file == fb.file and np.array_equal(a, b[::-1]) and not np.array_equal(a, b)
    read = textures.engine_texture
    module = sys.modules["inshade.engines.drop_in"]   # the package's drop_in is the function of that name
    monkeypatch.setattr(module, "engine_texture", lambda record, path, engine, r: read(record, path, "unreal", r))
    x = np.random.default_rng(3).random((256, 2)).astype(np.float32)
    assert not check_drop_in(unity, GraphModule.from_bundle(bundle), bundle, x).ok


@pytest.mark.parametrize("engine", ENGINES)
def test_a_filtered_table_takes_the_engines_sampler(zoo_bundles, engine):
    """The fast lookup path filters in hardware: the texture's sampler is the node's (Unity's samplerstate,
    Unreal's <name>Sampler); float cells keep it under the rule."""
    module, bundle, x = zoo_bundles["grid_texture"]
    d = drop_in(bundle, engine, storage="texture", lut_filter="fast")
    assert any(f.filtered for f, _ in d.images)
    assert ("samplerstate" if engine == "unity" else "Sampler") in d.text
    result = check_drop_in(d, module, bundle, x)
    assert result.ok, result.line()


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


def test_cli_writes_the_images_and_their_readme(tmp_path, capsys):
    from inshade.cli import main

    _wide_bundle().save(tmp_path / "wide")
    out = tmp_path / "unreal" / "Wide.hlsl"
    out.parent.mkdir()
    argv = ["codegen", str(tmp_path / "wide"), "--target", "hlsl", "--engine", "unreal", "--storage", "texture",
            "--check", "-o", str(out)]
    assert main(argv) == 0
    assert "(rule 1e-05): ok" in capsys.readouterr().out
    manifest = json.loads(out.with_suffix(".hlsl.json").read_text())
    files = [t["file"] for t in manifest["textures"]]
    assert files == ["wide_weights.exr"] and (out.parent / files[0]).read_bytes()[:4] == b"v/1\x01"   # EXR magic
    readme = out.with_name("Wide.README.md").read_text()
    assert "HDR High Precision (RGBA32F)" in readme and "`wide_weights.exr` (wide_weights)" in readme
    assert main(argv) == 2   # nothing replaced without --force
    assert "exists; add --force" in capsys.readouterr().err
    assert main([*argv, "--force"]) == 0
