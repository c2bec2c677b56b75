"""A DI-compressed PBR texture set on a lit mesh (techniques/di_pbr_set, models/pbr_lanes.py,
lib/pbr_set.glsl, passes/mesh_pbr_set.frag): the material, the shading parity, the whole pass
against its torch twin, the asset's scene and its errors.

Tolerances:
- lib/pbr_set.glsl vs torch at random inputs: the parity rule |glsl - torch| <= 1e-5 max(1, |torch|)
  (tests/parity.py), both float32 in the same operation order (the Disney lobes are tests/models/test_brdf.py's).
- The rendered pass, DI view (exact LUT path): the same rule per pixel. The network, the shading and
  the G-buffer fed to torch are the ones the pass used.
- The uncompressed view samples RGBA8 textures with the driver's bilinear filter, whose weights are
  8-bit fixed point on llvmpipe (and most GPUs): each lane may differ from float32 weights by up to
  2^-9 of a neighbouring texel difference, i.e. <= 2^-9 in [0, 1]. Through the normal map and the
  BRDF that gives |glsl - torch| <= 0.02 on radiance of ~1 here; asserted with the median <= 1e-3.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from inshade.codegen.sdf import environment_sh
from inshade.codegen.spherical_harmonics import sh_chunks
from inshade.models import pbr_lanes
from inshade.techniques.di_pbr_set import render, report
from inshade.techniques.di_pbr_set import train as P
from parity import TOL, parity_settings, run_sample_pass

SH_DEGREE = 3


def _glsl_shade(gl, a, b, p, ng, tangent, rd, sh, lights):
    rows = np.zeros((a.shape[0], 24), np.float32)
    rows[:, 0:4], rows[:, 4:8], rows[:, 8:11], rows[:, 12:15], rows[:, 16:20], rows[:, 20:23] = a, b, p, ng, tangent, rd
    return run_sample_pass(gl, "passes/pbr_set_eval_test.frag", rows, 6, chunks=sh_chunks(SH_DEGREE),
                           uniforms={"u_sh": np.asarray(sh, np.float32).tobytes(), "u_light_count": lights,
                                     "u_lights": np.asarray(render.LIGHTS, np.float32).tobytes(),
                                     "u_scene_light_count": len(render.LIGHTS)})[0][:, :3]


def _unit(x):
    return x / torch.linalg.norm(x, dim=-1, keepdim=True)


def _random_surface(seed: int, n: int):
    gen = torch.Generator().manual_seed(seed)
    lanes = torch.rand(n, 8, generator=gen)
    lanes[:, 5] = lanes[:, 5] * 0.5 + 0.5        # tangent-space normals point out of the surface
    lanes[:, 6] = lanes[:, 6] * 0.9 + 0.1        # roughness >= 0.1: D within float32's comfort (test_brdf)
    ng = _unit(torch.randn(n, 3, generator=gen))
    p = ng * 1.2 + torch.randn(n, 3, generator=gen) * 0.1
    tangent = torch.cat([torch.randn(n, 3, generator=gen),
                         torch.where(torch.rand(n, 1, generator=gen) < 0.5, -1.0, 1.0)], -1)
    eye = torch.tensor([0.5, 1.0, 4.0])
    rd = _unit(p - eye)
    keep = (rd * ng).sum(-1) < -0.05            # seen from the front, as a rasterised visible surface
    return lanes[keep], p[keep], ng[keep], tangent[keep], rd[keep]


@parity_settings(max_examples=3)
@given(seed=st.integers(0, 2 ** 31 - 1), lights=st.integers(0, len(render.LIGHTS)),
       sky=st.sampled_from(["studio", "noon", "sunset"]))
def test_pbr_set_shading_parity(gl, seed, lights, sky):
    lanes, p, ng, tangent, rd = _random_surface(seed, 512)
    sh = environment_sh(sky, 0.0, SH_DEGREE)
    out = _glsl_shade(gl, lanes[:, :4].numpy(), lanes[:, 4:].numpy(), p.numpy(), ng.numpy(), tangent.numpy(),
                      rd.numpy(), sh, lights)
    with torch.no_grad():
        ref = render.shade(pbr_lanes.unpack(lanes[:, :4], lanes[:, 4:]), p, ng, tangent, rd, torch.from_numpy(sh),
                           lights).numpy()
    assert np.isfinite(out).all() and ref.max() > 0.05
    err = np.abs(out - ref) / np.maximum(1.0, np.abs(ref))
    assert err.max() <= TOL, f"max scaled error {err.max():.3g} at {np.unravel_index(err.argmax(), err.shape)}"


def test_unpack_decodes_lanes():
    a = torch.tensor([[0.0, 0.5, 1.0, 0.5], [0.2, 0.2, 0.2, 0.5]])
    b = torch.tensor([[0.5, 1.0, 0.3, 0.7], [0.5, 0.5, 1.5, -0.2]])   # 2nd: zero-length normal, out-of-range lanes
    s = pbr_lanes.unpack(a, b)
    assert torch.allclose(s["normal_ts"], torch.tensor([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]))
    assert torch.allclose(s["albedo"][0], torch.tensor([0.0, 0.21404114, 1.0]), atol=1e-6)
    assert s["roughness"].tolist() == pytest.approx([0.3, 1.0]) and s["ao"].tolist() == pytest.approx([0.7, 0.0])


def test_bricks_material_tiles_and_is_8bit():
    s = pbr_lanes.bricks(64)
    assert s.shape == (64, 64, 8) and s.dtype == np.float32
    assert np.array_equal(np.round(s * 255) / 255, s), "lanes must be 8-bit values"
    n = s[..., 3:6] * 2 - 1
    assert np.abs(np.linalg.norm(n, axis=-1) - 1).max() < 0.02 and (n[..., 2] > 0).all()
    # periodic: the wrap-around neighbour differs from a texel no more than interior neighbours do
    wrap_u = np.abs(s[:, 0] - s[:, -1]).mean()
    inner_u = np.abs(s[:, 1:] - s[:, :-1]).mean()
    wrap_v = np.abs(s[0] - s[-1]).mean()
    inner_v = np.abs(s[1:] - s[:-1]).mean()
    assert wrap_u < 2 * inner_u and wrap_v < 2 * inner_v
    assert np.array_equal(pbr_lanes.bricks(64), s), "not deterministic"
    with pytest.raises(pbr_lanes.PbrSetError, match="multiple"):
        pbr_lanes.bricks(60)


@pytest.fixture(scope="module")
def asset(tmp_path_factory):
    out = tmp_path_factory.mktemp("pbr") / "di_pbr_test"
    m = P.build(out, size=64, steps=40, batch=2048, render=48, gl_metrics=False, progress=False)
    return out, m


def test_asset_files_and_lane_metrics(asset):
    out, m = asset
    for f in ("bundle.json", "weights.safetensors", "set0.png", "set1.png", "mesh.obj", "scene.json", "metrics.json",
              "report.md"):
        assert (out / f).is_file(), f
    assert "| DI (torch) |" in (out / "report.md").read_text()
    assert json.loads((out / "metrics.json").read_text())["texture"]["channels"] == 8
    t = m["texture"]
    # the budget is met (sizing rounds the primary down to a multiple of 8: 7.5x at this tiny size)
    assert t["ratio"] >= 6.0 and t["bytes"] * t["ratio"] == pytest.approx(64 * 64 * 8, rel=1e-3)
    for k in ("psnr_albedo", "psnr_normal", "psnr_roughness", "psnr_ao", "normal_mean_deg"):
        assert np.isfinite(m["di_torch"][k])


def test_pass_matches_torch_twin(gl, asset):
    from inshade.bundle import load
    from inshade.models.graph import GraphModule
    from PIL import Image

    out, _ = asset
    views = render.render_views(out, size=48, ctx=gl)
    graph = GraphModule.from_bundle(load(out))
    set8 = tuple(np.asarray(Image.open(out / f"set{i}.png")) for i in range(2))
    covered = views["_gbuffer"][0][::-1, :, 3] != 0
    assert 0.15 < covered.mean() < 0.9
    refs = {}
    for view in render.VIEWS:
        refs[view] = render.render_gbuffer(views["_gbuffer"], views["_uniforms"], 48, 48, views["_sh"], graph=graph,
                                           set8=set8, view=view, light_count=render.DEFAULT_LIGHTS)
    err = np.abs(views["di"] - refs["di"]) / np.maximum(1.0, np.abs(refs["di"]))
    assert err.max() <= TOL, f"DI view: max scaled error {err.max():.3g}"
    diff = np.abs(views["uncompressed"] - refs["uncompressed"])[covered]
    assert diff.max() <= 0.02 and np.median(diff) <= 1e-3, (diff.max(), np.median(diff))
    # split: left half is the uncompressed view, right half the DI view, pixel for pixel
    half = 24
    assert np.array_equal(views["split"][:, :half], views["uncompressed"][:, :half])
    assert np.array_equal(views["split"][:, half:], views["di"][:, half:])
    # the two sets differ (the compression is visible to the test), the background does not
    assert np.abs(views["di"] - views["uncompressed"])[covered].max() > 1e-3
    assert np.array_equal(views["di"][~covered], views["uncompressed"][~covered])


def test_scene_errors(asset, tmp_path):
    from inshade.geometry.mesh import obj_text, torus
    from inshade.scene.description import SceneError, load_scene

    out, _ = asset
    bad = tmp_path / "bad"
    shutil.copytree(out, bad)
    import trimesh

    plain = torus(segments=(8, 4))
    (bad / "mesh.obj").write_text(obj_text(trimesh.Trimesh(plain.vertices, plain.faces, process=False)))
    with pytest.raises(SceneError, match="no texture coordinates"):
        load_scene(bad)
    scene = json.loads((out / "scene.json").read_text())
    del scene["mesh"]
    (bad / "scene.json").write_text(json.dumps(scene))
    with pytest.raises(SceneError, match="needs \"mesh\""):
        load_scene(bad)


def test_network_with_wrong_outputs_is_one_compile_error(gl, asset, tmp_path):
    from inshade.shaders import ShaderCompileError
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene
    from inshade.models.texture_cascade import compress

    out, _ = asset
    bad = tmp_path / "rgb"
    shutil.copytree(out, bad)
    rgb = compress(np.random.default_rng(0).random((48, 48, 3)), 2, steps=1, decode=False)
    rgb.bundle.save(bad)
    with pytest.raises(ShaderCompileError, match="8-lane"):
        SceneRenderer(load_scene(bad), gl).release()


def test_cli_help_and_bad_steps(capsys):
    from inshade import cli

    with pytest.raises(SystemExit) as e:
        cli.main(["train", "di_pbr_set", "--help"])
    assert e.value.code == 0 and "--ratio" in capsys.readouterr().out
    assert cli.main(["train", "di_pbr_set", "-o", "/tmp/never_written_pbr", "--steps", "-1"]) == 2
    assert "--steps" in capsys.readouterr().err


def test_shipped_asset_renders_and_matches_torch(gl):
    """trained/di_pbr_set_bricks from a clean clone: loads, renders (DI view, 40^2) like its torch twin,
    and its recorded GLSL decode quality is what the bundle decodes to now."""
    from inshade.bundle import load
    from inshade.models.graph import GraphModule
    from inshade.runtime.network import evaluate_on_pixels

    folder = Path(__file__).resolve().parents[3] / "trained" / "di_pbr_set_bricks"
    m = json.loads((folder / "metrics.json").read_text())
    bundle = load(folder)
    views = render.render_views(folder, views=("di",), size=40, ctx=gl)
    ref = render.render_gbuffer(views["_gbuffer"], views["_uniforms"], 40, 40, views["_sh"],
                                graph=GraphModule.from_bundle(bundle), view="di", light_count=render.DEFAULT_LIGHTS)
    err = np.abs(views["di"] - ref) / np.maximum(1.0, np.abs(ref))
    assert err.max() <= TOL
    size = m["texture"]["width"]
    q = report.lane_metrics(evaluate_on_pixels(bundle, size, "exact"), pbr_lanes.bricks(size))
    assert q == pytest.approx(m["di_glsl_exact"], abs=1e-3)
