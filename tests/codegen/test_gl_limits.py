"""GL limits are part of codegen's plan (nothing silent, nothing partial).

For each limit a network depends on, a bundle that exceeds it (a limit lowered on purpose through
``limits=``, or llvmpipe's real one) either renders correctly in a layout that fits (exact path:
tests/parity.py's rule against the torch twin) or raises one clear LimitError naming the node,
the limit and the values. Never silently wrong. Limits missing from ``limits`` are the GL 3.3
minimums (codegen/limits.py).
"""
from __future__ import annotations

import numpy as np
import pytest
import torch

from inshade.codegen import generate
from inshade.codegen.glsl import TextureResource, UniformBlockResource
from inshade.codegen.limits import GL33_MINIMUMS, LimitError
from inshade.models import GraphModule, mlp_graph

from parity import check_parity, uniform_inputs
from test_lookup_array import lut_inputs, make_lut


def lut_bundle(res, channels=3, bits=32, seed=1, name="lut"):
    g = GraphModule([("uv", len(res))])
    g.add("lut", make_lut(res, channels, bits, seed=seed), "uv")
    g.output("y", "lut")
    return g.export(name)


def lut_parity(gl, res, limits, lut_filter="exact", channels=3, bits=32, n=256, tol=1e-5):
    bundle = lut_bundle(res, channels, bits)
    x = lut_inputs(0, n, len(res), res)
    check_parity(gl, bundle, x, tol=tol, lut_filter=lut_filter, limits=limits,
                 what=f"{res} {lut_filter} {bits}-bit under {limits}")
    return generate(bundle, lut_filter=lut_filter, limits=limits)


# --- GL_MAX_TEXTURE_SIZE: 1D and 2D arrays wrap into rows (exact), fast path errors ------------

@pytest.mark.parametrize("bits", [8, 16, 32])
def test_1d_array_wraps_into_rows_under_lowered_texture_size(gl, bits):
    gen = lut_parity(gl, [100], {"GL_MAX_TEXTURE_SIZE": 64}, bits=bits)
    (tex,) = gen.resources
    assert tex.data.shape[:2] == (2, 64)                  # 100 cells -> 2 rows of 64
    row = gen.plan.rows[0]
    assert row.storage == "texture/exact (wrap)"
    assert "GL_MAX_TEXTURE_SIZE is 64" in row.why and "64x2" in row.why
    assert gen.plan.limits["GL_MAX_TEXTURE_SIZE"] == {"uses": 64, "limit": 64, "source": "context"}
    assert "GL limits" in gen.plan.report()


def test_1d_array_fast_path_cannot_wrap(gl):
    with pytest.raises(LimitError, match=r"node lut: 1D lookup array of 100 cells needs a 100x1 texture.*"
                                         r"GL_MAX_TEXTURE_SIZE is 64"):
        generate(lut_bundle([100]), lut_filter="fast", limits={"GL_MAX_TEXTURE_SIZE": 64})


def test_2d_and_3d_arrays_wrap_on_the_exact_path(gl):
    gen = lut_parity(gl, [40, 5], {"GL_MAX_TEXTURE_SIZE": 32}, channels=5)   # 2 textures (5 channels)
    assert [r.data.shape[:2] for r in gen.resources] == [(7, 32), (7, 32)]  # 200 cells -> 7 rows
    gen = lut_parity(gl, [9, 7, 5], {"GL_MAX_3D_TEXTURE_SIZE": 8})
    assert gen.resources[0].dims == 2 and gen.plan.rows[0].storage == "texture/exact (wrap)"


def test_wrap_that_cannot_fit_raises(gl):
    with pytest.raises(LimitError, match=r"node lut: 2D lookup array of 40x40 = 1600 cells.*wrapped into rows "
                                         r"of a 2D texture it would need 32x50.*GL_MAX_TEXTURE_SIZE is 32"):
        generate(lut_bundle([40, 40]), limits={"GL_MAX_TEXTURE_SIZE": 32})


# --- GL_MAX_3D_TEXTURE_SIZE: 4D folds along y or x (both paths), else wraps / errors -----------

@pytest.mark.parametrize("lut_filter", ["exact", "fast"])
def test_4d_fold_moves_to_another_axis(gl, lut_filter):
    res, limits = [2, 3, 4, 5], {"GL_MAX_3D_TEXTURE_SIZE": 16}    # z = 4*5 = 20 > 16; y = 3*5 = 15 fits
    tol = 1e-5 if lut_filter == "exact" else 4 * 2.0**-8 * 4 + 1e-5   # fast: the documented bound, D <= 4
    gen = lut_parity(gl, res, limits, lut_filter=lut_filter, tol=tol)
    assert gen.resources[0].data.shape[:3] == (4, 15, 2)
    assert gen.plan.rows[0].storage == f"texture/{lut_filter} (fold)"
    assert "folded along y" in gen.plan.rows[0].why
    res = [3, 5, 4, 5]                                            # z 20, y 25 too big; x = 15 fits
    gen = lut_parity(gl, res, limits, lut_filter=lut_filter, tol=tol)
    assert gen.resources[0].data.shape[:3] == (4, 5, 15) and "folded along x" in gen.plan.rows[0].why


def test_4d_nothing_fits_exact_wraps_fast_errors(gl):
    limits = {"GL_MAX_3D_TEXTURE_SIZE": 4}
    gen = lut_parity(gl, [3, 3, 3, 3], limits)
    assert gen.plan.rows[0].storage == "texture/exact (wrap)"
    with pytest.raises(LimitError, match=r"node lut: 4D lookup array of 3x3x3x3 = 81 cells needs a 3x3x9 texture "
                                         r"\(z = 9\); GL_MAX_3D_TEXTURE_SIZE is 4 \(context\); the fast path"):
        generate(lut_bundle([3, 3, 3, 3]), lut_filter="fast", limits=limits)


# --- the three cases found on llvmpipe, at its real limits --------------------------------------

def test_llvmpipe_20000_cell_1d_array(gl, gl_limits):
    assert gl_limits["GL_MAX_TEXTURE_SIZE"] < 20000, "this case needs a driver whose 2D limit is < 20000"
    gen = lut_parity(gl, [20000], gl_limits)
    assert gen.plan.rows[0].storage == "texture/exact (wrap)"
    with pytest.raises(LimitError, match=r"node lut: 1D lookup array of 20000 cells needs a 20000x1 texture "
                                         r"\(x = 20000\); GL_MAX_TEXTURE_SIZE is \d+ \(context\)"):
        generate(lut_bundle([20000]), lut_filter="fast", limits=gl_limits)


@pytest.mark.parametrize("lut_filter", ["exact", "fast"])
def test_llvmpipe_2x2x64x64_4d_array(gl, gl_limits, lut_filter):
    assert gl_limits["GL_MAX_3D_TEXTURE_SIZE"] < 4096
    tol = 1e-5 if lut_filter == "exact" else 4 * 2.0**-8 * 4 + 1e-5
    gen = lut_parity(gl, [2, 2, 64, 64], gl_limits, lut_filter=lut_filter, tol=tol)
    assert gen.plan.rows[0].storage == f"texture/{lut_filter} (fold)"
    assert max(gen.resources[0].data.shape[:3]) <= gl_limits["GL_MAX_3D_TEXTURE_SIZE"]


def test_llvmpipe_20000x2_2d_array(gl, gl_limits):
    assert gl_limits["GL_MAX_TEXTURE_SIZE"] < 20000
    gen = lut_parity(gl, [20000, 2], gl_limits)
    assert gen.plan.rows[0].storage == "texture/exact (wrap)"
    with pytest.raises(LimitError, match=r"node lut: 2D lookup array of 20000x2 = 40000 cells.*GL_MAX_TEXTURE_SIZE"):
        generate(lut_bundle([20000, 2]), lut_filter="fast", limits=gl_limits)


def test_layouts_that_fit_are_unchanged():
    """Arrays within the limits keep the natural layout and the same code as before."""
    gen = generate(lut_bundle([4, 4, 4, 4]), limits={"GL_MAX_3D_TEXTURE_SIZE": 16})
    assert "inshade_lut4_exact(" in gen.chunk and "_fold" not in gen.chunk and "_wrapped" not in gen.chunk
    assert gen.plan.rows[0].storage == "texture/exact"


# --- dense layers: uniform blocks and the weight texture ---------------------------------------

def dense_bundle(in_dim, widths, out_dim, seed=0):
    torch.manual_seed(seed)
    return mlp_graph(in_dim, widths, out_dim, "tanh").export("mlp")


def test_ubo_block_size_lowered(gl):
    bundle = dense_bundle(8, [8], 4)   # 8 -> 8: 2x2 blocks = 256 + 32 B
    with pytest.raises(LimitError, match=r"node \w+: dense 8 -> 8 as a uniform block needs 288 B; "
                                         r"GL_MAX_UNIFORM_BLOCK_SIZE is 200 \(context\)"):
        generate(bundle, storage="ubo", limits={"GL_MAX_UNIFORM_BLOCK_SIZE": 200})
    # exactly at the limit it fits, and renders right
    check_parity(gl, bundle, uniform_inputs(1, 16, 8), storage="ubo", limits={"GL_MAX_UNIFORM_BLOCK_SIZE": 288})


def test_ubo_block_count_lowered():
    bundle = dense_bundle(4, [4, 4], 4)   # 3 dense layers
    with pytest.raises(LimitError, match=r"3 dense layers as uniform blocks need 3 blocks; "
                                         r"GL_MAX_FRAGMENT_UNIFORM_BLOCKS is 2 \(context\)"):
        generate(bundle, storage="ubo", limits={"GL_MAX_FRAGMENT_UNIFORM_BLOCKS": 2})


def test_weight_texture_too_wide_raises():
    bundle = dense_bundle(64, [4], 4)     # first layer 16 input blocks: 65 texels wide
    with pytest.raises(LimitError, match=r"the dense weight texture needs 65x\d+ texels.*GL_MAX_TEXTURE_SIZE is 64"):
        generate(bundle, storage="texture", limits={"GL_MAX_TEXTURE_SIZE": 64})


# --- samplers: every sampler the code declares counts --------------------------------------------

def test_sampler_units_lowered(gl):
    bundle = lut_bundle([4, 4], channels=9)   # 3 textures
    with pytest.raises(LimitError, match=r"samplers lut_lut_t0, lut_lut_t1, lut_lut_t2: needs samplers 3; "
                                         r"GL_MAX_TEXTURE_IMAGE_UNITS is 2 \(context\)"):
        generate(bundle, prefix="lut", limits={"GL_MAX_TEXTURE_IMAGE_UNITS": 2})
    with pytest.raises(LimitError, match="GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS is 2"):
        generate(bundle, limits={"GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS": 2})
    gen = generate(bundle, limits={"GL_MAX_TEXTURE_IMAGE_UNITS": 3})
    assert gen.plan.limits["GL_MAX_TEXTURE_IMAGE_UNITS"]["uses"] == 3


def test_missing_limits_are_gl33_minimums():
    gen = generate(lut_bundle([1500]))    # > 1024, the GL 3.3 minimum of GL_MAX_TEXTURE_SIZE
    assert gen.plan.rows[0].storage == "texture/exact (wrap)"
    assert gen.plan.limits["GL_MAX_TEXTURE_SIZE"] == {"uses": 1024, "limit": 1024, "source": "GL 3.3 minimum"}
    assert GL33_MINIMUMS["GL_MAX_3D_TEXTURE_SIZE"] == 256


# --- runtime: uploads are checked, never rendered as garbage ------------------------------------

class _Generated:
    def __init__(self, resources):
        self.resources = resources


def test_runtime_refuses_a_texture_over_the_driver_limit(gl):
    from inshade.runtime.network import NetworkResources

    big = gl.info["GL_MAX_TEXTURE_SIZE"] + 1
    res = TextureResource("net_big_t0", np.zeros((1, big, 4), np.float32), "f4")
    with pytest.raises(LimitError, match=rf"texture net_big_t0 \({big}x1, 4 channels, f4\).*GL_MAX_TEXTURE_SIZE"):
        NetworkResources(gl, _Generated([res]))


def test_runtime_checks_gl_errors_after_upload(gl, monkeypatch):
    """With the pre-check bypassed, the driver's GL_INVALID_VALUE is caught and named."""
    from inshade.runtime import network

    monkeypatch.setattr(network, "_check_fits", lambda ctx, res: None)
    big = gl.info["GL_MAX_TEXTURE_SIZE"] + 1
    res = TextureResource("net_big_t0", np.zeros((1, big, 4), np.float32), "f4")
    with pytest.raises(network.GLResourceError, match=r"texture net_big_t0 .*reported GL_INVALID_VALUE"):
        network.NetworkResources(gl, _Generated([res]))
    assert gl.error == "GL_NO_ERROR"
    block = UniformBlockResource("net_big_block", bytes(gl.info["GL_MAX_UNIFORM_BLOCK_SIZE"] + 16))
    monkeypatch.undo()
    with pytest.raises(LimitError, match=r"uniform block net_big_block .*GL_MAX_UNIFORM_BLOCK_SIZE"):
        network.NetworkResources(gl, _Generated([block]))


def test_runtime_refuses_more_samplers_than_units(gl):
    """The host program's samplers come first: binding past the driver's units raises."""
    from inshade.runtime.network import NetworkEvaluator

    units = gl.info["GL_MAX_TEXTURE_IMAGE_UNITS"]
    gen = generate(lut_bundle([2, 2], channels=8))   # 2 textures
    ev = NetworkEvaluator(gl, gen)
    try:
        assert ev.resources.bind(ev.program, first_unit=units - 2) == units
        with pytest.raises(LimitError, match=rf"sampler net_lut_t1 needs texture unit {units} .*"
                                             rf"GL_MAX_TEXTURE_IMAGE_UNITS is {units}"):
            ev.resources.bind(ev.program, first_unit=units - 1)
    finally:
        ev.release()
        ev.program.release()


def test_scene_renderer_limits_override(gl):
    """SceneRenderer(limits=...) plans against lowered limits: a shipped DI texture (88x88 and
    256-cell arrays) with GL_MAX_TEXTURE_SIZE 128 wraps the 256-cell ones on the exact path and
    renders like the natural layout; the fast path refuses with the clear error."""
    from pathlib import Path

    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(Path(__file__).resolve().parents[2] / "trained" / "di_texture_astronaut")
    cam = scene.make_camera()
    images = []
    for limits in (None, {"GL_MAX_TEXTURE_SIZE": 128}):
        r = SceneRenderer(scene, gl, settings={"lut_filter": "exact"}, limits=limits)
        try:
            if limits:
                assert any(row.storage == "texture/exact (wrap)" for row in r.generated[0].plan.rows)
            images.append(read_rgba(r.render_network(cam, 32, 32)))
        finally:
            r.release()
    np.testing.assert_allclose(images[1], images[0], rtol=1e-5, atol=1e-5)
    with pytest.raises(LimitError, match=r"GL_MAX_TEXTURE_SIZE is 128 \(context\); the fast path"):
        SceneRenderer(scene, gl, settings={"lut_filter": "fast"}, limits={"GL_MAX_TEXTURE_SIZE": 128}).release()
