"""mesh_features (the UV-free feature hierarchy) on every shading language beside OpenGL's GLSL (WGSL,
Vulkan GLSL, HLSL, Slang: SPIR-V on wgpu over this machine's Vulkan device), held to the rules of its GL
test (tests/components/test_mesh_features.py), and the shipped materials using it on every target
(sparse_voxels: test_targets_voxels.py).

The shipped materials take their triangle ids as uint inputs (the compute harness's `xu`); the random
graphs take them as the exact float integers the component also accepts."""
from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given

from inshade.bundle import load
from inshade.codegen import generate
from inshade.components.mesh_features.torch_twin import MeshFeatures
from inshade.models import GraphModule
from inshade.runtime.compute import TARGETS
from parity import assert_parity, parity_settings, torch_reference
from test_mesh_features import LAYOUT_CASES, MESHES, feature_cases, feature_graph, grid, surface_points
from test_targets_latent import evaluate

REPO = Path(__file__).resolve().parents[2]
MESH_BUNDLES = sorted((REPO / "trained").glob("uvfree_material_*/*/bundle.json"))

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def assert_target(bundle, x, target, what, **options):
    out = evaluate(generate(bundle, target=target, **options), x, target)
    if out is not None:
        assert_parity(out, torch_reference(bundle, x), what=f"{target} {what}")


# --- mesh_features ----------------------------------------------------------------------------------

@pytest.mark.parametrize("target", TARGETS)
@parity_settings(max_examples=3)
@given(case=feature_cases())
def test_mesh_features_parity(target, case):
    """Random meshes, levels, widths, table sizes and precisions (f16, f32, u8), in wide rows or wrapped
    into rows of 16 texels; points on edges, vertices and sub-triangle boundaries."""
    mesh = MESHES.get(case["mesh"]) or grid(int(case["mesh"][-1]), case["seed"] % 97)
    bundle = feature_graph(mesh, case["levels"], case["feats"], case["size"], case["precision"], False,
                           case["seed"]).export("mesh_features_test")
    x = surface_points(len(mesh[1]), case["levels"], case["seed"])
    limits = {"GL_MAX_TEXTURE_SIZE": 16} if case["small"] else None
    assert_target(bundle, x, target, str(case), limits=limits)


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("layout", list(LAYOUT_CASES))
def test_mesh_features_topology_layouts(monkeypatch, target, layout):
    """Each owner-table layout (12, 16 or 24 bytes per face), ids using the top bits of every lane."""
    from inshade.components.mesh_features import emit as codegen

    _, limits, tables = LAYOUT_CASES[layout]
    for name, value in limits.items():
        monkeypatch.setattr(codegen, name, value)
    corners, edges = tables()
    g = GraphModule([("x", 3)])
    g.add("mf", MeshFeatures(3, 2, 1 << 14, corners, edges, "f32", init_scale=1.0, seed=4), "x")
    g.output("y", "mf")
    x = surface_points(len(corners), 3, 5, 192)
    x[-1, 0] = len(corners) - 1              # the face holding the largest ids
    assert_target(g.export("mesh_features_test"), x, target, layout, limits={"GL_MAX_TEXTURE_SIZE": 256})


def test_mesh_features_spell_a_uint_texture_in_every_language():
    bundle = feature_graph(MESHES["grid2"], 2, 4, 16).export("mesh_features_test")
    spelled = {"330": "uniform usampler2D net_mf_topology;", "vulkan": "uniform utexture2D net_mf_topology;",
               "wgsl": "var net_mf_topology: texture_2d<u32>;", "hlsl": "Texture2D<uint4> net_mf_topology :",
               "slang": "Texture2D<uint4> net_mf_topology :"}
    for target, text in spelled.items():
        chunk = generate(bundle, target=target).chunk
        assert text in chunk, target
    assert "&net_mf_corners, &net_mf_edges);" in generate(bundle, target="wgsl").chunk
    assert "    uvec3 net_mf_corners; uvec3 net_mf_edges;\n" in generate(bundle).chunk


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("path", MESH_BUNDLES, ids=lambda p: p.parent.parent.name)
def test_the_shipped_uvfree_materials_on_every_target(target, path):
    bundle = load(path)
    assert any(port.dtype == "uint" for port in bundle.inputs)
    p = next(n for n in bundle.nodes if n.type == "mesh_features").params
    assert_target(bundle, surface_points(p["faces"], p["levels"], 3, 64), target, path.parent.parent.name)
