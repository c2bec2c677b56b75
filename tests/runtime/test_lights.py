"""Scene lights (scene/description.py "lights", shaders/lib/lights.glsl): point and directional lights
parsed with one error per bad field, packed into lib/lights' uniforms, and ``scene_light`` in GLSL
(through tests/shaders/passes/scene_light_test.frag) against numpy at random points and lights.

Tolerance: the parity rule of tests/parity.py, |glsl - numpy| <= 1e-5 max(1, |numpy|); numpy works
in float64 from the same float32 inputs (the driver's inversesqrt and division differ by ulps).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from inshade.scene.description import (LIGHT_KINDS, MAX_LIGHTS, DirectionalLight, PointLight, SceneError, light_uniforms,
                                   parse_scene)
from parity import assert_parity, parity_settings, run_sample_pass

REPO = Path(__file__).resolve().parents[2]
PLAIN = REPO / "trained" / "neural_image"        # a small scene; its lights are only parsed
PBR = REPO / "trained" / "di_pbr_set_bricks"     # a mesh scene whose pass reads u_lights directly


def _parse(lights, source=PLAIN):
    data = json.loads((source / "scene.json").read_text())
    data["lights"] = lights
    return parse_scene(data, root=source).lights


def test_parse_point_and_directional():
    lights = _parse([{"type": "point", "position": [1, 2, 3], "intensity": 5},
                     {"type": "directional", "direction": [0, 3, -4], "intensity": 2.5}])
    assert lights == [PointLight((1.0, 2.0, 3.0), 5.0), DirectionalLight((0.0, 0.6, -0.8), 2.5)]
    assert [light.kind for light in lights] == ["point", "directional"]
    assert lights[1].to_dict() == {"type": "directional", "direction": [0.0, 0.6, -0.8], "intensity": 2.5}
    # normalised at load: a round trip through to_dict is stable
    assert _parse([lights[1].to_dict()]) == [lights[1]]
    assert _parse([]) == []


@pytest.mark.parametrize("lights, field", [
    ({"type": "point"}, "lights:"),
    ([5], "lights[0]:"),
    ([{"type": "spot", "position": [0, 0, 0], "intensity": 1}], "lights[0].type"),
    ([{"position": [0, 0, 0], "intensity": 1}], "lights[0].type"),
    ([{"type": ["point"], "position": [0, 0, 0], "intensity": 1}], "lights[0].type"),
    ([{"type": "directional", "direction": [0, 0, 0], "intensity": 1}], "lights[0].direction"),
    ([{"type": "directional", "direction": [1e308, 1e308, 1e308], "intensity": 1}], "lights[0].direction"),
    ([{"type": "directional", "direction": [0, 1], "intensity": 1}], "lights[0].direction"),
    ([{"type": "directional", "direction": [0, True, 0], "intensity": 1}], "lights[0].direction"),
    ([{"type": "directional", "direction": "up", "intensity": 1}], "lights[0].direction"),
    ([{"type": "directional", "position": [0, 1, 0], "intensity": 1}], "lights[0].position"),
    ([{"type": "point", "direction": [0, 1, 0], "intensity": 1}], "lights[0].direction"),
    ([{"type": "point", "position": [0, 1, 0]}], "lights[0].intensity"),
    ([{"type": "directional", "direction": [0, 1, 0], "intensity": -1}], "lights[0].intensity"),
    ([{"type": "point", "position": [0, 1, 0], "intensity": 1}] * 4
     + [{"type": "directional", "direction": [0, 1, 0], "intensity": 1}], "lights:"),
])
def test_parse_errors_name_the_field(lights, field):
    with pytest.raises(SceneError) as info:
        _parse(lights)
    message = str(info.value)
    assert message.startswith(field) and "\n" not in message, message


def test_light_uniforms_layout():
    u = light_uniforms([PointLight((1.0, 2.0, 3.0), 4.0), DirectionalLight((0.0, 1.0, 0.0), 0.5)])
    packed = np.frombuffer(u["u_lights"], np.float32).reshape(MAX_LIGHTS, 4)
    kinds = np.frombuffer(u["u_light_kinds"], np.int32)
    assert packed.tolist() == [[1, 2, 3, 4], [0, 1, 0, 0.5], [0, 0, 0, 0], [0, 0, 0, 0]]
    assert kinds.tolist() == [0, 1, 0, 0] and u["u_scene_light_count"] == 2
    # lib/lights.glsl's constants are LIGHT_KINDS' indices
    text = (REPO / "shaders" / "lib" / "lights.glsl").read_text()
    for i, kind in enumerate(LIGHT_KINDS):
        assert f"#define INSHADE_LIGHT_{kind.upper()} {i}\n" in text
    assert f"#define INSHADE_MAX_LIGHTS {MAX_LIGHTS}\n" in text


def _reference(lights, p, index):
    """numpy float64 scene_light: (unit direction to the light, 1/d^2 or 1)."""
    to_light = np.empty_like(p)
    scale = np.empty(len(p))
    for k, light in enumerate(lights):
        sel = index == k
        if light.kind == "point":
            d = np.asarray(light.position, np.float32).astype(np.float64) - p[sel]
            d2 = np.sum(d * d, 1)
            to_light[sel] = d / np.sqrt(d2)[:, None]
            scale[sel] = 1.0 / d2
        else:
            to_light[sel] = np.asarray(light.direction, np.float32).astype(np.float64)
            scale[sel] = 1.0
    return to_light, scale


_vec = st.tuples(*[st.floats(-4.0, 4.0, allow_nan=False, width=32)] * 3)


@parity_settings(max_examples=4)
@given(kinds=st.lists(st.sampled_from(LIGHT_KINDS), min_size=1, max_size=MAX_LIGHTS), vectors=st.lists(
    _vec, min_size=MAX_LIGHTS, max_size=MAX_LIGHTS), seed=st.integers(0, 2 ** 31 - 1))
def test_scene_light_parity(gl, kinds, vectors, seed):
    lights = []
    for kind, v in zip(kinds, vectors):
        if kind == "point":
            lights.append(PointLight(tuple(map(float, v)), 1.0))
        else:
            v = np.asarray(v, np.float64) + [0.0, 0.5, 0.0]   # never zero
            lights.append(DirectionalLight(tuple(v / np.linalg.norm(v)), 1.0))
    rng = np.random.default_rng(seed)
    n = 256
    p = rng.uniform(-4.0, 4.0, (n, 3)).astype(np.float32)
    index = rng.integers(0, len(lights), n)
    # keep points 0.05 away from point lights: 1/d^2 stays a sensible number (<= 400)
    for k, light in enumerate(lights):
        if light.kind == "point":
            pos = np.asarray(light.position, np.float32)
            near = (index == k) & (np.linalg.norm(p - pos, axis=1) < 0.05)
            p[near] = pos + np.float32(0.1)
    rows = np.concatenate([p, index[:, None].astype(np.float32)], 1)
    out = run_sample_pass(gl, "passes/scene_light_test.frag", rows, uniforms=light_uniforms(lights))[0]
    to_light, scale = _reference(lights, p.astype(np.float64), index)
    assert_parity(out[:, :3], to_light, what="scene_light to_light")
    assert_parity(out[:, 3], scale, what="scene_light irradiance_scale")
    assert np.allclose(np.linalg.norm(out[:, :3], axis=1), 1.0, atol=1e-5)


def test_directional_light_refused_by_a_point_only_program(gl):
    """The shipped PBR pass reads u_lights as positions: a directional light there is an error at
    render time that names the lights and the program, not a light at the wrong place."""
    from inshade.runtime.headless import render_scene

    data = json.loads((PBR / "scene.json").read_text())
    data["lights"] = [{"type": "directional", "direction": [0, 1, 0], "intensity": 1.0}]
    scene = parse_scene(data, root=PBR)
    with pytest.raises(SceneError, match=r"^lights: passes/mesh_pbr_set.frag treats every light as a point light"):
        render_scene(scene, width=8, height=8)
