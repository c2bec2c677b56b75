"""Progressive accumulation (ProgramSpec.accumulate, runtime/renderer.py SceneRenderer): the per-pixel
random numbers of shaders/lib/random.glsl against their numpy twin inshade/random.py (bit for bit),
and the running mean of a stochastic program over frames, with a test-only plug-in technique
(tests/plugins/toy_noise) whose samples are those random numbers: after N samples the target is the
numpy mean of the N samples, any change of the draw's inputs restarts it, and `inshade render --spp`
writes the mean and records spp."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from inshade import technique
from inshade.random import pcg, random_uniform
from inshade.runtime.render import float_target, read_rgba_raw, release_target

PLUGINS = Path(__file__).resolve().parents[1] / "plugins"
TOY = PLUGINS / "toy_noise"
FEW = settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _toy():
    """The toy_noise plug-in module, registered in this process (once)."""
    sys.path.insert(0, str(PLUGINS))
    try:
        import toy_noise
    finally:
        sys.path.remove(str(PLUGINS))
    if "toy_noise" not in [t.name for t in technique.techniques()]:
        technique.register(toy_noise.TECHNIQUE)
    return toy_noise


def expected_mean(camera, width, height, samples, *, gain=1.0):
    """The toy program's running mean after ``samples`` draws, float64, data orientation:
    attachment 0 = (gain * random_uniform3(stream 0), 1), attachment 1 = (random_uniform3(stream 1),
    u of the pixel centre under ``camera``)."""
    y, x = np.mgrid[0:height, 0:width]
    a0 = np.mean([random_uniform(x, y, i, 0, 3).astype(np.float64) for i in range(samples)], 0)
    a1 = np.mean([random_uniform(x, y, i, 1, 3).astype(np.float64) for i in range(samples)], 0)
    ox, _, ex, _ = camera.view(width, height)
    u = ox + (x + 0.5) / width * ex
    return (np.concatenate([np.float64(np.float32(gain)) * a0, np.ones((height, width, 1))], -1),
            np.concatenate([a1, u[..., None]], -1))


# running mean in float32 (mean + (x - mean) / n, one rounding or so per step) vs the exact mean of
# values in [0, 1): a few float32 ulps of 1 per sample
def mean_tol(samples: int) -> float:
    return 4 * samples * float(np.finfo(np.float32).eps)


# --- lib/random vs inshade/random.py -------------------------------------------------------------------
def test_pcg_known_values():
    """PCG-RXS-M-XS 32 (Jarzynski & Olano 2020), values worked out by hand from the published
    constants: state = v * 747796405 + 2891336453; word = ((state >> ((state >> 28) + 4)) ^ state) *
    277803737; out = (word >> 22) ^ word, all modulo 2**32."""
    def by_hand(v):
        m = 2 ** 32
        state = (v * 747796405 + 2891336453) % m
        word = (((state >> ((state >> 28) + 4)) ^ state) * 277803737) % m
        return (word >> 22) ^ word

    vs = [0, 1, 2, 12345, 2 ** 31, 2 ** 32 - 1]
    assert [int(pcg(v)) for v in vs] == [by_hand(v) for v in vs]
    assert pcg(np.array(vs, np.uint32)).dtype == np.uint32


@pytest.fixture
def random_pass(gl, fullscreen_test_pass):
    return gl, fullscreen_test_pass("passes/random_test.frag")


@FEW
@given(sample_index=st.integers(-2 ** 31, 2 ** 31 - 1), stream=st.integers(-2 ** 31, 2 ** 31 - 1),
       offset=st.tuples(st.integers(0, 2 ** 20), st.integers(0, 2 ** 20)))
def test_glsl_random_equals_numpy_bit_for_bit(random_pass, sample_index, stream, offset):
    gl, p = random_pass
    w, h = 9, 7
    fbo = float_target(gl, w, h, 2)
    try:
        gl.viewport = (0, 0, w, h)
        p.render(fbo, uniforms={"u_sample_index": sample_index, "u_stream": stream, "u_pixel_offset": offset})
        got4, narrow = read_rgba_raw(fbo, 0), read_rgba_raw(fbo, 1)
    finally:
        release_target(fbo)
    y, x = np.mgrid[0:h, 0:w]
    x, y = x + offset[0], y + offset[1]
    want = random_uniform(x, y, sample_index, stream, 4)
    np.testing.assert_array_equal(got4, want)
    np.testing.assert_array_equal(narrow[..., 0], random_uniform(x, y, sample_index, stream))
    np.testing.assert_array_equal(narrow[..., 1], random_uniform(x, y, sample_index, stream, 2)[..., 1])
    np.testing.assert_array_equal(narrow[..., 2], random_uniform(x, y, sample_index, stream, 3)[..., 2])


def test_numpy_random_is_uniform_and_decorrelated():
    """[0, 1), flat histogram, and neighbouring pixels / samples / streams / components unrelated."""
    y, x = np.mgrid[0:128, 0:128]
    u = random_uniform(x, y, 3, 0, 4).astype(np.float64)
    assert u.min() >= 0.0 and u.max() < 1.0
    counts = np.histogram(u, bins=16, range=(0, 1))[0]
    expect = u.size / 16
    assert np.abs(counts - expect).max() < 5 * np.sqrt(expect)   # ~5 sigma of a binomial count
    others = [random_uniform(x + 1, y, 3, 0, 4), random_uniform(x, y + 1, 3, 0, 4), random_uniform(x, y, 4, 0, 4),
              random_uniform(x, y, 3, 1, 4), np.roll(u, 1, -1)]
    for v in others:
        r = np.corrcoef(u.ravel(), np.asarray(v, np.float64).ravel())[0, 1]
        assert abs(r) < 0.02, r   # 65536 pairs: |r| of independent samples is ~0.004


def test_random_uniform_rejects_bad_width():
    with pytest.raises(ValueError, match="n: must be 1..4"):
        random_uniform(0, 0, 0, 0, 5)


# --- accumulation in SceneRenderer --------------------------------------------------------------------
@pytest.fixture
def toy_renderer(gl, tmp_path):
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    toy = _toy()
    scene = load_scene(toy.write(tmp_path / "noise", size=(8, 6)))
    r = SceneRenderer(scene, gl)
    yield r, scene
    r.release()


def _network(r):
    return read_rgba_raw(r._targets["network"], 0), read_rgba_raw(r._targets["network"], 1)


def test_running_mean_equals_numpy_mean_of_the_samples(toy_renderer):
    r, scene = toy_renderer
    cam = scene.make_camera()
    for n in range(1, 7):
        r.render(cam, 8, 6)   # each render of the same view adds one sample
        assert r.samples == n
        got0, got1 = _network(r)
        want0, want1 = expected_mean(cam, 8, 6, n)
        np.testing.assert_allclose(got0, want0, atol=mean_tol(n), rtol=0, err_msg=f"attachment 0, {n} samples")
        np.testing.assert_allclose(got1, want1, atol=mean_tol(n), rtol=0, err_msg=f"attachment 1, {n} samples")
    assert r.info(cam, 8, 6)["spp"] == 6
    # the displayed output is the mean too (attachment 0, image orientation)
    assert np.abs(r.read()[::-1][..., :3] - got0[..., :3]).max() == 0


def test_any_change_of_the_draw_restarts_the_mean(toy_renderer):
    r, scene = toy_renderer
    cam = scene.make_camera()
    for _ in range(3):
        r.render(cam, 8, 6)
    assert r.samples == 3
    cam.pan(2.0, 0.0, 8, 6)           # camera
    r.render(cam, 8, 6)
    assert r.samples == 1
    got, want = _network(r)[1], expected_mean(cam, 8, 6, 1)[1]
    np.testing.assert_array_equal(got[..., :3], want[..., :3])   # sample index 0 again, bit for bit
    np.testing.assert_allclose(got[..., 3], want[..., 3], atol=mean_tol(1), rtol=0)   # u under the panned camera
    r.render(cam, 8, 6)
    assert r.samples == 2
    assert r.set_setting("gain", 0.5) == "uniform"   # a setting (uniform)
    r.render(cam, 8, 6)
    assert r.samples == 1
    np.testing.assert_allclose(_network(r)[0], expected_mean(cam, 8, 6, 1, gain=0.5)[0], atol=mean_tol(1), rtol=0)
    r.render(cam, 8, 4)               # size
    assert r.samples == 1
    r.render(cam, 8, 4)
    assert r.samples == 2
    r.reload_weights()                # weights
    r.render(cam, 8, 4)
    assert r.samples == 1


def test_accumulate_draws_exactly_spp_and_caps_later_renders(toy_renderer):
    r, scene = toy_renderer
    cam = scene.make_camera()
    r.accumulate(cam, 8, 6, 5, progress=False)
    assert r.samples == 5
    r.render(cam, 8, 6)                # at the cap: the same view adds nothing
    assert r.samples == 5
    want0, want1 = expected_mean(cam, 8, 6, 5)
    np.testing.assert_allclose(_network(r)[1], want1, atol=mean_tol(5), rtol=0)
    r.accumulate(cam, 8, 6, 7, progress=False)   # more: continues from 5
    assert r.samples == 7
    np.testing.assert_allclose(_network(r)[1], expected_mean(cam, 8, 6, 7)[1], atol=mean_tol(7), rtol=0)
    r.accumulate(cam, 8, 6, 2, progress=False)   # fewer than held: restarts
    assert r.samples == 2
    np.testing.assert_allclose(_network(r)[1], expected_mean(cam, 8, 6, 2)[1], atol=mean_tol(2), rtol=0)
    with pytest.raises(ValueError, match="spp: must be an int >= 1, got 0"):
        r.accumulate(cam, 8, 6, 0)


def test_a_deterministic_program_takes_one_sample_only(gl):
    from inshade.runtime.headless import render_scene
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(Path(__file__).resolve().parents[2] / "trained" / "neural_image")
    assert not scene.spec.accumulate
    with pytest.raises(ValueError, match="spp 3: program passes/field2d.frag .* does not accumulate"):
        render_scene(scene, width=8, height=8, spp=3)
    r = SceneRenderer(scene, gl)
    try:
        cam = scene.make_camera()
        with pytest.raises(ValueError, match="spp 2: program passes/field2d.frag"):
            r.accumulate(cam, 8, 8, 2)
        r.accumulate(cam, 8, 8, 1)
        r.render(cam, 8, 8)
        r.render(cam, 8, 8)
        assert r.samples == 1 and r.info(cam, 8, 8)["spp"] == 1
    finally:
        r.release()


def test_cli_render_spp_writes_the_mean_and_records_spp(tmp_path):
    toy = _toy()
    asset = toy.write(tmp_path / "noise", size=(8, 6))
    from inshade.scene.description import load_scene

    cam = load_scene(asset).make_camera()
    shot = tmp_path / "mean.exr"
    env = dict(os.environ, INSHADE_TECHNIQUES=str(TOY))
    run = subprocess.run([sys.executable, "-m", "inshade.cli", "render", str(asset), "--spp", "4", "-o", str(shot),
                          "--set", "gain=0.75"], capture_output=True, text=True, env=env, timeout=600)
    assert run.returncode == 0, run.stderr
    from inshade.scene.image_io import read_exr

    image = np.asarray(read_exr(shot), np.float64)
    want0, _ = expected_mean(cam, 8, 6, 4, gain=0.75)
    np.testing.assert_allclose(image[::-1][..., :3], want0[..., :3], atol=mean_tol(4), rtol=0)
    sidecar = json.loads(Path(str(shot) + ".json").read_text())
    assert sidecar["spp"] == 4
    # the sidecar re-renders the same mean
    again = tmp_path / "again.exr"
    run = subprocess.run([sys.executable, "-m", "inshade.cli", "render", "--from", str(shot) + ".json", "-o",
                          str(again)], capture_output=True, text=True, env=env, timeout=600)
    assert run.returncode == 0, run.stderr
    np.testing.assert_array_equal(np.asarray(read_exr(again)), np.asarray(read_exr(shot)))

