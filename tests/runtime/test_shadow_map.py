"""Shadow maps of directional lights (runtime/shadow.py, shaders/lib/shadow_map.glsl,
ProgramSpec.shadows in runtime/renderer.py) through the real driver, on a ground quad, a floating
box and a thin two-sided card lit from two directions:

- GLSL ``shadow_visibility`` at random points equals the numpy twin on the read-back maps;
- away from shadow edges both equal exact ray casting (trimesh) against the caster;
- the fitted light matrices put every caster vertex inside the clip cube;
- a ProgramSpec with ``shadows`` drawn by SceneRenderer binds the maps, redraws them only when the
  request changes and keeps the GL object count flat."""
from __future__ import annotations

import ctypes
import json

import numpy as np
import pytest
import trimesh
from hypothesis import given
from hypothesis import strategies as st

from inshade import technique
from inshade.bundle import Bundle
from inshade.runtime.network import gl_function
from inshade.runtime.programs import ProgramCache
from inshade.runtime.render import FullscreenPass, float_target, read_rgba_raw, release_target, upload_float_texture
from inshade.runtime.shadow import ShadowMaps, bounding_sphere, light_frame, light_matrices, shadow_visibility_np
from inshade.technique import ShadowRequest

from parity import parity_settings

FEW = parity_settings(4)
SIZE = 64          # map side in the tests: small, so shadow edges span many sample points
# |GLSL - numpy| for the same comparisons: the bilinear PCF weights are computed from float32
# clip coordinates in GLSL (~1e-7 relative, times SIZE / 2 texels per clip unit), float64 in numpy
PCF_TOL = 1e-5
# a comparison this close to equality may round either way in float32: such points are skipped
AMBIGUOUS = 1e-5


def _quad(a, b, c, d):
    return [a, b, c, d], [[0, 1, 2], [0, 2, 3]]


def caster() -> tuple[np.ndarray, np.ndarray]:
    """The unit-square ground (y = 0), a box floating over it and a vertical zero-thickness card."""
    parts = [_quad((0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)),
             _quad((0.6, 0.1, 0.7), (0.85, 0.1, 0.7), (0.85, 0.5, 0.7), (0.6, 0.5, 0.7))]
    box = trimesh.creation.box(extents=(0.2, 0.15, 0.2))
    box.apply_translation((0.45, 0.375, 0.45))
    parts.append((box.vertices.tolist(), box.faces.tolist()))
    vertices, faces = [], []
    for v, f in parts:
        faces += (np.asarray(f) + len(vertices)).tolist()
        vertices += [list(map(float, p)) for p in v]
    return np.asarray(vertices, np.float32), np.asarray(faces, np.uint32)


def unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64)
    return (v / np.linalg.norm(v)).astype(np.float32)


# toward the light: one lights the card's -z face, the other its +z face
DIRECTIONS = np.stack([unit((0.3, 1.0, -0.5)), unit((-0.4, 0.8, 0.6))])


@pytest.fixture
def maps(gl):
    m = ShadowMaps(gl)
    v, f = caster()
    m.update(ShadowRequest(v, f, DIRECTIONS, size=SIZE, key="caster"))
    yield gl, m
    m.release()


@pytest.fixture
def probe(gl):
    cache = ProgramCache(gl)
    p = FullscreenPass(gl, cache.get("common/fullscreen.vert", "passes/shadow_map_test.frag"))
    yield p
    p.vao.release()
    cache.release()


def glsl_visibility(gl, p, m: ShadowMaps, points: np.ndarray, layers: np.ndarray, bias: float) -> np.ndarray:
    """shadow_visibility(points[i], layers[i], bias) through the test pass, [N]."""
    n = len(points)
    w = 32
    h = -(-n // w)
    data = np.zeros((h * w, 4), np.float32)
    data[:n, :3], data[:n, 3] = points, layers
    tex = upload_float_texture(gl, data.reshape(h, w, 4))
    fbo = float_target(gl, w, h)
    try:
        gl.viewport = (0, 0, w, h)
        unit = m.bind(p.program, 1)
        assert unit == 2
        p.render(fbo, uniforms={"u_bias": bias}, textures={"u_points": tex})
        return read_rgba_raw(fbo).reshape(-1, 4)[:n, 0]
    finally:
        release_target(fbo)
        tex.release()


def ambiguous(depth, matrices, points, layer, bias, margin: float = AMBIGUOUS) -> np.ndarray:
    """Points whose depth comparison against any texel of their 2x2 PCF footprint is within
    ``margin`` of equality (float32 may round it either way)."""
    m = np.asarray(matrices, np.float64)[layer]
    ndc = points.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
    z = ndc[:, 2] * 0.5 + 0.5 - bias
    h, w = depth.shape[1:]
    base = np.floor((ndc[:, :2] * 0.5 + 0.5) * [w, h] - 0.5).astype(np.int64)
    out = np.zeros(len(points), bool)
    for dy in (0, 1):
        for dx in (0, 1):
            stored = depth[layer, np.clip(base[:, 1] + dy, 0, h - 1), np.clip(base[:, 0] + dx, 0, w - 1)]
            out |= np.abs(stored.astype(np.float64) - z) < margin
    return out


# --- the GL pass and the GLSL chunk ------------------------------------------------------------------

def test_matrices_contain_every_caster_vertex(maps):
    """Every vertex of the caster lands strictly inside the clip cube of every light; the light's
    near plane faces the light (a vertex nearer the light has the smaller depth)."""
    _, m = maps
    v, _ = caster()
    assert m.matrices.shape == (2, 4, 4) and m.layers == 2
    for layer, d in enumerate(DIRECTIONS):
        clip = np.c_[v, np.ones(len(v))] @ m.matrices[layer].T.astype(np.float64)
        assert np.abs(clip[:, :3]).max() < 1.0 and np.allclose(clip[:, 3], 1.0)
        toward = v.astype(np.float64) @ d
        assert np.corrcoef(toward, clip[:, 2])[0, 1] < -0.999   # depth decreases toward the light
    np.testing.assert_array_equal(m.matrices, light_matrices(v, DIRECTIONS))
    assert m.depth_scale == pytest.approx(1 / (2 * bounding_sphere(v)[1]))


def test_depth_is_the_nearest_surface(maps):
    """Texel centres seen straight down a light's direction: the stored depth is the first hit of
    a ray cast from the light's near plane (the ground, the box or the card), 1.0 where none."""
    _, m = maps
    depth = m.read()
    assert depth.shape == (2, SIZE, SIZE)
    v, f = caster()
    mesh = trimesh.Trimesh(v, f, process=False)
    for layer, d in enumerate(DIRECTIONS):
        inv = np.linalg.inv(m.matrices[layer].astype(np.float64))
        ij = (np.stack(np.meshgrid(np.arange(SIZE), np.arange(SIZE)), -1).reshape(-1, 2) + 0.5) / SIZE * 2 - 1
        near = np.c_[ij, -np.ones(len(ij)), np.ones(len(ij))] @ inv.T        # clip z = -1: the near plane
        locs, rays, _ = mesh.ray.intersects_location(near[:, :3], np.repeat(-d[None].astype(np.float64), len(ij), 0),
                                                     multiple_hits=False)
        want = np.ones(len(ij))
        want[rays] = ((np.c_[locs, np.ones(len(locs))] @ m.matrices[layer].T.astype(np.float64))[:, 2] + 1) / 2
        got = depth[layer].reshape(-1)
        # texel centres within a hair of a triangle edge may be covered or not by either side
        ok = np.abs(got - want) < 1e-5
        assert ok.mean() > 0.97, f"layer {layer}: {ok.mean():.3f} of texels match ray casting"
        assert (want < 1).sum() > SIZE * SIZE / 4   # the ground covers much of the map


@FEW
@given(seed=st.integers(0, 2 ** 31 - 1), bias=st.sampled_from([0.0, 1e-3, 0.01]))
def test_glsl_equals_numpy_twin(maps, probe, seed, bias):
    """shadow_visibility (GLSL) equals shadow_visibility_np on the read-back maps at random points,
    inside and outside the map, for both layers and for layers -1 / 2 (no such layer: 1.0)."""
    gl, m = maps
    rng = np.random.default_rng(seed)
    n = 32 * 20
    points = rng.uniform(-0.4, 1.4, (n, 3)).astype(np.float32)
    layers = rng.choice([-1, 0, 1, 1, 0, 2], n)
    got = glsl_visibility(gl, probe, m, points, layers, bias)
    depth = m.read()
    want = np.ones(n)
    skip = np.zeros(n, bool)
    for layer in (0, 1):
        sel = layers == layer
        want[sel] = shadow_visibility_np(depth, m.matrices, points[sel], layer, bias)
        skip[sel] = ambiguous(depth, m.matrices, points[sel], layer, bias)
    assert skip.mean() < 0.05
    np.testing.assert_allclose(got[~skip], want[~skip], atol=PCF_TOL, rtol=0)
    np.testing.assert_array_equal(got[(layers < 0) | (layers > 1)], 1.0)
    assert ((want > 0) & (want < 1)).any() and (want[~skip] == 0).any()   # edges and full shadow occur


def clear_of_edges(mesh, m: ShadowMaps, layer: int, points: np.ndarray, bias: float) -> tuple[np.ndarray, np.ndarray]:
    """(hit, clear): whether a ray from each point toward the light hits the caster, and whether
    the point is farther than 2 texels from a shadow edge: rays from the point moved up to 2 texels
    across the light (a 9 x 9 grid of offsets, half a texel apart) all agree, and where they hit, the
    nearest hit is more than 2 biases in front (a surface that close, e.g. a wall nearly parallel to
    the light, has a depth that varies more than that between neighbouring texel centres)."""
    d = DIRECTIONS[layer].astype(np.float64)
    x, y = light_frame(d)
    texel = 2 * bounding_sphere(mesh.vertices)[1] / m.texture.size[0]   # world units per texel
    steps = np.arange(-4, 5) * 0.5 * texel
    hits, near = [], np.full(len(points), np.inf)
    for a in steps:
        for b in steps:
            origins = points.astype(np.float64) + a * x + b * y + 1e-5 * d
            locs, rays, _ = mesh.ray.intersects_location(origins, np.repeat(d[None], len(points), 0),
                                                         multiple_hits=False)
            hit = np.zeros(len(points), bool)
            hit[rays] = True
            np.minimum.at(near, rays, np.linalg.norm(locs - origins[rays], axis=1))
            hits.append(hit)
    hits = np.stack(hits)
    centre = hits[len(hits) // 2]
    agree = hits.all(0) | ~hits.any(0)
    deep = ~centre | (near * m.depth_scale > 2 * bias)
    clip = np.c_[points, np.ones(len(points))] @ m.matrices[layer].T.astype(np.float64)
    return centre, agree & deep & (np.abs(clip[:, :3]) < 1).all(1)


@FEW
@given(seed=st.integers(0, 2 ** 31 - 1))
def test_agrees_with_ray_casting_away_from_edges(maps, probe, seed):
    """Points over the ground, half of them in the shadows of the box and the card (caster surface
    points moved away from the light): away from shadow edges (see clear_of_edges) GLSL gives
    exactly 0 or 1, the ray cast's answer (a ray toward the light hits the caster or not)."""
    gl, m = maps
    rng = np.random.default_rng(seed)
    n = 32 * 16
    v, f = caster()
    mesh = trimesh.Trimesh(v, f, process=False)
    raised = trimesh.Trimesh(v, f[2:], process=False)   # the box and the card (faces 0, 1: the ground)
    bias = 1e-3
    for layer, d in enumerate(DIRECTIONS):
        surface = trimesh.sample.sample_surface(raised, n, seed=int(rng.integers(2 ** 31)))[0]
        shade = surface - rng.uniform(0.05, 0.4, (n, 1)) * d.astype(np.float64)
        free = np.c_[rng.uniform(0, 1, n), rng.uniform(0.01, 0.6, n), rng.uniform(0, 1, n)]
        points = np.concatenate([free, shade[shade[:, 1] > 0.01]]).astype(np.float32)
        got = glsl_visibility(gl, probe, m, points, np.full(len(points), layer), bias)
        hit, clear = clear_of_edges(mesh, m, layer, points, bias)
        assert clear.mean() > 0.3, f"layer {layer}: only {clear.mean():.2f} of the points are clear of edges"
        np.testing.assert_array_equal(got[clear], np.where(hit[clear], 0.0, 1.0), err_msg=f"layer {layer}")
        assert hit[clear].sum() > 15 and (~hit[clear]).sum() > 15   # both answers are tested


def test_thin_card_casts_a_shadow_from_both_sides(maps, probe):
    """The zero-thickness card shadows the ground behind it for the light on either side (no culling)."""
    gl, m = maps
    centre = np.array([0.725, 0.3, 0.7])
    points = np.stack([centre - 0.15 * d.astype(np.float64) for d in DIRECTIONS])   # away from each light
    assert points[0, 2] > 0.7 > points[1, 2]   # one behind each face of the card
    got = glsl_visibility(gl, probe, m, points.astype(np.float32), np.array([0, 1]), 1e-3)
    np.testing.assert_array_equal(got, 0.0)
    lit = glsl_visibility(gl, probe, m, points[::-1].astype(np.float32), np.array([0, 1]), 1e-3)
    np.testing.assert_array_equal(lit, 1.0)   # the same points are lit by the other light


def test_same_request_does_not_redraw_or_allocate(maps):
    """update() with the same key, directions and size draws nothing and makes no GL objects; new
    directions of the same count redraw into the same texture; a new size reallocates it."""
    gl, m = maps
    v, f = caster()
    before, version, tex, drawn = gl_objects(gl), m.version, m.texture, m.read()
    assert not m.update(ShadowRequest(v, f, DIRECTIONS.copy(), size=SIZE, key="caster"))
    assert m.version == version and gl_objects(gl) == before
    assert m.update(ShadowRequest(v, f, DIRECTIONS[::-1].copy(), size=SIZE, key="caster"))
    assert m.version == version + 1 and m.texture is tex and gl_objects(gl) == before
    np.testing.assert_array_equal(m.read(), drawn[::-1])   # the layers follow the directions
    assert m.update(ShadowRequest(v, f, DIRECTIONS, size=SIZE // 2, key="caster"))
    assert m.texture.size == (SIZE // 2, SIZE // 2, 2) and gl_objects(gl) == before


@pytest.mark.parametrize("kwargs, message", [
    (dict(vertices=np.zeros((3, 2))), r"ShadowRequest.vertices: expected \[V, 3\]"),
    (dict(faces=np.array([[0, 1, 9]])), r"ShadowRequest.faces: indices must lie in 0..3"),
    (dict(faces=np.zeros((1, 3), np.float32)), r"ShadowRequest.faces: expected integer \[F, 3\]"),
    (dict(directions=np.array([[0.0, 2.0, 0.0]])), r"ShadowRequest.directions: must be unit vectors"),
    (dict(directions=np.zeros((0, 3))), r"ShadowRequest.directions: expected \[L, 3\] with L >= 1"),
    (dict(size=0), r"ShadowRequest.size: must be an int >= 1, got 0"),
])
def test_bad_requests_name_the_field(kwargs, message):
    args = dict(vertices=np.zeros((4, 3)), faces=np.array([[0, 1, 2]]), directions=np.array([[0.0, 1.0, 0.0]]))
    with pytest.raises(ValueError, match=message):
        ShadowRequest(**{**args, **kwargs})


def test_limits_name_the_field(gl):
    m = ShadowMaps(gl)
    big = int(gl.info["GL_MAX_TEXTURE_SIZE"]) + 1
    with pytest.raises(ValueError, match=rf"ShadowRequest.size: {big} texels; .*GL_MAX_TEXTURE_SIZE"):
        m.update(ShadowRequest(np.zeros((3, 3)), np.array([[0, 1, 2]]), np.array([[0.0, 1.0, 0.0]]), size=big))
    m.release()


# --- GL object counting (glIs*, as the viewer's soak test does) ---------------------------------------

_IS = ("glIsTexture", "glIsBuffer", "glIsFramebuffer", "glIsRenderbuffer", "glIsVertexArray", "glIsProgram")


def gl_objects(gl, upto: int = 2048) -> dict:
    counts = {}
    for name in _IS:
        fn = gl_function(gl, name, ctypes.c_ubyte, ctypes.c_uint)
        counts[name] = sum(1 for i in range(1, upto + 1) if fn(i))
    return counts


# --- ProgramSpec.shadows through SceneRenderer ----------------------------------------------------------

def _hook_request(values) -> ShadowRequest:
    v, f = caster()
    tilt = float(values["sun"])
    return ShadowRequest(v, f, np.stack([unit((0.3 + tilt, 1.0, -0.5)), DIRECTIONS[1]]), size=32, key="caster")


HOOK_CALLS = []


def _shadows(scene, bundles, values):
    HOOK_CALLS.append(dict(values))
    return None if values["off"] else _hook_request(values)


SPEC = technique.ProgramSpec("passes/shadow_scene_test.frag", bundle_kinds=("shadow_scene_test",),
                             uniforms={"u_bias": 1e-3}, shadows=_shadows)
TECH = technique.Technique(name="shadow_scene_test", summary="a test-only program reading lib/shadow_map",
                           kinds=("shadow_scene_test",), programs=(SPEC,))


@pytest.fixture
def shadow_scene(tmp_path):
    if "shadow_scene_test" not in [t.name for t in technique.techniques()]:
        technique.register(TECH)
    out = tmp_path / "shadow_scene"
    meta = {"format": "inshade.bundle", "version": 1, "kind": "shadow_scene_test", "name": "shadow_scene",
            "inputs": [{"name": "uv", "dim": 2, "semantic": "uv"}],
            "nodes": [{"id": "l0", "type": "dense", "inputs": ["uv"], "params": {"out": 3, "bias": True}}],
            "outputs": [{"name": "rgb", "node": "l0", "semantic": "linear_rgb"}]}
    Bundle(meta, {"l0.weight": np.zeros((3, 2), np.float32), "l0.bias": np.zeros(3, np.float32)}).save(out)
    scene = {"format": "inshade.scene", "version": 1, "name": "shadow_scene", "program": SPEC.program,
             "size": [24, 24], "networks": [{"bundle": ".", "output": "rgb"}], "camera": {"type": "plane2d"},
             "settings": {"sun": {"type": "float", "default": 0.0, "min": 0.0, "max": 1.0, "frame": "sun"},
                          "off": {"type": "bool", "default": False, "frame": "off"},
                          "layer": {"type": "int", "default": 0, "min": 0, "max": 1, "uniform": "u_layer"}}}
    (out / "scene.json").write_text(json.dumps(scene))
    yield out
    technique.unregister("shadow_scene_test")


def test_renderer_binds_and_reuses_the_shadow_maps(gl, shadow_scene):
    """SceneRenderer calls ProgramSpec.shadows, draws the maps, binds them (the ground's visibility
    per pixel equals the numpy twin on the renderer's own maps), redraws them only when the request
    changes (a setting the hook reads), and makes no new GL objects for a redraw or a camera move."""
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(shadow_scene)
    r = SceneRenderer(scene, gl)
    try:
        cam = scene.make_camera()
        y, x = np.mgrid[0:24, 0:24]
        ground = np.stack([(x + 0.5) / 24, np.zeros_like(x, float), (y + 0.5) / 24], -1).reshape(-1, 3)

        def check(layer):
            got = r.read("network")[::-1][..., 0].reshape(-1)   # data orientation: pixel (x, y) = [y, x]
            m = r.shadow_maps
            want = shadow_visibility_np(m.read(), m.matrices, ground, layer, 1e-3)
            skip = ambiguous(m.read(), m.matrices, ground, layer, 1e-3)
            np.testing.assert_allclose(got[~skip], want[~skip], atol=PCF_TOL, rtol=0)
            assert (want == 0).any() and (want == 1).any()
            return got

        r.render(cam, 24, 24)
        assert r.shadow_maps.layers == 2 and r.shadow_maps.texture.size == (32, 32, 2)
        first = check(0)
        version, before = r.shadow_maps.version, gl_objects(gl)
        cam.pan(1.0, 0.0, 24, 24)
        r.render(cam, 24, 24)
        assert r.shadow_maps.version == version and gl_objects(gl) == before   # nothing redrawn or made
        assert r.set_setting("layer", 1) == "uniform"
        r.render(cam, 24, 24)
        check(1)
        r.set_setting("layer", 0)
        assert r.set_setting("sun", 0.8) == "uniform"
        r.render(cam, 24, 24)
        assert r.shadow_maps.version == version + 1 and gl_objects(gl) == before
        assert not np.array_equal(check(0), first)   # the shadow moved with the light
        r.set_setting("off", True)
        r.render(cam, 24, 24)
        assert r.shadow_maps.layers == 0
        np.testing.assert_array_equal(r.read("network")[..., 0], 1.0)   # no layers: lit everywhere
        assert HOOK_CALLS and HOOK_CALLS[-1]["off"] is True
    finally:
        r.release()
    assert r.shadow_maps.texture is None
