"""The importance-sampled environment (runtime/environment.py, shaders/lib/environment.glsl):
the numpy distribution against its own definition (normalisation, sampled density), the rotated
image against the SH path, GLSL against numpy through the real driver (tests/parity.py rule), and
the renderer binding the textures for a program that includes the chunk."""
from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from inshade import sh
from inshade.codegen.sdf import environment_sh
from inshade.scene.camera import camera_from_dict
from inshade.runtime.environment import (EnvironmentSampler, EnvironmentTextures, environment_image, mis_power,
                                         scene_environment)
from inshade.scene.image_io import load_environment, write_exr
from inshade.runtime.programs import ProgramCache
from inshade.runtime.render import FullscreenPass, float_target, read_rgba_raw, release_target, upload_float_texture
from inshade.runtime.renderer import SceneRenderer
from inshade.runtime.scene_inputs import rotated_map_sh as _rotated_map_sh
from inshade.scene.description import SceneError, load_scene

from parity import assert_parity, parity_settings

ROOT = Path(__file__).resolve().parents[2]


def random_image(seed: int, h: int, dark_rows: int = 0) -> np.ndarray:
    """A spiky random HDR map (a few bright texels), optionally with all-black rows."""
    rng = np.random.default_rng(seed)
    img = rng.random((h, 2 * h, 3)) ** 4 * 10.0
    img[rng.random((h, 2 * h)) < 0.02] *= 50.0
    if dark_rows:
        img[rng.choice(h, dark_rows, replace=False)] = 0.0
    return img.astype(np.float32)


# --- the numpy distribution -----------------------------------------------------------------

@pytest.mark.parametrize("case", ["noon", "random", "dark_rows", "black"])
def test_pdf_integrates_to_one(case):
    """sum pdf(w) dw over a grid 4x finer than the texels (cell centres never on a texel border),
    with each cell's exact solid angle: 1 to 1e-3 (the only error is 1/sin(theta) varying inside a
    cell, O(dtheta^2))."""
    img = {"noon": lambda: environment_image({"sky": "noon", "rotation": 25.0}),
           "random": lambda: random_image(1, 16),
           "dark_rows": lambda: random_image(2, 16, dark_rows=5),
           "black": lambda: np.zeros((16, 32, 3), np.float32)}[case]()
    s = EnvironmentSampler(img)
    k = 4
    w, h = s.width * k, s.height * k
    dirs = sh.equirect_directions(w, h).reshape(-1, 3)
    omega = sh.equirect_solid_angles(w, h).reshape(-1)
    total = float((s.pdf(dirs) * omega).sum())
    assert abs(total - 1.0) < 1e-3, total


@pytest.mark.parametrize("seed", [0, 5])
def test_sample_density_matches_pdf(seed):
    """Samples land in each half-texel cell (2x finer than the texels in u and v) as often as the
    pdf says: chi-square over the cells with an expected count >= 20, below dof + 6 sqrt(2 dof)
    (a 6-sigma bound; fixed seed). A sampler that forgot sin(theta), or whose offset inside a texel
    were not uniform in (u, v), is off by thousands. Every sample's pdf equals pdf(direction)."""
    img = random_image(seed, 8, dark_rows=2)
    s = EnvironmentSampler(img)
    n = 400_000
    u = np.random.default_rng(seed + 100).random((n, 2)).astype(np.float32)
    dirs, pdf = s.sample(u)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(pdf, s.pdf(dirs), rtol=1e-9)
    uv = sh.direction_to_equirect(dirs)
    cols, rows = 2 * s.width, 2 * s.height
    cell = np.clip(np.floor(uv[:, 1] * rows), 0, rows - 1).astype(int) * cols + \
        np.clip(np.floor(uv[:, 0] * cols), 0, cols - 1).astype(int)
    counts = np.bincount(cell, minlength=rows * cols)
    # expected: the pdf integrated over each cell = texel probability / 4 (uniform in (u, v))
    expected = n * np.repeat(np.repeat(s.texel_probability.astype(np.float64), 2, 0), 2, 1).reshape(-1) / 4
    assert counts[expected == 0].sum() == 0, "samples in texels of probability 0"
    keep = expected >= 20
    chi2 = float((((counts - expected) ** 2) / np.where(keep, expected, 1.0))[keep].sum())
    dof = int(keep.sum()) - 1
    assert chi2 < dof + 6 * math.sqrt(2 * dof), (chi2, dof)


def test_texel_weights_are_luminance_times_sin_theta():
    """The texel probabilities (not just self-consistent): luminance x sin(theta_centre), normalised.
    They are differences of float32 CDF values in [0, 1], hence exact only to a few float32 ulp of 1
    (2^-23 ~ 1.2e-7) absolute: atol 3e-7."""
    img = random_image(3, 8)
    s = EnvironmentSampler(img)
    lum = img.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    want = lum * np.sin((np.arange(8) + 0.5) * math.pi / 8)[:, None]
    np.testing.assert_allclose(s.texel_probability, want / want.sum(), rtol=1e-6, atol=3e-7)


def test_bad_images_and_settings():
    with pytest.raises(ValueError, match=r"W = 2H, got shape \[8, 8, 3\]"):
        EnvironmentSampler(np.ones((8, 8, 3)))
    bad = np.ones((8, 16, 3))
    bad[1, 1, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        EnvironmentSampler(bad)
    with pytest.raises(ValueError, match="environment.rotation"):
        environment_image({"sky": "noon", "rotation": float("nan")})
    with pytest.raises(ValueError, match="unknown sky preset 'mars'"):
        environment_image({"sky": "mars", "rotation": 0.0})
    with pytest.raises(ValueError, match="environment.map"):
        environment_image({"sky": "map", "rotation": 0.0})


# --- the image matches the SH lighting --------------------------------------------------------

@pytest.mark.parametrize("sky", ["sunset", "noon", "studio"])
@pytest.mark.parametrize("rotation", [0.0, 37.5, -120.0])
def test_preset_image_projects_to_the_scene_sh(sky, rotation):
    """The SH of the texture equals the SH the scene lights with (codegen/sdf.py environment_sh:
    the preset at 256x128 projected, then the SH rotated exactly). Both are equirect quadratures of
    the same analytic sky at different resolutions (512 vs 256 wide), so they differ by the
    discretisation error of the coarser one, which rotation does not change: at rotation 0 it is
    2.3e-4 of the largest coefficient for "sunset" (a sharp sun lobe near the horizon), 6e-5 for
    "noon", 2e-5 for "studio"; tolerance 1e-3. Rotating the wrong way is off by 4e-2 ("noon")
    to 1.5 ("studio") of the scale."""
    img = environment_image({"sky": sky, "rotation": rotation, "degree": 4})
    assert img.shape == (256, 512, 3) and img.dtype == np.float32
    got = sh.project_environment(img, 4)
    want = environment_sh(sky, rotation, 4)
    scale = np.abs(want).max()
    assert np.abs(got - want).max() < 1e-3 * scale, (np.abs(got - want).max(), scale)


@pytest.mark.parametrize("rotation", [45.0, 10.3])
def test_map_image_projects_to_the_rotated_map_sh(tmp_path, rotation):
    """A map: columns shifted by rotation / 360 * W. 45 deg on a 256-wide map is 32 whole texels,
    exact (1e-5 of the scale: float32 storage); 10.3 deg interpolates linearly between columns, which
    scales azimuthal frequency m by >= cos(pi m / W) (m <= 3 for degree 4: >= 1 - 7e-4): 1e-3."""
    path = write_exr(tmp_path / "env.exr", sh.procedural_sky("sunset", 256))
    env = {"sky": "map", "map": str(path), "rotation": 0.0}
    img = environment_image(env, {"rotation": rotation})
    want = _rotated_map_sh(sh.project_environment(load_environment(path), 4), rotation)
    got = sh.project_environment(img, 4)
    tol = 1e-5 if (rotation / 360 * 256).is_integer() else 1e-3
    scale = np.abs(want).max()
    assert np.abs(got - want).max() < tol * scale, (np.abs(got - want).max(), scale)


# --- GLSL against numpy -------------------------------------------------------------------------

def texel_interior_directions(s: EnvironmentSampler, seed: int, n: int) -> np.ndarray:
    """float32 unit directions at random texels, 0.1..0.9 of the way across them in u and v, so a
    float32 atan in the shader (error ~1e-7 rad against 0.1 texel >= 1e-3 rad) picks the same texel."""
    rng = np.random.default_rng(seed)
    i = rng.integers(0, s.height, n)
    j = rng.integers(0, s.width, n)
    v = (i + rng.uniform(0.1, 0.9, n)) / s.height
    u = (j + rng.uniform(0.1, 0.9, n)) / s.width
    theta, phi = math.pi * v, 2 * math.pi * (u - 0.5)
    d = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], -1)
    return d.astype(np.float32)


def run_env_pass(ctx, s: EnvironmentSampler, u: np.ndarray, dirs: np.ndarray, ab: np.ndarray) -> list:
    """passes/env_eval.frag over N samples (rows of 2 texels: (u, a, b), (dir, 0)); 3 outputs [N, 4]."""
    n = len(u)
    width = 64
    h = (n + width - 1) // width
    grid = np.zeros((h * width, 8), np.float32)
    grid[:n, 0:2], grid[:n, 2:4], grid[:n, 4:7] = u, ab, dirs
    cache = ProgramCache(ctx)
    prog = cache.get("common/fullscreen.vert", "passes/env_eval.frag")
    env = EnvironmentTextures(ctx, s)
    tex = upload_float_texture(ctx, grid.reshape(h, width * 2, 4))
    fbo = float_target(ctx, width, h, 3)
    pass_ = FullscreenPass(ctx, prog)
    ctx.viewport = (0, 0, width, h)
    try:
        assert env.bind(prog, first_unit=1) == 4
        pass_.render(fbo, textures={"u_inputs": tex})
        return [read_rgba_raw(fbo, k).reshape(-1, 4)[:n] for k in range(3)]
    finally:
        pass_.vao.release()
        env.release()
        tex.release()
        release_target(fbo)
        cache.release()


@given(sky=st.sampled_from(["sunset", "noon", "studio", "random"]), rotation=st.floats(-180, 180),
       seed=st.integers(0, 2**31 - 1))
@parity_settings(4)
def test_glsl_matches_numpy(gl, sky, rotation, seed):
    """env_sample (direction and pdf), env_pdf, env_radiance and mis_power under the parity rule.
    env_sample needs no care at CDF steps: the texel is chosen by float32 comparisons of the same
    float32 u against the same float32 CDF values on both sides (exact), and the offset inside the
    texel is continuous. Lookups use directions inside texels (texel_interior_directions)."""
    img = random_image(seed % 1000, 32, dark_rows=3) if sky == "random" else \
        environment_image({"sky": sky, "rotation": rotation})
    s = EnvironmentSampler(img)
    rng = np.random.default_rng(seed)
    n = 1024
    u = rng.random((n, 2)).astype(np.float32)
    u[:8] = [[0, 0], [0, 0.5], [0.5, 0], [1, 1], [0.99999994, 0.5], [0.25, 0.99999994], [0.75, 1e-7], [1e-7, 0.3]]
    u[8:40, 1] = s.marginal[rng.integers(0, s.height, 32)]           # exactly on CDF steps
    dirs = texel_interior_directions(s, seed, n)
    ab = (rng.random((n, 2)) * 10.0 ** rng.uniform(-6, 6, (n, 2))).astype(np.float32)
    ab[:4] = [[0, 0], [0, 1], [1, 0], [3e18, 1e-3]]
    out_sample, out_lookup, out_mis = run_env_pass(gl, s, u, dirs, ab)
    want_dirs, want_pdf = s.sample(u)
    assert (want_pdf[:8] > 0).sum() >= 6
    assert_parity(out_sample[:, :3], want_dirs, what="env_sample direction")
    assert_parity(out_sample[:, 3], want_pdf, what="env_sample pdf")
    assert_parity(out_lookup[:, :3], s.radiance(dirs), what="env_radiance")
    assert_parity(out_lookup[:, 3], s.pdf(dirs), what="env_pdf")
    assert_parity(out_mis[:, 0], mis_power(ab[:, 0], ab[:, 1]), what="mis_power(a, b)")
    assert_parity(out_mis[:, 1], mis_power(ab[:, 1], ab[:, 0]), what="mis_power(b, a)")


# --- the renderer binds it --------------------------------------------------------------------

@pytest.fixture
def env_probe():
    """A test-only technique whose program (tests/shaders/passes/env_probe.frag) includes lib/environment."""
    from inshade import technique

    record = technique.Technique("env_probe", "test: the environment texture along camera rays",
                                 programs=(technique.ProgramSpec("passes/env_probe.frag", geometry="sdf",
                                                                 attachments=2),))
    technique.techniques()      # built-ins first, so the registry's own loading does not race this
    technique.register(record)
    yield record
    technique.unregister("env_probe")


def probe_scene(tmp_path, environment: dict) -> Path:
    shutil.copy(ROOT / "trained" / "sdf_creature" / "sdf.json", tmp_path / "sdf.json")
    scene = {"format": "inshade.scene", "version": 1, "name": "env_probe", "program": "passes/env_probe.frag",
             "size": [48, 32], "networks": [], "sdf": "sdf.json",
             "camera": {"type": "orbit", "fov_y": 100.0, "target": [0, 0, 0], "distance": 3.0, "yaw": 30.0,
                        "pitch": 20.0},
             "environment": environment,
             "settings": {"sky": {"type": "choice", "default": environment.get("sky", "map"),
                                  "choices": ["sunset", "noon", "studio"], "environment": "sky"},
                          "env_rotation": {"type": "float", "default": 0.0, "min": -180.0, "max": 180.0,
                                           "environment": "rotation"}}}
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    return tmp_path / "scene.json"


def test_renderer_binds_the_environment_for_programs_that_use_it(gl, tmp_path, env_probe):
    """A scene whose program includes lib/environment gets the textures: the pass's env_radiance and
    env_pdf along its camera rays equal numpy's radiance/pdf of the same directions (read back from
    the pass), before and after changing the sky and rotation settings; release() frees them."""
    scene = load_scene(probe_scene(tmp_path, {"sky": "sunset", "rotation": 0.0}))
    camera = camera_from_dict(scene.camera)
    r = SceneRenderer(scene, gl)
    try:
        assert r.environment is not None
        seen = []
        for change in ({}, {"sky": "noon"}, {"env_rotation": 70.0}):
            for name, value in change.items():
                assert r.set_setting(name, value) == "uniform"
            r.render_network(camera, 48, 32)
            colour, ray = (r.read("network", k).reshape(-1, 4) for k in (0, 1))
            env = scene_environment(scene, r.values)
            s = EnvironmentSampler(environment_image(env))
            np.testing.assert_array_equal(r.environment.sampler.image, s.image)
            assert_parity(colour[:, :3], s.radiance(ray[:, :3]), what=f"env_radiance {env}")
            assert_parity(ray[:, 3], s.pdf(ray[:, :3]), what=f"env_pdf {env}")
            seen.append(colour[:, :3])
        assert np.abs(seen[0] - seen[1]).max() > 0.1 and np.abs(seen[1] - seen[2]).max() > 0.1
        textures = list(r.environment.textures.values())
    finally:
        r.release()
    assert r.environment is None
    assert all(type(t.mglo).__name__ == "InvalidObject" for t in textures)   # moderngl: released


def test_renderer_skips_the_environment_when_unused(gl):
    scene = load_scene(ROOT / "trained" / "sdf_creature")
    r = SceneRenderer(scene, gl)
    try:
        assert r.environment is None
    finally:
        r.release()


def test_environment_needs_a_lit_scene():
    class Bare:
        name, program, environment, settings = "bare", "passes/x.frag", None, {}

    with pytest.raises(ValueError, match="scene 'bare': program passes/x.frag samples the environment"):
        scene_environment(Bare(), {})


def test_mis_power_is_the_power_heuristic():
    np.testing.assert_allclose(mis_power([1.0, 2.0, 0.0, 3.0], [2.0, 1.0, 5.0, 0.0]), [0.2, 0.8, 0.0, 1.0])
    a, b = np.random.default_rng(0).random((2, 100)) * 100
    np.testing.assert_allclose(mis_power(a, b) + mis_power(b, a), 1.0, atol=1e-15)
