"""PRT shading (Learnt Transfer, Dhawal et al. 2022): lib/prt.glsl + passes/sdf_prt.frag vs the torch reference
(techniques/prt/twin.py), the light matrix vs the numpy triple product, the shading formulation vs the SH
toolkit, scene/renderer integration (settings, errors, network SDF geometry).

Tolerances: the transfer network at the shader's own hit points and normals (debug views 5/6):
|glsl - torch| <= 1e-4 (the network alone agrees to ~1e-6, tests/parity.py).
Images: PSNR >= 50 dB over all pixels of a 48x48 render, linear float, peak 1 (as tests/geometry/test_sdf.py:
silhouette pixels whose hit status differs between the executors are inside that budget).
Random untrained transfer networks (transfer_graph(width=16)): parity does not need training.
"""
from __future__ import annotations

import json
import math
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from inshade.techniques.prt import SHADING_MODES
from inshade.techniques.prt.codegen import light_matrix, light_matrix_blocks, light_matrix_uniform, prt_chunk
from inshade.codegen.sdf import environment_sh
from inshade.techniques.prt.twin import (PrtShading, compose, image_metrics, light_matrix_t, phong_bands_f32, prt_glossy,
                                quality_orbit, render, trace_view)
from inshade.techniques.prt.transfer_model import TransferFrame, transfer_graph
from inshade.sh import (convolve_zonal, lambert_bands, phong_bands, sh_evaluate, sh_product, triple_product_tensor)

from prt_gl import PRT_SETTINGS, render_with_gbuffer

ROOT = Path(__file__).resolve().parents[3]
SIZE = 48

SDF_SCENE = {  # a blob on a slab: self-occlusion where they meet, visible from the test camera
    "format": "inshade.geometry.sdf", "version": 1, "name": "prt_test",
    "bound": {"center": [0.0, 0.0, 0.0], "radius": 1.6},
    "trace": {"max_steps": 96, "step_scale": 0.9, "hit_eps": 0.001, "normal_eps": 0.001},
    "root": {"type": "union", "k": 0.1, "children": [
        {"type": "sphere", "radius": 0.55, "albedo": [0.8, 0.5, 0.3]},
        {"type": "transform", "translate": [0.0, -0.6, 0.0],
         "child": {"type": "round_box", "size": [1.0, 0.12, 0.8], "radius": 0.05, "albedo": [0.6, 0.6, 0.65]}}]},
}
CAMERA = {"type": "orbit", "fov_y": 40.0, "target": [0.0, -0.1, 0.0], "distance": 3.6, "yaw": -25.0, "pitch": -20.0}


def transfer_bundle(center, radius, seed=0, width=16, scale=1.2):
    torch.manual_seed(seed)
    g = transfer_graph(width=width, layers=2, pos_freqs=3, normal_freqs=2)
    frame = TransferFrame(tuple(center), radius, scale)
    return g, frame, g.export("transfer", f"transfer_{seed}", render={"transfer": frame.to_dict()})


def write_scene(folder: Path, *, sdf=None, networks=None, program="passes/sdf_prt.frag", environment=None,
                settings=None, extra=None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    if sdf is None:
        (folder / "sdf.json").write_text(json.dumps(SDF_SCENE))
        sdf = "sdf.json"
    data = {"format": "inshade.scene", "version": 1, "name": folder.name, "program": program, "size": [SIZE, SIZE],
            "networks": [{"bundle": "transfer", "prefix": "transfer"}] if networks is None else networks,
            "sdf": sdf, "camera": CAMERA, "environment": environment or {"sky": "noon", "rotation": 0.0, "degree": 4},
            "settings": PRT_SETTINGS if settings is None else settings, **(extra or {})}
    (folder / "scene.json").write_text(json.dumps(data))
    return folder


@pytest.fixture(scope="module")
def prt_scene(tmp_path_factory):
    from inshade.geometry.sdf import parse_sdf

    folder = tmp_path_factory.mktemp("prt_scene")
    sdf = parse_sdf(SDF_SCENE)
    graph, frame, bundle = transfer_bundle(sdf.center, sdf.radius)
    bundle.save(folder / "transfer")
    write_scene(folder)
    return folder, graph, frame



def _gl_render(gl, program_cache, folder, settings_seq, size=SIZE):
    """Render the scene once per settings dict in ``settings_seq`` through one SceneRenderer
    (settings changes take the uniform path); returns the linear RGBA images and the renderer's
    environment SH of the last one."""
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(folder)
    r = SceneRenderer(scene, gl, cache=program_cache)
    images, outcomes = [], []
    try:
        cam = scene.make_camera()
        for settings in settings_seq:
            outcomes.append([r.set_setting(k, v) for k, v in settings.items()])
            images.append(read_rgba(r.render_network(cam, size, size)).copy())
        sh = r.environment_sh()
        program = r.program
    finally:
        r.release()
    return images, sh, scene, outcomes, program


def _psnr(a, b):
    mse = float(np.mean((np.asarray(a, np.float64)[..., :3] - b[..., :3]) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(1.0 / mse)


# CPU side: light matrix, bands, formulation --------------------------------------------------------
def test_light_matrix_vs_numpy_triple_product():
    rng = np.random.default_rng(0)
    env = environment_sh("sunset", 30.0)
    m = light_matrix(env)
    tau = triple_product_tensor(4)
    direct = np.zeros((3, 16, 16))
    for c in range(3):
        for k in range(16):
            for i in range(16):
                direct[c, k, i] = sum(tau[i, j, k] * float(env[j, c]) for j in range(16))
    np.testing.assert_allclose(m, direct, rtol=0, atol=1e-12)
    t = rng.normal(size=16)
    np.testing.assert_allclose(np.einsum("cki,i->kc", m, t), sh_product(env.astype(np.float64), np.stack([t] * 3, 1)),
                               atol=1e-12)
    # the uniform's mat4 blocks (column-major) multiply out to M_c t as GLSL computes it
    blocks = np.frombuffer(light_matrix_uniform(env), np.float32).reshape(48, 4, 4)
    np.testing.assert_array_equal(blocks, light_matrix_blocks(m))
    tb = t.reshape(4, 4)
    for c in range(3):
        h = np.concatenate([sum(blocks[c * 16 + 4 * bk + bi].T.astype(np.float64) @ tb[bi] for bi in range(4))
                            for bk in range(4)])
        np.testing.assert_allclose(h, m[c] @ t, rtol=1e-6, atol=1e-6)
    assert light_matrix_uniform(env) == light_matrix_uniform(env.copy())    # deterministic
    with pytest.raises(ValueError, match="non-finite"):
        light_matrix(np.full((16, 3), np.nan))
    with pytest.raises(ValueError, match=r"\[16, 3\]"):
        light_matrix(np.zeros((9, 3)))


@pytest.mark.parametrize("s", [0.0, 1.0, 3.5, 16.0, 200.0])
def test_phong_bands_f32_match_toolkit(s):
    np.testing.assert_allclose(phong_bands_f32(s), phong_bands(s, 4), rtol=2e-6, atol=1e-7)


def test_glossy_formulation_vs_sh_toolkit():
    """prt_glossy = sum_k g_l H_k y_k(R), H = projection of (lighting x transfer): checked against
    sh_product + convolve_zonal + sh_evaluate; exponent 1 gives lambert/pi, a huge exponent the
    band-limited product itself (every g_l -> 1)."""
    rng = np.random.default_rng(1)
    env = environment_sh("studio", -40.0)
    t = rng.normal(size=(5, 16)).astype(np.float32)
    r = rng.normal(size=(5, 3))
    r = (r / np.linalg.norm(r, axis=1, keepdims=True)).astype(np.float32)
    m = light_matrix_t(env)
    for s in (0.0, 1.0, 12.0, 1e5):
        got = prt_glossy(torch.from_numpy(t), torch.from_numpy(r), s, m).numpy()
        for n in range(5):
            h = sh_product(env.astype(np.float64), np.stack([t[n].astype(np.float64)] * 3, 1))
            want = sh_evaluate(convolve_zonal(h, phong_bands(s, 4)), r[n].astype(np.float64))
            np.testing.assert_allclose(got[n], want, rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(phong_bands_f32(1.0), lambert_bands(4) / math.pi, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(phong_bands_f32(1e5), 1.0, atol=1e-4)


def test_unoccluded_diffuse_is_irradiance():
    """Shading sanity: with the analytic unoccluded transfer (Lambert bands x basis of n), diffuse
    PRT is exactly the SH irradiance shading of models/sdf.py (sdf_diffuse)."""
    from inshade.techniques.prt.twin import prt_diffuse
    from inshade.models.sdf import sh_irradiance_t
    from inshade.sh import band_of, sh_basis

    rng = np.random.default_rng(2)
    n = rng.normal(size=(64, 3))
    n = torch.from_numpy((n / np.linalg.norm(n, axis=1, keepdims=True)).astype(np.float32))
    t = sh_basis(n, 4, torch) * torch.from_numpy(lambert_bands(4)[band_of(4)].astype(np.float32))
    env = torch.from_numpy(environment_sh("noon"))
    np.testing.assert_allclose(prt_diffuse(t, env).numpy(), sh_irradiance_t(env, n).numpy(), rtol=1e-5, atol=1e-5)


def test_prt_chunk_deterministic_and_checked(prt_scene):
    from inshade.bundle import load
    from inshade.techniques.prt.codegen import PrtError

    folder, graph, frame = prt_scene
    b = load(folder / "transfer")
    assert prt_chunk(b, "transfer") == prt_chunk(load(folder / "transfer"), "transfer")
    assert "#include <network_transfer>" in prt_chunk(b, "transfer")
    assert "#define PRT_NET_EVAL transfer_eval" in prt_chunk(b, "transfer")
    assert "#define PRT_NET_EVAL net_eval" in prt_chunk(b, "net")
    other = graph.export("neural_image", "not_transfer")
    with pytest.raises(PrtError, match="kind"):
        prt_chunk(other)
    no_frame = graph.export("transfer", "no_frame")
    with pytest.raises(PrtError, match="render.transfer"):
        prt_chunk(no_frame)


@pytest.mark.parametrize("version", ["330", "450", "es300"])
def test_prt_passes_pass_glslang(prt_scene, tmp_path, version):
    """Both PRT passes, fully assembled, pass the reference compiler (stricter than Mesa)."""
    import subprocess

    from inshade.bundle import load
    from inshade.codegen.network import generate
    from inshade.techniques.prt.codegen import prt_chunks
    from inshade.codegen.sdf import sdf_chunks
    from inshade.codegen.spherical_harmonics import sh_chunks
    from inshade.geometry.sdf import parse_sdf
    from inshade.shaders import assemble
    from inshade.technique import choice_chunks, program_spec

    assert shutil.which("glslangValidator"), "glslangValidator not found on PATH: install glslang-tools"
    b = load(prt_scene[0] / "transfer")
    chunks = {"network_transfer": generate(b, prefix="transfer", target=version).chunk, **prt_chunks(b, "transfer"),
              **sdf_chunks(parse_sdf(SDF_SCENE)), **sh_chunks(4)}
    for program in ("passes/sdf_prt.frag", "passes/mesh_prt.frag"):
        path = tmp_path / f"{program.split('/')[1]}.{version}.frag"
        choices = choice_chunks(program_spec(program)[1])
        path.write_text(assemble(program, version=version, chunks={**chunks, **choices}).source)
        result = subprocess.run(["glslangValidator", str(path)], capture_output=True, text=True)
        assert result.returncode == 0, f"{program} ({version}):\n{result.stdout}{result.stderr}"


# GLSL vs torch ---------------------------------------------------------------------------------------
def test_transfer_at_hit_points_glsl_vs_torch(gl, program_cache, prt_scene):
    """The network in the shader at the shader's own hit points and normals vs the torch network
    at those points: <= 1e-4."""
    from inshade.techniques.prt.transfer_model import evaluate_transfer

    folder, graph, frame = prt_scene
    images, _, _, _, _ = _gl_render(gl, program_cache, folder, [{"debug": d} for d in (5, 6, 1, 2, 3, 4)])
    pos, nrm = images[0], images[1]
    mask = pos[..., 3] > 0.5
    assert mask.sum() > 0.25 * SIZE * SIZE, "the test camera should see the object"
    transfer_gl = np.concatenate([im[mask] for im in images[2:]], -1)         # [M, 16]
    with torch.no_grad():
        ref = evaluate_transfer(graph, frame, torch.from_numpy(pos[mask][:, :3]), torch.from_numpy(nrm[mask][:, :3]))
    err = np.abs(transfer_gl - ref.numpy()).max()
    assert err <= 1e-4, f"max |glsl - torch| transfer at hit points {err:.3g}"
    # and the shader's normals are unit length
    np.testing.assert_allclose(np.linalg.norm(nrm[mask][:, :3], axis=1), 1.0, atol=1e-5)


@pytest.mark.parametrize("mode,sky,rotation", [("diffuse", "noon", 0.0), ("glossy", "sunset", 90.0)])
def test_image_glsl_vs_torch_reference(gl, program_cache, prt_scene, mode, sky, rotation):
    folder, graph, frame = prt_scene
    settings = {"shading": mode, "sky": sky, "env_rotation": rotation, "phong_exponent": 8.0, "ks": 0.7}
    images, sh, scene, _, _ = _gl_render(gl, program_cache, folder, [settings])
    np.testing.assert_array_equal(sh, environment_sh(sky, rotation))
    cam = scene.make_camera()
    shading = PrtShading(mode=mode, exponent=8.0, albedo=1.0, kd=1.0, ks=0.7)
    ref = render(scene.sdf, graph, frame, cam.uniforms(SIZE, SIZE), SIZE, SIZE, sh, shading)
    hit = ref["hit"]
    assert hit.mean() > 0.25
    surface = images[0][..., :3][hit] - ref["rgba"][..., :3][hit]
    assert np.abs(ref["rgba"][..., :3][hit]).max() > 0.05, "shading should not be trivially zero"
    psnr = _psnr(images[0], ref["rgba"])
    assert psnr >= 50.0, f"{mode}: PSNR {psnr:.1f} dB (surface max err {np.abs(surface).max():.3g})"


def test_glossy_ks_and_settings_take_the_uniform_path(gl, program_cache, prt_scene):
    folder, _, _ = prt_scene
    seq = [{}, {"shading": "glossy", "ks": 0.0}, {"ks": 0.8}, {"phong_exponent": 64.0}, {"sky": "sunset"},
           {"env_rotation": 120.0}, {"albedo": 0.5}]
    images, sh, _, outcomes, _ = _gl_render(gl, program_cache, folder, seq)
    assert all(o == "uniform" for row in outcomes for o in row), outcomes
    diffuse, glossy_ks0 = images[0], images[1]
    np.testing.assert_array_equal(glossy_ks0, diffuse)          # ks = 0: glossy adds exactly nothing
    for a, b, what in zip(images[1:], images[2:], ["ks", "exponent", "sky", "rotation", "albedo"]):
        assert np.abs(a - b).max() > 1e-3, f"changing {what} did not change the image"


def test_light_matrix_follows_environment(gl, program_cache, prt_scene):
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    folder, _, _ = prt_scene
    scene = load_scene(folder)
    r = SceneRenderer(scene, gl, cache=program_cache)
    try:
        cam = scene.make_camera()
        u1 = r._uniforms(r.program, cam, 8, 8)["u_prt_light"]
        r.set_setting("env_rotation", 45.0)
        u2 = r._uniforms(r.program, cam, 8, 8)["u_prt_light"]
    finally:
        r.release()
    assert u1 == light_matrix_uniform(environment_sh("noon", 0.0))
    assert u2 == light_matrix_uniform(environment_sh("noon", 45.0)) and u1 != u2


def test_unbound_prt_uniforms_take_defaults(gl, program_cache, prt_scene, tmp_path):
    """A scene without PRT settings gets techniques/prt/codegen.py UNIFORM_DEFAULTS (= PrtShading()) every
    frame, even on a program another renderer left in a debug view."""
    import dataclasses

    from inshade.techniques.prt import UNIFORM_DEFAULTS

    d = PrtShading()
    assert (SHADING_MODES[UNIFORM_DEFAULTS["u_shading"]], UNIFORM_DEFAULTS["u_phong_exponent"],
            UNIFORM_DEFAULTS["u_albedo"], UNIFORM_DEFAULTS["u_kd"], UNIFORM_DEFAULTS["u_ks"]) == \
        dataclasses.astuple(d)
    src, _, _ = prt_scene
    shutil.copytree(src / "transfer", tmp_path / "transfer")
    plain = write_scene(tmp_path, settings={})
    first, _, _, _, _ = _gl_render(gl, program_cache, src, [{"debug": 5}, {"debug": 0}])
    second, _, _, _, _ = _gl_render(gl, program_cache, plain, [{}])
    np.testing.assert_array_equal(second[0], first[1])


# network SDF geometry ---------------------------------------------------------------------------------
def _fit_blob_sdf(width=48):
    """A network SDF without training: random softplus features, output layer by least squares
    to an ellipsoid's distance bound (instant; smooth; a plausible SDF-like field)."""
    from inshade.components.elementwise.torch_twin import Softplus
    from inshade.models.graph import mlp_graph
    from inshade.models.network_sdf import NetworkSdfModule

    torch.manual_seed(0)
    graph = mlp_graph(3, [width], 1, activation=Softplus())
    module = NetworkSdfModule(graph, {"max_steps": 64, "step_scale": 0.7, "hit_eps": 1e-3, "normal_eps": 1e-3},
                              center=(0.0, 0.0, 0.0), radius=1.2, albedo=(0.7, 0.6, 0.5), name="blob")
    q = torch.rand(4096, 3, generator=torch.Generator().manual_seed(0)) * 2 - 1
    d = (torch.sqrt((q * q * torch.tensor([1.0, 2.0, 1.0])).sum(-1)) - 0.5)[:, None]   # normalised units
    with torch.no_grad():
        l0, l1 = graph.nodes["l0"].linear, graph.nodes["l1"].linear
        l0.weight.normal_(0.0, 2.0)
        l0.bias.uniform_(-1.5, 1.5)
        h = graph.nodes["a0"](l0(q))
        x = torch.linalg.lstsq(torch.cat([h, torch.ones(h.shape[0], 1)], 1).double(), d.double()).solution.float()
        l1.weight.copy_(x[:-1].T)
        l1.bias.copy_(x[-1])
    return module


def test_network_sdf_scene_glsl_vs_torch(gl, tmp_path):
    """"sdf": {"network": bundle}: a network SDF traced by the same PRT pass (one more generated
    chunk + its GL resources), diffuse and glossy vs the torch reference with the NetworkSdfModule."""
    module = _fit_blob_sdf()
    module.export(name="blob").save(tmp_path / "sdfnet")
    graph, frame, bundle = transfer_bundle(module.scene.center, module.scene.radius, seed=3)
    bundle.save(tmp_path / "transfer")
    folder = write_scene(tmp_path, sdf={"network": "sdfnet"})
    images, sh, scene, _, _ = _gl_render(gl, None, folder, [{}, {"shading": "glossy"}], size=32)
    cam = scene.make_camera()
    for image, mode in zip(images, SHADING_MODES):
        ref = render(module, graph, frame, cam.uniforms(32, 32), 32, 32, sh,
                     PrtShading(mode=mode, exponent=8.0, ks=0.5))
        assert ref["hit"].mean() > 0.1
        psnr = _psnr(image, ref["rgba"])
        assert psnr >= 50.0, f"network SDF {mode}: PSNR {psnr:.1f} dB"


# scene errors -----------------------------------------------------------------------------------------
def _scene_error(folder, match):
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import SceneError, load_scene

    with pytest.raises(SceneError, match=match) as info:
        SceneRenderer(load_scene(folder))
    assert "scene.json" in str(info.value)
    return str(info.value)


def test_missing_transfer_network_one_clear_error(tmp_path, prt_scene):
    _scene_error(write_scene(tmp_path / "none", networks=[]), "networks: passes/sdf_prt.frag needs a network of kind 'prt'")
    _scene_error(write_scene(tmp_path / "missing"), r"networks\[0\]\.bundle: no bundle at")
    # a bundle that is not a transfer network
    folder = tmp_path / "wrong_kind"
    torch.manual_seed(0)
    g = transfer_graph(width=8, layers=1)
    g.export("neural_image", "image_net").save(folder / "transfer")
    _scene_error(write_scene(folder), "needs a transfer network")
    # no geometry
    folder = write_scene(tmp_path / "no_sdf")
    data = json.loads((folder / "scene.json").read_text())
    del data["sdf"]
    (folder / "scene.json").write_text(json.dumps(data))
    _scene_error(folder, "sdf: passes/sdf_prt.frag traces an SDF")
    # the shading choice may name only the declared modes (SHADING_MODES)
    bad = dict(PRT_SETTINGS, shading=dict(PRT_SETTINGS["shading"], choices=["diffuse", "phong"]))
    shutil.copytree(prt_scene[0] / "transfer", tmp_path / "modes" / "transfer")
    _scene_error(write_scene(tmp_path / "modes", settings=bad),
                 "settings.shading.choices: 'phong' is not a u_shading value")


def test_bad_environment_one_clear_error(tmp_path, prt_scene):
    from inshade.scene.image_io import write_exr

    src, _, _ = prt_scene

    def with_env(name, env, make=None):
        folder = tmp_path / name
        shutil.copytree(src / "transfer", folder / "transfer")
        if make:
            make(folder)
        return write_scene(folder, environment=env, settings={})

    nan = np.ones((16, 32, 3), np.float32)
    nan[3, 5, 1] = np.nan
    _scene_error(with_env("nan", {"map": "env.exr"}, lambda f: write_exr(f / "env.exr", nan)), "non-finite")
    _scene_error(with_env("shape", {"map": "env.exr"},
                          lambda f: write_exr(f / "env.exr", np.ones((16, 16, 3), np.float32))), "twice as wide")
    _scene_error(with_env("nofile", {"map": "missing.exr"}), "environment.map: .*no such file")
    _scene_error(with_env("sky", {"sky": "mars"}), "environment.sky: unknown sky 'mars'")
    _scene_error(with_env("degree", {"sky": "noon", "degree": 3}), "environment.degree")


def test_environment_map_lights_the_scene(gl, program_cache, tmp_path, prt_scene):
    """An equirectangular map (here the sunset preset written to EXR) lights the scene as the
    preset's own SH does, and rotates with the environment setting."""
    from inshade.sh import procedural_sky
    from inshade.scene.image_io import write_exr
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    src, _, _ = prt_scene
    folder = tmp_path / "map"
    shutil.copytree(src / "transfer", folder / "transfer")
    write_exr(folder / "env.exr", procedural_sky("sunset", 256))
    settings = {"env_rotation": dict(PRT_SETTINGS["env_rotation"], default=30.0)}
    write_scene(folder, environment={"map": "env.exr", "rotation": 30.0}, settings=settings)
    r = SceneRenderer(load_scene(folder), gl, cache=program_cache)
    try:
        np.testing.assert_allclose(r.environment_sh(), environment_sh("sunset", 30.0), rtol=1e-5, atol=1e-5)
        r.set_setting("env_rotation", -60.0)
        np.testing.assert_allclose(r.environment_sh(), environment_sh("sunset", -60.0), rtol=1e-5, atol=1e-5)
    finally:
        r.release()


# headless + quality ---------------------------------------------------------------------------------
def test_headless_render_and_sidecar(gl, program_cache, prt_scene, tmp_path):
    from inshade.runtime.headless import render_scene, save_render

    folder, _, _ = prt_scene
    image, info = render_scene(folder, width=24, height=24, settings={"shading": "glossy", "sky": "sunset"}, ctx=gl,
                               cache=program_cache)
    assert image.shape == (24, 24, 4) and np.isfinite(image).all()
    assert info["bundles"][0]["prefix"] == "transfer" and info["sdf"]["name"] == "prt_test"
    assert info["environment"]["sky"] == "sunset" and info["view"]["settings"]["shading"] == "glossy"
    png, sidecar = save_render(image, info, tmp_path / "shot.png")
    assert png.is_file() and json.loads(sidecar.read_text())["gl"]["renderer"]


def test_transfer_bundle_alone_is_one_clear_error(prt_scene):
    from inshade.runtime.headless import RenderSpecError, render_bundle

    with pytest.raises(RenderSpecError, match="a (prt|transfer) bundle is drawn by a scene, not on its own.*passes/sdf_prt.frag"):
        render_bundle(prt_scene[0] / "transfer")


def test_quality_orbit_smoke(gl, program_cache, prt_scene):
    """quality_orbit runs GL vs the ray-cast ground truth (tiny: 2 views, 16x16, 16 rays) and
    reports finite, per-view PSNR/SSIM/MAE for both materials. The values are meaningless for an
    untrained network; benchmarks report the real ones."""
    folder, _, _ = prt_scene
    out = quality_orbit(folder, n_views=2, size=16, n_dirs=16, ctx=gl, cache=program_cache, progress=False)
    assert out["gl_renderer"] and out["n_views"] == 2
    for mode in SHADING_MODES:
        assert len(out[mode]["views"]) == 2
        assert all(math.isfinite(out[mode][k]) for k in ("psnr", "ssim", "mae"))
    assert image_metrics(np.ones((8, 8, 3)), np.ones((8, 8, 3)))["psnr"] == math.inf


def test_ground_truth_matches_reference_when_transfer_is_exact(prt_scene):
    """compose() is shared: a reference render whose transfer is replaced by the view's own
    ground truth is the ground-truth render (same pixels), so quality differences are the
    network's alone."""
    from inshade.techniques.prt.twin import ground_truth_transfer, render_ground_truth
    from inshade.scene.camera import camera_from_dict
    from inshade.scene.description import load_scene

    folder, _, _ = prt_scene
    scene = load_scene(folder)
    u = camera_from_dict(CAMERA).uniforms(12, 12)
    sh = environment_sh("noon")
    view = trace_view(scene.sdf, u, 12, 12)
    gt = ground_truth_transfer(scene.sdf, view, n_dirs=16, seed=4)
    a = compose(view, gt, sh, PrtShading(mode="glossy"))
    b = render_ground_truth(scene.sdf, u, 12, 12, sh, PrtShading(mode="glossy"), n_dirs=16, seed=4)
    np.testing.assert_array_equal(a["rgba"], b["rgba"])


# triangle meshes (deferred: G-buffer pass + mesh_prt) ------------------------------------------------
@pytest.fixture(scope="module")
def mesh_scene(tmp_path_factory):
    import trimesh
    import trimesh.creation

    from inshade.geometry.mesh import bounding_sphere

    folder = tmp_path_factory.mktemp("mesh_scene")
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    slab = trimesh.creation.box(extents=[1.8, 0.2, 1.4])
    slab.apply_translation([0.0, -0.6, 0.0])
    mesh = trimesh.util.concatenate([ball, slab])
    mesh.export(folder / "mesh.ply")
    center, radius = bounding_sphere(mesh)
    graph, frame, bundle = transfer_bundle(center, radius, seed=5)
    bundle.save(folder / "transfer")
    data = json.loads((write_scene(folder, program="passes/mesh_prt.frag") / "scene.json").read_text())
    del data["sdf"]
    data["mesh"] = "mesh.ply"
    (folder / "scene.json").write_text(json.dumps(data))
    return folder, graph, frame


def _gl_mesh(gl, program_cache, folder, settings_seq, size=SIZE):
    return render_with_gbuffer(gl, program_cache, folder, settings_seq, size, targets=2)


def test_mesh_transfer_at_gbuffer_points_glsl_vs_torch(gl, program_cache, mesh_scene):
    from inshade.techniques.prt.transfer_model import evaluate_transfer

    folder, graph, frame = mesh_scene
    out, _, _ = _gl_mesh(gl, program_cache, folder, [{"debug": d} for d in (1, 2, 3, 4)])
    _, pos, nrm = out[0]
    covered = pos[..., 3] > 0
    assert covered.mean() > 0.2
    transfer_gl = np.concatenate([img[::-1][covered] for img, _, _ in out], -1)    # image -> data rows
    with torch.no_grad():
        ref = evaluate_transfer(graph, frame, torch.from_numpy(pos[covered][:, :3]),
                                torch.from_numpy(nrm[covered][:, :3])).numpy()
    err = np.abs(transfer_gl - ref).max()
    assert err <= 1e-4, f"mesh: max |glsl - torch| transfer {err:.3g}"


@pytest.mark.parametrize("mode", SHADING_MODES)
def test_mesh_image_glsl_vs_torch_reference(gl, program_cache, mesh_scene, mode):
    from inshade.techniques.prt.twin import render_gbuffer

    folder, graph, frame = mesh_scene
    out, sh, scene = _gl_mesh(gl, program_cache, folder, [{"shading": mode, "sky": "sunset", "env_rotation": 45.0}])
    image, pos, nrm = out[0]
    ref = render_gbuffer(pos, nrm, graph, frame, scene.make_camera().uniforms(SIZE, SIZE), SIZE, SIZE, sh,
                         PrtShading(mode=mode, exponent=8.0, ks=0.5))
    psnr = _psnr(image, ref["rgba"])
    assert psnr >= 50.0, f"mesh {mode}: PSNR {psnr:.1f} dB"


def test_mesh_scene_errors_and_quality_smoke(gl, program_cache, mesh_scene, tmp_path):
    folder, _, _ = mesh_scene
    bad = tmp_path / "bad"
    shutil.copytree(folder, bad)
    (bad / "mesh.ply").write_text("not a mesh")
    _scene_error(bad, "mesh: .*mesh.ply")
    (bad / "mesh.ply").unlink()
    _scene_error(bad, "mesh: .*no such file")
    out = quality_orbit(folder, n_views=2, size=16, n_dirs=8, ctx=gl, cache=program_cache, progress=False)
    assert all(math.isfinite(out[m]["mae"]) for m in SHADING_MODES)


# the window app (inshade view) -----------------------------------------------------------------------
from test_viewer import xvfb  # noqa: E402,F401  (the Xvfb display fixture)


_VIEWER_SCRIPT = """
import sys
import numpy as np
from inshade.viewer.app import ViewerApp

app = ViewerApp(sys.argv[1], size=(160, 120), vsync=False, screenshot_dir=sys.argv[3])
try:
    for folder in sys.argv[1:3]:
        assert app.open(folder), app.messages[-1:]
        app.step(3)
        assert app.renderer.error is None, app.renderer.error
        before = app.read_window().astype(np.int16)
        assert app.set_setting("shading", "glossy") == "uniform"
        assert app.set_setting("sky", "sunset") == "uniform"
        app.step(2)
        after = app.read_window().astype(np.int16)
        assert after.std() > 5 and np.abs(after - before).max() > 10, folder + ": no visible change"
        print("ok", folder)
finally:
    app.close()
"""


def test_viewer_opens_prt_scenes_and_switches_material(xvfb, prt_scene, mesh_scene, tmp_path):
    """inshade view on an SDF and a mesh PRT scene: draws, and the material/sky settings change the
    picture without a rebuild. In a subprocess: GLFW keeps process-wide X state, which must not
    outlive another test module's Xvfb."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, DISPLAY=xvfb)
    proc = subprocess.run([sys.executable, "-c", _VIEWER_SCRIPT, str(prt_scene[0]), str(mesh_scene[0]), str(tmp_path)],
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0 and proc.stdout.count("ok ") == 2, proc.stdout + proc.stderr


def test_bench_prt_quick_writes_reports(tmp_path):
    """`inshade bench prt --quick` on the shipped mesh asset: JSON + markdown + plot, renderer named."""
    import json

    from inshade.techniques.prt import bench as bench_prt

    root = Path(__file__).resolve().parents[3]
    assert bench_prt.main(["--quick", "--assets", str(root / "trained" / "prt_mesh"), "--out", str(tmp_path),
                           "--mesh", str(root / "trained" / "prt_mesh" / "mesh.ply")]) == 0
    result = json.loads((tmp_path / "prt.json").read_text())
    assert {r["k"] for r in result["frames"]} == {16, 64}
    assert all(r["seconds"] > 0 and r["storage"] for r in result["frames"])
    assert result["rays"] and result["rays"][0]["rays_per_second"] > 0
    assert result["machine"]["gl_renderer"] in (tmp_path / "prt.md").read_text()
    assert (tmp_path / "prt.png").stat().st_size > 0


# The quality targets for k=64 (diffuse >= 45 dB, glossy >= 38 dB against the per-pixel
# ground-truth transfer render, surface pixels), re-measured on the shipped assets with a small
# orbit (3 views, 48², 256 ground-truth rays: estimator noise ~51 dB diffuse) to keep CI fast; the
# 30-view numbers are in each asset's metrics.json. The neural-SDF asset (its transfer network
# evaluated per ground-truth sample) takes ~35 s: under INSHADE_SLOW.
@pytest.mark.parametrize("asset", ["prt_creature", pytest.param("prt_neural_bunny", marks=pytest.mark.skipif(
    not os.environ.get("INSHADE_SLOW"), reason="~35 s; set INSHADE_SLOW=1")), "prt_mesh"])
def test_shipped_prt_asset_meets_quality_targets(asset, program_cache):
    from inshade.techniques.prt.twin import quality_orbit

    root = Path(__file__).resolve().parents[3] / "trained" / asset
    q = quality_orbit(root, n_views=3, size=48, n_dirs=256, cache=program_cache, progress=False)
    assert q["diffuse"]["psnr"] >= 45.0, q["diffuse"]
    assert q["glossy"]["psnr"] >= 38.0, q["glossy"]
