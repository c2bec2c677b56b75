"""appearance_prefilter's march: the GLSL pass (passes/appearance_prefilter.frag, lib/dap_march,
lib/dap_frame) drawn through the real renderer against its torch twin (march.py
render_prefiltered) on tiny random voxel grids with randomly initialised decoders.

- the view frame and the phase-bin centres: GLSL vs torch vs numpy (frame.py), poles included;
- the image: >= 50 dB PSNR (peak = the reference's largest value) at forced scales and at the
  footprint-chosen blend of two scales, for random cameras, dolly distances and suns;
- the `scale` view shows the torch footprint scale L per pixel (1e-4);
- a bundle whose render metadata lacks the mask or the bins, and a scene whose network has another
  prefix, are one error each.
"""
from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import example, given
from hypothesis import strategies as st

from inshade.scene.camera import OrbitCamera
from inshade.scene.description import DirectionalLight, SceneError, load_scene

from parity import parity_settings, run_sample_pass

import inshade.techniques.appearance_prefilter as record
from inshade.techniques.appearance_prefilter import frame as np_frame
from inshade.techniques.appearance_prefilter import march

W = H = 32
MASK, BT, BP = 4, 2, 4
BINS = BT * BP
PSNR_MIN = 50.0   # the march against its torch reference



# --- the view frame ---------------------------------------------------------------------------

FRAME_PASS = """
#include <lib/dap_frame>
#include <lib/test_pass>
uniform int u_bt;
uniform int u_bp;
layout(location = 0) out vec4 out_t;
layout(location = 1) out vec4 out_b;
layout(location = 2) out vec4 out_c;
void main() {
    vec4 x = test_input(0);
    vec3 t, b;
    dap_view_frame(x.xyz, t, b);
    int i = int(x.w);
    out_t = vec4(t, 0.0);
    out_b = vec4(b, 0.0);
    out_c = vec4(dap_bin_centre(i / u_bp, i - (i / u_bp) * u_bp, u_bt, u_bp), 0.0);
}
"""


def _directions(seed: int, n: int) -> np.ndarray:
    """Unit directions: random ones, ones near the poles (|y| > 0.999, both signs) and just outside
    (0.99 < |y| < 0.9989), never within 1e-4 of the switch (float32 vs float64 would disagree)."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    k = n // 4
    for rows, lo, hi in ((slice(0, k), 0.9992, 1.0), (slice(k, 2 * k), 0.99, 0.9989)):
        y = rng.uniform(lo, hi, k) * rng.choice([-1.0, 1.0], k)
        phi = rng.uniform(0, 2 * math.pi, k)
        s = np.sqrt(1 - y * y)
        v[rows] = np.c_[s * np.cos(phi), y, s * np.sin(phi)]
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return v.astype(np.float32)


@parity_settings(4)
@given(seed=st.integers(0, 2**31 - 1), layout=st.sampled_from([(2, 4), (4, 8), (3, 5), (1, 1)]))
def test_view_frame_and_bin_centres_match_torch_and_numpy(gl, seed, layout):
    bt, bp = layout
    w = _directions(seed, 256)
    bins = np.arange(256) % (bt * bp)
    t, b, c = run_sample_pass(gl, "passes/dap_frame_test.frag", np.c_[w, bins].astype(np.float32),
                              attachments=3, uniforms={"u_bt": bt, "u_bp": bp},
                              chunks={"passes/dap_frame_test.frag": FRAME_PASS})
    tt, bb = march.view_frame(torch.from_numpy(w))
    nt, nb, _ = np_frame.view_frame(w.astype(np.float64))
    for glsl, ref, what in ((t[:, :3], tt.numpy(), "t (torch)"), (b[:, :3], bb.numpy(), "b (torch)"),
                            (t[:, :3], nt, "t (numpy)"), (b[:, :3], nb, "b (numpy)")):
        np.testing.assert_allclose(glsl, ref, rtol=0, atol=1e-6, err_msg=what)
    # a right-handed orthonormal frame (t, b, w) with t horizontal away from the poles
    np.testing.assert_allclose(np.cross(nt, nb), w, atol=1e-6)
    far = np.abs(w[:, 1]) < 0.999
    assert np.abs(nt[far, 1]).max() < 1e-7
    centres = march.bin_centres(bt, bp).numpy()[bins]
    np.testing.assert_allclose(c[:, :3], centres, rtol=0, atol=1e-6, err_msg="bin centres (torch)")
    np.testing.assert_allclose(c[:, :3], np_frame.bin_centres(bt, bp)[bins], rtol=0, atol=1e-6,
                               err_msg="bin centres (numpy)")


# --- tiny scenes --------------------------------------------------------------------------------

def _voxels(seed: int, scales: tuple[int, int]):
    """Random occupied cells, each finer cell inside an occupied coarser one (the hierarchy a
    voxelised scene gives), with random bounding spheres inside their cells."""
    rng = np.random.default_rng(seed)
    smin, smax = scales
    cells, parents = [], None
    for s in range(smin, smax + 1):
        n = 1 << s
        k, j, i = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij"))
        ok = rng.random(k.size) < (0.45 if s == smin else 0.6)
        if parents is not None:
            ok &= parents[k >> 1, j >> 1, i >> 1]
        cells += [(s, a, b, c) for a, b, c in zip(i[ok], j[ok], k[ok])]
        parents = ok.reshape(n, n, n)
    cells = np.array(cells, np.uint32)   # already sorted by (scale, k, j, i)
    size = 1.0 / (1 << cells[:, 0].astype(np.int64))
    centre = (cells[:, 1:4] + rng.uniform(0.25, 0.75, (len(cells), 3))) * size[:, None]
    radius = size * rng.uniform(0.3, 0.9, len(cells))
    return cells, np.c_[centre, radius].astype(np.float32)


def _bundle(seed: int, scales: tuple[int, int]):
    """A random-init decoder bundle over random voxels (raw lanes random too, so voxels differ)."""
    from inshade.techniques.appearance_prefilter.model import KIND, build_decoders

    cells, spheres = _voxels(seed, scales)
    raw = np.random.default_rng(seed + 1).uniform(0.0, 1.0, (len(cells), 4)).astype(np.float32)
    graph = build_decoders(raw, cells, spheres, latent=4, raw=4, width=8, blocks=1, mask=MASK, bins=BINS,
                           view_freqs=2, light_freqs=2, scale_min=scales[0], scale_max=scales[1], seed=seed)
    render = {"mask": MASK, "bins": BINS, "bins_theta": BT, "bins_phi": BP}
    return graph, graph.export(KIND, "dap_test", render=render), cells, spheres


def _settings() -> dict:
    return {name: dict(value, default=False) if name == "shadows" else value
            for name, value in record.SETTINGS.items()}


def _write_scene(folder: Path, bundle, *, prefix: str = "dap", sky: str = "overcast") -> Path:
    bundle.save(folder / "dap")
    scene = {"format": "inshade.scene", "version": 1, "name": "dap_test", "program": record.PROGRAM,
             "size": [W, H], "networks": [{"bundle": "dap", "prefix": prefix}],
             "camera": {"type": "orbit", "target": [0.5, 0.5, 0.5], "distance": 2.0},
             "lights": [{"type": "directional", "direction": [0.3, 0.8, 0.5], "intensity": 2.0}],
             "environment": {"sky": sky, "degree": 3}, "settings": _settings()}
    (folder / "scene.json").write_text(json.dumps(scene))
    return folder


class _Drawn:
    """One scene's renderer, kept for a module (compiling dominates on llvmpipe)."""

    def __init__(self, seed: int, scales: tuple[int, int]):
        from inshade.codegen.sdf import environment_sh
        from inshade.runtime.renderer import SceneRenderer

        _, bundle, cells, spheres = _bundle(seed, scales)
        self.args = march.bundle_args(bundle)   # the reference is what the bundle says
        self.graph, self.cells, self.spheres = self.args["decoder"], self.args["cells"], self.args["spheres"]
        assert np.array_equal(self.cells, cells) and np.array_equal(self.spheres, spheres)
        a = self.args
        assert (a["mask"], a["bins"], a["scale_min"], a["scale_max"]) == (MASK, BINS, *scales)
        self._tmp = tempfile.TemporaryDirectory()
        self.renderer = SceneRenderer(load_scene(_write_scene(Path(self._tmp.name), bundle)))
        self.sh = environment_sh("overcast", 0.0, 3)

    def draw(self, camera, sun, *, distance=1.0, force_scale=-1, view="prefiltered", shadows=False):
        """(GLSL image, torch image, torch alternatives [6, H, W, 4]), in image orientation. With
        shadows the torch side reads the renderer's shadow map through the numpy twin of
        shadow_visibility.

        Alternatives: the march is discontinuous where a ray passes a cell edge (which cell comes
        next) or a mask texel boundary (NEAREST), and GLSL and torch compute the eye and the rays
        to a few ulp (FMA contraction, matrix order), so a pixel that close to a discontinuity may
        land on either side. The alternatives are torch renders with the eye moved by ~16 ulp
        along each axis, both ways (see _check): the cell edges and the mask texels' boundaries are
        axis-aligned planes, so an axis is what carries a ray across one (two random directions
        missed a pixel whose ray grazed one)."""
        from inshade.runtime.shadow import shadow_visibility_np

        r = self.renderer
        r.scene.lights = [DirectionalLight(tuple(float(v) for v in sun), 2.0)]
        for name, value in (("distance", float(distance)), ("force_scale", force_scale), ("view", view),
                            ("shadows", shadows)):
            r.set_setting(name, value)
        r.render_network(camera, W, H)
        glsl = r.read("network")
        visibility = None
        if shadows:
            depth, matrices = r.shadow_maps.read(), r.shadow_maps.matrices
            assert depth.shape == (1, record.SHADOW_SIZE, record.SHADOW_SIZE)
            visibility = lambda p: shadow_visibility_np(depth, matrices, p.numpy(), 0, march.SHADOW_BIAS)  # noqa: E731
        def twin(uniforms):
            return march.render_prefiltered(**self.args, camera=uniforms, width=W, height=H, distance=distance,
                                            sun_dir=sun, sun_radiance=2.0, sh=self.sh, force_scale=force_scale,
                                            view=view, shadows=visibility)

        uniforms = camera.uniforms(W, H)
        ref = twin(uniforms)
        eye = np.asarray(uniforms["u_eye"], np.float64)
        ro = 0.5 + (eye - 0.5) * distance
        nudge = 16 * 2.0 ** -23 * np.abs(ro).max() / distance   # ~16 ulp of the dollied eye
        alternatives = [twin(dict(uniforms, u_eye=tuple(eye + sign * nudge * v / np.linalg.norm(v))))
                        for v in np.eye(3) for sign in (1.0, -1.0)]
        return glsl, ref, np.stack(alternatives)

    def release(self):
        self.renderer.release()
        self._tmp.cleanup()


@pytest.fixture(scope="module")
def coarse():
    """Scales 2..3: at the default distance every pixel asks for the finest scale (clamped)."""
    d = _Drawn(5, (2, 3))
    yield d
    d.release()


@pytest.fixture(scope="module")
def blended():
    """Scales 2..5: the footprint picks fractional scales over most of the object at these sizes."""
    d = _Drawn(11, (2, 5))
    yield d
    d.release()


def psnr(img: np.ndarray, ref: np.ndarray) -> float:
    """PSNR over all four channels, peak = the reference's largest value."""
    mse = float(np.mean((img.astype(np.float64) - ref) ** 2))
    peak = float(np.abs(ref).max())
    return math.inf if mse == 0.0 else 10.0 * math.log10(peak * peak / mse)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64)
    return (v / np.linalg.norm(v)).astype(np.float32)


cameras = st.builds(lambda yaw, pitch, dist: OrbitCamera(target=(0.5, 0.5, 0.5), distance=dist, yaw=yaw, pitch=pitch),
                    st.floats(0.0, 360.0), st.floats(-80.0, 80.0), st.floats(1.3, 2.5))
suns = st.builds(_unit, st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1))


def _check(glsl, ref, alternatives, what: str, min_coverage: float):
    """>= PSNR_MIN against torch, where a pixel that matches an alternative (draw) better than the
    reference by > 1e-3 is compared with that alternative: at most 2% of the pixels may need one."""
    assert np.isfinite(glsl).all(), f"{what}: non-finite GLSL pixels"
    assert ref[..., 3].mean() > min_coverage, f"{what}: the voxels barely show ({ref[..., 3].mean():.3g})"
    err = np.abs(glsl - ref).max(-1)
    alt_err = np.abs(glsl[None] - alternatives).max(-1)
    use = (alt_err.min(0) < err - 1e-3)
    best = np.where(use[..., None], alternatives[alt_err.argmin(0), np.arange(H)[:, None], np.arange(W)], ref)
    assert use.mean() <= 0.02, f"{what}: {use.sum()} pixels match only a nudged eye's torch render"
    p = psnr(glsl, best)
    assert p >= PSNR_MIN, (f"{what}: PSNR {p:.1f} dB < {PSNR_MIN} (max abs error {np.abs(glsl - best).max():.3g}; "
                           f"{use.sum()} pixels compared with a nudged eye's render; "
                           f"without them {psnr(glsl, ref):.1f} dB)")


@parity_settings(8)
@given(camera=cameras, sun=suns, force=st.sampled_from([2, 3]),
       view=st.sampled_from(["prefiltered", "coverage", "albedo"]))
def test_march_at_a_forced_scale_matches_torch(coarse, camera, sun, force, view):
    _check(*coarse.draw(camera, sun, force_scale=force, view=view), f"scale {force}, {view}", 0.02)


@parity_settings(8)
@given(camera=cameras, sun=suns, eye=st.floats(3.3, 7.0), force=st.sampled_from([-1, -1, 2, 5]))
def test_march_at_the_footprint_blend_matches_torch(blended, camera, sun, eye, force):
    """The dolly puts the eye `eye` from the box centre: L between 3.5 and 5 at 32 x 32, 45 degrees."""
    distance = eye / camera.distance
    L, hit = march.scale_map(camera, W, H, distance=distance, scale_min=2, scale_max=5, force_scale=force)
    if force < 0:   # the case under test: two marches mixed by fract(L) over most of the object
        assert hit.any() and ((L % 1.0) > 0.0)[hit].mean() > 0.5
    _check(*blended.draw(camera, sun, distance=distance, force_scale=force), f"distance {distance:.3g}, scale {force}",
           0.002)


@parity_settings(4)
@given(camera=cameras, sun=suns, force=st.sampled_from([-1, 2, 3]))
# a ray grazing a cell edge, which only a nudge along an axis carries across
@example(camera=OrbitCamera(target=(0.5, 0.5, 0.5), distance=1.5690519941837784, yaw=356.3511913297218,
                            pitch=60.250428917802594), sun=_unit((0.0, 0.0, 1.0)), force=2)
def test_march_with_the_sun_shadow_map_matches_torch(coarse, camera, sun, force):
    """Shadows on: the GLSL march reads the shadow map of the finest cells' cubes; torch reads the
    same map through runtime/shadow.py's numpy twin; the shadows change the picture (the cells occlude
    each other; a random decoder's phase has either sign, so "darker" is not a property here)."""
    _, lit_ref, _ = coarse.draw(camera, sun, force_scale=force)
    glsl, ref, alternatives = coarse.draw(camera, sun, force_scale=force, shadows=True)
    _check(glsl, ref, alternatives, f"shadows, scale {force}", 0.02)
    assert (np.abs(ref - lit_ref) > 1e-3).any(), "shadows change nothing"


@parity_settings(2)   # each example is a full march (the view colours what the pixel covers)
@given(camera=cameras, eye=st.floats(1.5, 12.0), force=st.sampled_from([-1, -1, 3]))
def test_scale_view_shows_the_footprint_scale(blended, camera, eye, force):
    """The scale each pixel marched at, as a ramp on what it covers (red / coverage = (L - S_MIN) /
    (S_MAX - S_MIN)), over black; nothing outside the box."""
    distance = max(1.0, eye / camera.distance)
    glsl, ref, alternatives = blended.draw(camera, _unit([0, 1, 0]), distance=distance, force_scale=force, view="scale")
    _check(glsl, ref, alternatives, f"scale view, scale {force}", 0.002)
    L, hit = march.scale_map(camera, W, H, distance=distance, scale_min=2, scale_max=5, force_scale=force)
    assert (glsl[~hit] == 0.0).all()
    covered = hit & (glsl[..., 3] > 0.05)
    assert covered.any()
    shown = 2.0 + glsl[..., 0][covered] / glsl[..., 3][covered] * 3.0   # red = coverage x (L - S_MIN) / (S_MAX - S_MIN)
    np.testing.assert_allclose(shown, L[covered], rtol=0, atol=2e-3)


def test_coverage_saturates_behind_opaque_voxels(coarse):
    """Against the model, not only the twin: with every coverage output forced to 1 (a huge sigmoid
    bias), a ray through an occupied voxel whose sphere covers the whole beam is fully covered, and
    radiance then stops growing (the front voxel takes all the weight)."""
    cells, spheres = coarse.cells, coarse.spheres.copy()
    spheres[:, 3] = 1.0   # every mask spans the beam
    graph = coarse.graph
    with torch.no_grad():
        bias = graph.nodes["cov_head"].linear.bias
        old = bias.clone()
        bias.fill_(40.0)
    try:
        camera = OrbitCamera(target=(0.5, 0.5, 0.5), distance=2.0, yaw=20.0, pitch=10.0)
        img = march.render_prefiltered(graph, cells, spheres, camera, W, H, sun_dir=_unit([0, 1, 0]), sun_radiance=2.0,
                                       sh=coarse.sh, force_scale=3, mask=MASK, bins=BINS, view="coverage")
    finally:
        with torch.no_grad():
            bias.copy_(old)
    L, hit = march.scale_map(camera, W, H, distance=1.0, scale_min=2, scale_max=3, force_scale=3)
    cov = img[..., 3]
    assert set(np.unique(cov[~hit])) <= {0.0}
    assert ((cov == 1.0) | (cov == 0.0)).all() and (cov == 1.0).mean() > 0.1


# --- bad input --------------------------------------------------------------------------------------

@pytest.mark.parametrize("render, field", [({"bins": BINS}, "render.mask"), ({"mask": MASK}, "render.bins"),
                                           ({"mask": MASK, "bins": 7}, "render.bins"),
                                           ({"mask": 8, "bins": BINS}, "outputs: .*coverage\\[64\\]")])
def test_bundle_without_mask_or_bins_is_one_error(tmp_path, render, field):
    _, bundle, _, _ = _bundle(1, (2, 2))
    bundle.meta["render"] = render
    with pytest.raises(SceneError, match=field) as info:
        load_scene(_write_scene(tmp_path, bundle))
    assert "\n" not in str(info.value)


def test_network_with_another_prefix_is_one_error(tmp_path):
    _, bundle, _, _ = _bundle(1, (2, 2))
    with pytest.raises(SceneError, match=r'prefix "dap"') as info:
        load_scene(_write_scene(tmp_path, bundle, prefix="net"))
    assert "\n" not in str(info.value)


def test_scene_without_an_environment_is_one_error(tmp_path):
    _, bundle, _, _ = _bundle(1, (2, 2))
    folder = _write_scene(tmp_path, bundle)
    scene = json.loads((folder / "scene.json").read_text())
    scene["environment"] = None
    (folder / "scene.json").write_text(json.dumps(scene))
    with pytest.raises(SceneError, match=r"scene\.json: environment: .*SH environment") as info:
        load_scene(folder)
    assert "\n" not in str(info.value)
