"""How a scene is lit: its ``"lights"`` (point and directional, uploaded as ``u_lights`` +
``u_light_kinds`` to programs that include ``lib/lights``) and, for an SDF or mesh scene, its
``"environment"``: a procedural sky or an equirectangular map, projected to SH."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from inshade import technique

from .common import SceneError, finite

MAX_LIGHTS = 4   # lib/lights.glsl INSHADE_MAX_LIGHTS
ENVIRONMENT_KEYS = {"sky", "rotation", "degree", "map", "intensity"}


@dataclass(frozen=True)
class PointLight:
    position: tuple[float, float, float]
    intensity: float
    kind = "point"

    def to_dict(self) -> dict:
        return {"type": "point", "position": list(self.position), "intensity": self.intensity}


@dataclass(frozen=True)
class DirectionalLight:
    direction: tuple[float, float, float]   # unit vector towards the light
    intensity: float                        # irradiance, no falloff
    kind = "directional"

    def to_dict(self) -> dict:
        return {"type": "directional", "direction": list(self.direction), "intensity": self.intensity}


# light type -> (its vector field, the class); the kind's index is u_light_kinds' value
# (lib/lights.glsl INSHADE_LIGHT_POINT 0, INSHADE_LIGHT_DIRECTIONAL 1)
LIGHT_TYPES = {"point": ("position", PointLight), "directional": ("direction", DirectionalLight)}
LIGHT_KINDS = tuple(LIGHT_TYPES)


def parse_lights(data) -> list:
    """scene.json "lights": [{"type": "point", "position": [x, y, z], "intensity": I} or
    {"type": "directional", "direction": [x, y, z] (towards the light), "intensity": I}, ...]."""
    if not isinstance(data, list):
        raise SceneError("lights: must be a list of {\"type\": \"point\", \"position\": [x, y, z], \"intensity\": I} "
                         "or {\"type\": \"directional\", \"direction\": [x, y, z], \"intensity\": I}")
    if len(data) > MAX_LIGHTS:
        raise SceneError(f"lights: at most {MAX_LIGHTS} lights, got {len(data)}")
    return [_light(light, f"lights[{i}]") for i, light in enumerate(data)]


def _light(light, w: str):
    if not isinstance(light, dict):
        raise SceneError(f"{w}: must be an object {{\"type\": ..., ...}}")
    kind = light.get("type")
    if not isinstance(kind, str) or kind not in LIGHT_TYPES:
        raise SceneError(f"{w}.type: must be one of {', '.join(map(repr, LIGHT_TYPES))}, got {kind!r}")
    vector, cls = LIGHT_TYPES[kind]
    extra = sorted(set(light) - {"type", vector, "intensity"})
    if extra:
        raise SceneError(f"{w}.{extra[0]}: unknown field for a {kind} light (known: intensity, {vector}, type)")
    vec, power = light.get(vector), light.get("intensity")
    if not (isinstance(vec, list) and len(vec) == 3 and all(finite(v) for v in vec)):
        raise SceneError(f"{w}.{vector}: must be 3 finite numbers, got {vec!r}")
    vec = tuple(float(v) for v in vec)
    if kind == "directional":
        length = math.sqrt(sum(v * v for v in vec))
        if not length > 1e-12 or not math.isfinite(length):
            raise SceneError(f"{w}.direction: must be a non-zero vector of finite length (towards the light), "
                             f"got {list(vec)!r}")
        vec = tuple(v / length for v in vec)
    if not finite(power) or power < 0:
        raise SceneError(f"{w}.intensity: must be a finite number >= 0, got {power!r}")
    return cls(vec, float(power))


def light_uniforms(lights) -> dict:
    """lib/lights.glsl's uniforms for ``lights``: u_lights (vec4: position or direction, intensity),
    u_light_kinds (LIGHT_KINDS index), u_scene_light_count; unused slots are zero."""
    import numpy as np

    packed = np.zeros((MAX_LIGHTS, 4), np.float32)
    kinds = np.zeros(MAX_LIGHTS, np.int32)
    for i, light in enumerate(lights):
        packed[i] = (*(light.position if light.kind == "point" else light.direction), light.intensity)
        kinds[i] = LIGHT_KINDS.index(light.kind)
    return {"u_lights": packed.tobytes(), "u_light_kinds": kinds.tobytes(), "u_scene_light_count": len(lights)}


def parse_environment(value, root: Path, lit: bool, spec: technique.ProgramSpec) -> tuple[dict | None, object]:
    """``"environment"``: kept as given for a flat scene; for a lit one (an SDF or a mesh) the sky
    or map it names, with its defaults, at the SH degree the program uses. Returns (environment,
    map SH or None)."""
    if value is not None and not isinstance(value, dict):
        raise SceneError("environment: must be an object or null")
    if not lit:
        return value, None
    environment, environment_map = lit_environment(value, root)
    need = spec.environment_degree
    if need is not None and environment["degree"] != need:
        raise SceneError(f"environment.degree: {spec.program} uses {need * need} SH coefficients "
                         f"(degree {need}), got {environment['degree']}")
    return environment, environment_map


def lit_environment(env, root: Path) -> tuple[dict, object]:
    """The lighting of an SDF or mesh scene: a procedural sky preset ("sky") or an equirectangular map
    ("map": .exr/.png/.jpg relative to the scene file, projected to SH once here; "sky" is then
    "map"), rotated about +y by "rotation" degrees, its radiance scaled by "intensity". Returns
    (environment, map SH or None)."""
    from inshade.sh import MAX_DEGREE

    given = dict(env or {})
    env = {"sky": "map" if "map" in given else "overcast", "rotation": 0.0, "degree": 4, "intensity": 1.0, **given}
    extra = sorted(set(env) - ENVIRONMENT_KEYS)
    if extra:
        raise SceneError(f"environment.{extra[0]}: unknown field (known: degree, intensity, map, rotation, sky)")
    rot = env["rotation"]
    if isinstance(rot, bool) or not isinstance(rot, (int, float)) or not math.isfinite(rot):
        raise SceneError(f"environment.rotation: must be a finite number of degrees, got {rot!r}")
    gain = env["intensity"]
    if isinstance(gain, bool) or not isinstance(gain, (int, float)) or not math.isfinite(gain) or gain < 0:
        raise SceneError(f"environment.intensity: must be a finite number >= 0, got {gain!r}")
    if env["degree"] not in range(1, MAX_DEGREE + 1):
        raise SceneError(f"environment.degree: must be an int in 1..{MAX_DEGREE}, got {env['degree']!r}")
    sh = _environment_map(env, root) if "map" in env else None
    _check_sky(env["sky"], sh is not None)
    return env, sh


def _environment_map(env: dict, root: Path):
    """The SH of ``env["map"]`` at ``env["degree"]``; the map's path becomes absolute."""
    from inshade.scene.image_io import load_environment
    from inshade.sh import project_environment

    if not isinstance(env["map"], str):
        raise SceneError("environment.map: must name an equirectangular image (.exr, .png, .jpg)")
    path = (root / env["map"]).resolve()
    try:
        sh = project_environment(load_environment(path), env["degree"])
    except ValueError as exc:   # load_environment names the file and what is wrong with it
        raise SceneError(f"environment.map: {exc}") from None
    env["map"] = str(path)
    return sh


def _check_sky(sky, has_map: bool) -> None:
    from inshade.sh import SKY_PRESETS

    if not isinstance(sky, str):
        raise SceneError(f"environment.sky: must be a sky name, got {sky!r}")
    if sky not in SKY_PRESETS and not (sky == "map" and has_map):
        known = ", ".join([*SKY_PRESETS, *(["map"] if has_map else [])])
        raise SceneError(f"environment.sky: unknown sky {sky!r} (known: {known})")


def check_sky_settings(settings: dict, has_map: bool) -> None:
    """Settings that pick the sky name only presets (or "map", when the scene has one)."""
    from inshade.sh import SKY_PRESETS

    for name, s in settings.items():
        if s.binding == "environment" and s.target == "sky":
            bad = [c for c in (s.choices or (s.default,))
                   if not isinstance(c, str) or c not in SKY_PRESETS and not (c == "map" and has_map)]
            if bad:
                raise SceneError(f"settings.{name}.choices: unknown sky {bad[0]!r} (known: {', '.join(SKY_PRESETS)}"
                                 f"{', map' if has_map else ''})")
