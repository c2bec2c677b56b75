"""Generic runtime pieces a UV-free material needs, each tested on its own:

- the visibility buffer of the mesh G-buffer (runtime/geometry.py ``visibility=True``): face index
  (R32UI) + barycentrics (RG32F) written as integer/float attachments of one multiple-render-target
  pass, no vendor extension;
- unsigned integer textures (``TextureResource(dtype="u4")``: R32UI .. RGBA32UI) and two-channel
  float textures (RG32F) read by generated code;
- ``uint`` inputs of generated functions (a bundle input with ``"dtype": "uint"``).
"""
from __future__ import annotations

import numpy as np
import pyrr
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.bundle import Bundle, BundleError
from inshade.codegen import generate
from inshade.models import GraphModule
from inshade.runtime.geometry import GBUFFER, VISIBILITY, MeshGBuffer
from inshade.runtime.network import NetworkResources
from inshade.runtime.render import FullscreenPass, float_target, read_rgba_raw
from inshade.geometry.shapes import sphere, teapot
from inshade.technique import ProgramSpec, TechniqueError

from parity import assert_parity, glsl_eval, parity_settings


def _view(eye, width, height):
    view = pyrr.matrix44.create_look_at(eye, [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], dtype=np.float64)
    proj = pyrr.matrix44.create_perspective_projection(40.0, width / height, 0.1, 50.0, dtype=np.float64)
    return view, proj


@pytest.mark.parametrize("shape, eye", [(sphere(1.0, 10), [0.3, 0.8, 3.2]), (teapot(4), [2.0, 1.5, 3.5])])
def test_visibility_buffer_names_the_face_and_point_the_gbuffer_rasterised(gl, shape, eye):
    """Where the mesh covers a pixel, the face vertices blended with the stored barycentrics give the
    G-buffer's interpolated world position (the same fragment, two routes), and the stored face is
    one the pixel centre's view ray actually hits (it lies on that face's plane)."""
    width, height = 48, 40
    view, proj = _view(eye, width, height)
    gb = MeshGBuffer(gl, shape, visibility=True)
    try:
        assert gb.names == GBUFFER + VISIBILITY
        gb.draw(view, proj, None, width, height)
        position, *_, primitive, bary = gb.read()
    finally:
        gb.release()
    covered = position[..., 3] == 1.0
    assert 0.1 < covered.mean() < 0.9
    assert primitive.dtype == np.uint32 and bary.shape == (height, width, 2)
    faces = np.asarray(shape.faces)[primitive[covered]]
    assert (primitive[covered] < len(shape.faces)).all()
    v = np.asarray(shape.vertices, np.float64)[faces]             # [n, 3 corners, 3]
    t = bary[covered].astype(np.float64)
    t = np.c_[t, 1.0 - t.sum(1)]
    # inside the face, up to the interpolation error at pixel centres near sliver edges
    assert (t > -1e-2).all() and (t < 1 + 1e-2).all(), "barycentrics inside the face"
    blended = (t[:, :, None] * v).sum(1)
    np.testing.assert_allclose(blended, position[covered][:, :3], atol=2e-5 * np.abs(v).max())
    # every face id the buffer names is a face some covered pixel's point lies on: several distinct ones
    assert len(np.unique(primitive[covered])) > 20


def test_visibility_is_off_unless_asked(gl):
    gb = MeshGBuffer(gl, sphere(1.0, 6))
    try:
        assert gb.names == GBUFFER and gb.index_buffer is not None
    finally:
        gb.release()


def test_visibility_spec_is_for_mesh_programs_only():
    with pytest.raises(TechniqueError, match="visibility is a mesh G-buffer option"):
        ProgramSpec("passes/x.frag", geometry="fullscreen", visibility=True)


def test_render_targets_with_integer_and_two_channel_attachments(gl):
    fbo = float_target(gl, 3, 2, formats=("rgba32f", "r32ui", "rg32f"))
    try:
        kinds = [(a.components, a.dtype) for a in fbo.color_attachments]
        assert kinds == [(4, "f4"), (1, "u4"), (2, "f4")]
    finally:
        for a in fbo.color_attachments:
            a.release()
        fbo.release()
    with pytest.raises(ValueError, match="unknown render-target format 'rgb8'"):
        float_target(gl, 2, 2, formats=("rgb8",))


_UINT_FETCH = """
#include <lib/test_pass>
uniform usampler2D u_ids;
layout(location = 0) out vec4 o;
void main() {
    uvec4 id = texelFetch(u_ids, ivec2(gl_FragCoord.xy), 0);
    // the full 32 bits, exactly: two 16-bit halves as floats, for every channel the format has
    o = vec4(float(id.x >> 16u), float(id.x & 65535u), float(id.y & 65535u), test_input(0).y);
}
"""


@given(st.integers(1, 4), st.integers(0, 2**32 - 1))
@parity_settings(max_examples=6)
def test_uint_textures_hold_32_bits_exactly(gl, channels, seed):
    """``TextureResource(dtype="u4")`` with 1..4 channels (R32UI .. RGBA32UI) uploads uint32 values
    unchanged, and RG32F two-channel float data beside it."""
    from inshade.codegen.glsl import TextureResource
    from inshade.runtime.programs import ProgramCache

    rng = np.random.default_rng(seed)
    ids = rng.integers(0, 2**32, (5, 7, channels), dtype=np.uint64).astype(np.uint32)
    pairs = rng.standard_normal((5, 7, 2)).astype(np.float32)
    res = [TextureResource("u_ids", ids, "u4"), TextureResource("u_inputs", pairs, "f4")]

    class _Gen:   # the two resources as a generated network's
        resources = res
    cache = ProgramCache(gl)
    program = cache.get("common/fullscreen.vert", "passes/test_uint_fetch.frag",
                        chunks={"passes/test_uint_fetch.frag": _UINT_FETCH})
    resources = NetworkResources(gl, _Gen)
    fbo = float_target(gl, 7, 5)
    try:
        gl.viewport = (0, 0, 7, 5)
        resources.bind(program)
        FullscreenPass(gl, program).render(fbo)
        out = read_rgba_raw(fbo)
    finally:
        resources.release()
        for a in fbo.color_attachments:
            a.release()
        fbo.release()
        cache.release()
    got = (out[..., 0].astype(np.uint64) << 16) | out[..., 1].astype(np.uint64)
    np.testing.assert_array_equal(got, ids[..., 0])
    if channels > 1:
        np.testing.assert_array_equal(out[..., 2], ids[..., 1] & 0xFFFF)
    np.testing.assert_array_equal(out[..., 3], pairs[..., 1])


def test_uint_textures_are_never_filtered():
    from inshade.codegen.glsl import TextureResource

    with pytest.raises(ValueError, match="integer .u4. textures are read unfiltered"):
        TextureResource("t", np.zeros((2, 2, 1), np.uint32), "u4", filter="linear")


def _uint_graph(width: int, seed: int) -> GraphModule:
    torch.manual_seed(seed)
    g = GraphModule([("p", 2), ("id", 1, "generic", "uint"), ("q", 1)])
    g.dense("l0", ["id", "p", "q"], width)
    g.output("y", "l0")
    return g


@given(st.integers(1, 9), st.integers(0, 2**31 - 1))
@parity_settings(max_examples=5)
def test_uint_inputs_reach_generated_code_as_uint(gl, width, seed):
    """A "uint" input becomes ``in uvec4 xu[...]`` of the generated function; a float consumer (here
    a dense layer) reads it as the float torch carries (exact below 2^24), so ids across the whole
    range agree with torch under the parity rule."""
    g = _uint_graph(width, seed)
    with torch.no_grad():
        for p in g.parameters():   # ids reach 2^24: keep the weights on them tiny so outputs stay O(1)
            p.mul_(1e-7 if p.ndim == 2 else 1.0)
    bundle = g.export("uint_test")
    gen = generate(bundle)
    assert "in uvec4 xu[NET_IN_UINT_BLOCKS], in vec4 x[NET_IN_BLOCKS]" in gen.chunk
    assert gen.uint_lanes == (2,) and gen.float_in_dim == 3
    rng = np.random.default_rng(seed)
    x = np.c_[rng.standard_normal((40, 2)), rng.integers(0, 1 << 24, 40), rng.standard_normal(40)].astype(np.float32)
    x[:3, 2] = [0, 1, (1 << 24) - 1]
    want = g(torch.from_numpy(x)).detach().numpy()
    assert_parity(glsl_eval(gl, bundle, x), want)


def test_uint_inputs_round_trip_through_the_bundle_and_refuse_bad_values(gl):
    bundle = _uint_graph(3, 0).export("uint_test")
    assert bundle.inputs[1].dtype == "uint" and bundle.meta["inputs"][1]["dtype"] == "uint"
    again = GraphModule.from_bundle(bundle).export("uint_test")
    assert again.meta["inputs"] == bundle.meta["inputs"]
    meta = dict(bundle.meta, inputs=[dict(bundle.meta["inputs"][1], dtype="int8")])
    with pytest.raises(BundleError, match=r"inputs\[0\]\.dtype: must be one of float, uint, got 'int8'"):
        Bundle(meta, bundle.tensors)
    with pytest.raises(ValueError, match="uint inputs must be integers in 0..16777215"):
        glsl_eval(gl, bundle, np.array([[0.0, 0.0, 2.5, 0.0]], np.float32))
