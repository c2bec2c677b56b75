"""Every shading language codegen writes beside OpenGL's GLSL -- WGSL, Vulkan GLSL, HLSL, Slang -- run on
a real driver (runtime.compute: wgpu-native on this machine's Vulkan device; SPIR-V by glslang, and by
the Slang compiler slangpy ships) and held to the same rule as GLSL (tests/parity.py): dense layers in
every weight storage, activations, encodings, the zoo, the limits each API guarantees. Other components: tests/codegen/test_targets_*.py;
a component without a lowering is refused in one line (tests/components/test_component_folder.py)."""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from inshade.bundle import load
from inshade.codegen import generate
from inshade.codegen.limits import LimitError
from inshade.codegen.targets import TargetError
from inshade.runtime.compute import TARGETS, compute_device, run_target
from inshade.runtime.compute.run import shader_code
from parity import (MLPSpec, activation_specs, assert_conditioned, assert_parity, build_mlp, mlp_specs,
                    parity_settings, spec_inputs, torch_reference, uniform_inputs)


REPO = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.usefixtures("one_torch_thread")
STORAGES = ("inline", "ubo", "texture")
CASES = [(t, s) for t in TARGETS for s in STORAGES]


def evaluate(gen, x, target):
    return run_target(gen, x, target)[0]


def test_the_compute_device_is_this_machines_vulkan_driver():
    dev = compute_device()
    assert dev.backend == "Vulkan" and dev.name, dev.description


@pytest.mark.parametrize("target, storage", CASES)
@parity_settings(max_examples=5)
@given(data=st.data())
def test_random_mlp_parity(target, storage, data):
    spec = data.draw(mlp_specs(max_width=48, block_budget=160), label="spec")
    bundle = build_mlp(spec).export("mlp")
    x = spec_inputs(spec, 200)
    out = evaluate(generate(bundle, target=target, storage=storage), x, target)
    assert_parity(out, torch_reference(bundle, x), what=f"{target} {storage} {spec}")


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("precision", ["f16", "i8"])
def test_stored_precisions_on_every_target(target, precision):
    """Dense weights at f16 and i8 (inshade/quantize.py) in every storage, against the quantized twin."""
    from inshade.quantize import quantized

    spec = MLPSpec([3, 2], [21, 13], [("relu", {}), ("tanh", {})], 6, None, 0, [True, False, True], seed=11)
    run = MLPSpec([3], [24] * 4, [("relu", {})] * 4, 2, None, None, [True] * 5, seed=11)   # a folded texture run
    for spec, storages in ((spec, STORAGES), (run, ("texture",))):
        bundle = quantized(build_mlp(spec).export("mlp"), precision)
        x = spec_inputs(spec, 200)
        for storage in storages:
            out = evaluate(generate(bundle, target=target, storage=storage), x, target)
            assert_parity(out, torch_reference(bundle, x), what=f"{target} {storage} {precision} {spec}")


@pytest.mark.parametrize("target", TARGETS)
@parity_settings(max_examples=12)
@given(act=activation_specs())
def test_every_activation_on_every_target(target, act):
    """Each activation through hidden layers of odd widths (padding lanes, partial blocks, a lane path
    through the output tap), on inputs 40x past the unit range where the activation promises it."""
    spec = MLPSpec([3, 2], [13, 7], [act] * 2, 6, None, 0, [True] * 3, seed=7)
    bundle = build_mlp(spec).export("mlp")
    x = spec_inputs(spec, 128)
    if act[0] not in ("exp", "expm1", "sin", "cos"):
        x = np.concatenate([x, 40.0 * x])
    out = evaluate(generate(bundle, target=target, storage="inline"), x, target)
    assert_parity(out, torch_reference(bundle, x), what=f"{target} {act}")


# a device's queried storage-buffer count (lavapipe binds far more than the APIs' minimums: Vulkan's 4 leaves 2)
STORAGE_LIMITS = {"GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS": 16}


@pytest.mark.parametrize("target", TARGETS)
@parity_settings(max_examples=4)
@given(data=st.data())
def test_storage_buffer_weights_on_every_target(target, data):
    """``ssbo``: each layer's weights in a read-only storage buffer (Vulkan / WebGPU storage buffers, HLSL
    and Slang StructuredBuffers), the std140 block's bytes."""
    spec = data.draw(mlp_specs(max_width=48, block_budget=160), label="spec")
    bundle = build_mlp(spec).export("mlp")
    x = spec_inputs(spec, 200)
    out = evaluate(generate(bundle, target=target, storage="ssbo", limits=STORAGE_LIMITS), x, target)
    assert_parity(out, torch_reference(bundle, x), what=f"{target} ssbo {spec}")


def test_storage_buffers_are_planned_against_each_api_and_refused_by_opengl():
    bundle = _mlp([8, 8, 8])   # 4 layers: 4 buffers beside the caller's 2
    with pytest.raises(LimitError, match=r"4 dense layers as storage buffers need 4 blocks beside the 2 the caller "
                                         r"keeps; GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS is 4 \(Vulkan minimum "
                                         r"maxPerStageDescriptorStorageBuffers\)"):
        generate(bundle, target="vulkan", storage="ssbo")
    assert len(generate(bundle, target="wgsl", storage="ssbo").resources) == 4   # WebGPU: 8 per stage
    with pytest.raises(TargetError, match="OpenGL's GLSL \\(330\\) has no storage buffers") as e:
        generate(bundle, target="330", storage="ssbo")
    assert "\n" not in str(e.value)


def _mlp(widths, inputs=(4,)):
    spec = MLPSpec(list(inputs), list(widths), [("relu", {})] * len(widths), 4, None, None, [True] * (len(widths) + 1))
    return build_mlp(spec).export("mlp")


@pytest.mark.parametrize("target, storage, limit", [
    ("wgsl", "ubo", "WebGPU default maxUniformBufferBindingSize"),
    ("hlsl", "ubo", "D3D11 feature level 11_0 D3D11_REQ_CONSTANT_BUFFER_ELEMENT_COUNT x 16 B"),
    ("vulkan", "ubo", "Vulkan minimum maxUniformBufferRange"),
])
def test_a_uniform_block_past_the_targets_limit_is_refused_naming_it(target, storage, limit):
    bundle = _mlp([256, 256])      # 256 x 256: a 262,144-byte block
    with pytest.raises(LimitError) as e:
        generate(bundle, target=target, storage=storage)
    assert limit in str(e.value) and "\n" not in str(e.value)


def test_a_weight_texture_past_the_targets_side_is_refused_naming_its_limit():
    bundle = _mlp([4096], inputs=(64,))     # 4096 -> 4: 1 + 4 x 1024 texels wide, past Vulkan's 4096, within WebGPU's 8192
    with pytest.raises(LimitError, match="Vulkan minimum maxImageDimension2D"):
        generate(bundle, target="vulkan", storage="texture")
    assert generate(bundle, target="wgsl", storage="texture").resources[0].data.shape[1] == 4097


def test_too_many_uniform_blocks_are_refused_and_auto_plans_around_them():
    bundle = _mlp([32] * 13)       # 14 layers: a block each would pass WebGPU's 12 per stage
    with pytest.raises(LimitError, match="maxUniformBuffersPerShaderStage"):
        generate(bundle, target="wgsl", storage="ubo")
    gen = generate(bundle, target="wgsl", storage="auto")
    assert {r.storage for r in gen.plan.rows if r.type == "dense"} <= {"inline", "ubo", "texture"}
    x = np.random.default_rng(0).uniform(-1, 1, (64, 4)).astype(np.float32)
    assert_parity(evaluate(gen, x, "wgsl"), torch_reference(bundle, x), what="wgsl auto, 14 layers")


@pytest.mark.parametrize("target", ["vulkan", "hlsl", "slang"])
def test_the_sources_compile_with_their_languages_compiler(target):
    """Vulkan GLSL through glslangValidator -V, HLSL through glslang's HLSL front end (-D), Slang through the
    Slang compiler: each to SPIR-V, which wgpu's validation then takes (shader_code)."""
    bundle = _mlp([13, 9])
    for storage in STORAGES:
        code = shader_code(generate(bundle, target=target, storage=storage), target)
        assert code[:4] == b"\x03\x02\x23\x07", f"{target} {storage}: not SPIR-V"


def test_a_source_its_compiler_refuses_names_the_compiler_and_the_error():
    from inshade.runtime.compute import ShaderBuildError

    gen = generate(_mlp([13]), target="slang")
    broken = dataclasses.replace(gen, chunk=gen.chunk.replace("void net_eval(", "void net_evil(", 1))
    with pytest.raises(ShaderBuildError, match="slang -target spirv: .*undefined identifier"):
        run_target(broken, np.zeros((4, 4), np.float32), "slang")


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("encoding", ["frequency", "frequency_with_input", "triangle_wave", "one_blob",
                                      "spherical_harmonics"])
def test_encodings_on_every_target(target, encoding):
    """NeRF's frequencies (2^7 pi x: the range-reduced sin / cos), triangle waves (a modulo), tiny-cuda-nn's
    OneBlob and the SH basis up to degree 4 (on unit directions) feeding an MLP."""
    import torch

    from inshade.components.encodings.torch_twin import Frequency, SphericalHarmonics, TriangleWave
    from inshade.components.one_blob.torch_twin import OneBlob
    from inshade.models.graph import mlp_graph

    torch.manual_seed(3)
    enc = {"frequency": lambda: Frequency(8), "frequency_with_input": lambda: Frequency(3, include_input=True),
           "triangle_wave": lambda: TriangleWave(5), "one_blob": lambda: OneBlob(8),
           "spherical_harmonics": lambda: SphericalHarmonics(4)}[encoding]()
    bundle = mlp_graph(3, [16, 16], 4, "relu", enc).export("enc")
    x = np.random.default_rng(4).uniform(-1, 1, (256, 3)).astype(np.float32)
    if encoding == "spherical_harmonics":
        x /= np.linalg.norm(x, axis=1, keepdims=True)
    out = evaluate(generate(bundle, target=target, storage="inline"), x, target)
    assert_parity(out, torch_reference(bundle, x), what=f"{target} {encoding}")


def test_the_gl_runtime_keeps_its_context_beside_the_compute_driver(gl):
    """wgpu opens no GL backend of its own: the GL runtime draws before and after a compute target runs."""
    from parity import glsl_eval

    bundle = _mlp([8])
    x = np.random.default_rng(2).uniform(-1, 1, (16, 4)).astype(np.float32)
    before = glsl_eval(gl, bundle, x)
    run_target(generate(bundle, target="wgsl"), x, "wgsl")
    assert np.array_equal(glsl_eval(gl, bundle, x), before)


# the components whose shipped networks their own target tests run (tests/codegen/test_targets_*.py)
COVERED = {"lookup_array", "hash_grid", "dense_grid", "latent_pyramid", "shading_frames", "proxy_params",
           "mesh_features", "sparse_voxels"}
OTHERS = [p.parent for p in sorted((REPO / "trained").rglob("bundle.json"))
          if not COVERED & {n.type for n in load(p).nodes}]
# one network per asset (prt_atrium's 21 region networks share one shape); INSHADE_SLOW=1 runs every one
SHIPPED = OTHERS if os.environ.get("INSHADE_SLOW") else list(
    {p.relative_to(REPO / "trained").parts[0]: p for p in reversed(OTHERS)}.values())


def test_the_other_shipped_networks_are_found():
    names = {str(p.relative_to(REPO / "trained")) for p in OTHERS}
    assert {"prt_mechanical/transfer", "prt_neural_bunny/sdf", "prt_atrium/region_0"} <= names, names


@pytest.mark.parametrize("folder", SHIPPED, ids=lambda p: str(p.relative_to(REPO / "trained")))
def test_the_other_shipped_networks_on_every_target(folder):
    """Every shipped network the component tests do not run (PRT transfers and SDFs, plain MLPs): 64 points in
    [0, 1] on every target, under the rule or, where torch's own fp32 answer is past it, the conditioning rule
    (the frequency-encoded PRT transfers at positions and normals outside their training domain)."""
    bundle = load(folder)
    x = uniform_inputs(5, 64, bundle.in_dim, 0.0, 1.0)
    ref = torch_reference(bundle, x)
    for target in TARGETS:
        assert_conditioned(evaluate(generate(bundle, target=target), x, target), ref, bundle, x,
                           what=f"{target} {folder.name}")


@pytest.fixture(scope="module")
def zoo_bundles(tmp_path_factory):
    """The zoo's plain-torch networks exported (tests/zoo.py), with the inputs they were made for."""
    from zoo import exported

    return {name: (bundle, x) for name, (_, bundle, x) in
            exported(lambda name: tmp_path_factory.mktemp(name) / "b").items()}


@pytest.mark.parametrize("target", TARGETS)
def test_the_zoo_on_every_target(zoo_bundles, target):
    """Every zoo network matches torch on the target."""
    for name, (bundle, x) in zoo_bundles.items():
        gen = generate(bundle, target=target, storage="inline")
        assert_parity(evaluate(gen, x, target), torch_reference(bundle, x), what=f"{target} zoo {name}")


@pytest.mark.parametrize("target", ["330", "wgsl"])
def test_codegen_check_prints_the_measure_for_a_network_of_several_inputs(tmp_path, capsys, target):
    """`inshade codegen --check` on a bundle with two inputs (the torch twin takes them concatenated
    or one by one)."""
    from inshade.cli import main
    from inshade.models import GraphModule

    g = GraphModule([("p", 3, "position"), ("d", 3, "direction")])
    g.output("rgb", g.dense("l1", g.dense("l0", ["p", "d"], 8), 3))
    g.export("two", "two").save(tmp_path / "two")
    assert main(["-q", "codegen", str(tmp_path / "two"), "--target", target, "--check"]) == 0
    out = capsys.readouterr().out
    assert f"max |{'glsl' if target == '330' else target} - source| = " in out and "(rule 1e-05): ok (1026 rows" in out
