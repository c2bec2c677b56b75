"""What the scene pass reads besides its networks' code: the scene's textures and reference image,
its uniforms (camera, settings, lights, environment SH, the technique's per-frame values), the
importance-sampled environment, the shadow maps, and the texture units they are bound to."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Callable

import moderngl
import numpy as np
from PIL import Image

from inshade.codegen.sdf import environment_sh as sky_sh
from inshade.scene.description import SceneError
from inshade.scene.image_io import read_exr
from inshade.technique import FrameInputs

from .environment import EnvironmentSampler, EnvironmentTextures, environment_image, scene_environment
from .shadow import ShadowMaps


def scene_texture(ctx: moderngl.Context, t) -> moderngl.Texture:
    """A scene.json texture: RGBA8 bytes as stored (no sRGB decode), uv (0,0) = bottom-left."""
    data = np.asarray(Image.open(t.image).convert("RGBA"), np.uint8)[::-1]
    tex = ctx.texture(data.shape[1::-1], 4, np.ascontiguousarray(data).tobytes(), alignment=1)
    if t.mipmaps:
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        tex.anisotropy = min(t.anisotropy, ctx.max_anisotropy)
    else:
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = t.repeat
    return tex


def load_reference(path: Path, colour: str = "srgb") -> np.ndarray:
    """Reference image as linear float32 RGB [H, W, 3], image orientation (row 0 = top)."""
    if colour == "linear":
        return np.asarray(read_exr(path), np.float32)[..., :3]
    encoded = np.asarray(Image.open(path).convert("RGB"), np.float64) / 255.0
    linear = np.where(encoded <= 0.04045, encoded / 12.92, ((encoded + 0.055) / 1.055) ** 2.4)
    return linear.astype(np.float32)


def reference_texture(ctx: moderngl.Context, scene) -> tuple[np.ndarray | None, moderngl.Texture]:
    """(the scene's reference image or None, its texture for the display pass: one black texel
    without a reference, since the display program samples it either way)."""
    image = None
    if scene.reference is not None:
        image = load_reference(scene.reference.image, scene.reference.colour)
        tex = ctx.texture(image.shape[1::-1], 3, np.ascontiguousarray(image[::-1]).tobytes(),
                          dtype="f4")   # uv (0,0) = bottom-left
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    else:
        tex = ctx.texture((1, 1), 3, np.zeros(3, "f4").tobytes(), dtype="f4")
    tex.repeat_x = tex.repeat_y = False
    return image, tex


def rotated_map_sh(coeffs: np.ndarray, rotation_deg: float) -> np.ndarray:
    """An environment map's SH rotated about +y, float32, as codegen.sdf.environment_sh does for
    the sky presets."""
    from inshade.sh import rotate_sh, rotation_matrix

    if rotation_deg:
        coeffs = rotate_sh(coeffs, rotation_matrix([0.0, 1.0, 0.0], math.radians(rotation_deg)))
    return np.asarray(coeffs, np.float32)


def environment_sh(scene, values: dict) -> np.ndarray:
    """The radiance SH [K, 3] float32 of the scene's environment with its settings applied."""
    env = dict(scene.environment)
    for name, s in scene.settings.items():
        if s.binding == "environment":
            env[s.target] = values[name]
    if env["sky"] == "map":   # environment.map, projected at load time (scene/description.py)
        sh = rotated_map_sh(scene.environment_map, float(env["rotation"]))
    else:
        sh = sky_sh(env["sky"], float(env["rotation"]), int(env["degree"]))
    gain = float(env.get("intensity", 1.0))
    return sh if gain == 1.0 else (sh * np.float32(gain)).astype(np.float32)


def scene_uniforms(scene, spec, values: dict, program, camera, width, height,
                   sh: Callable[[], np.ndarray]) -> dict:
    """The uniforms ``program`` declares, as the scene pass sets them for ``camera`` at this size
    (``sh``: the environment's SH, asked for only where the scene is lit)."""
    out = {"u_size": (float(width), float(height))}
    out.update(spec.uniforms)
    out.update(camera.uniforms(width, height))
    for name, s in scene.settings.items():
        if s.binding == "uniform":
            v = values[name]
            if isinstance(v, bool):
                v = int(v)
            elif s.type == "choice":   # a choice drives an int uniform: its (declared) index
                v = s.index(v)
            out[s.target] = v
    if "u_lights" in program:   # lib/lights.glsl: the scene's lights
        from inshade.scene.description import light_uniforms
        # a program that never calls scene_light (u_light_kinds unused) reads u_lights as positions
        if any(light.kind != "point" for light in scene.lights) and "u_light_kinds" not in program:
            raise SceneError(f"lights: {scene.program} treats every light as a point light (it reads "
                             "u_lights without scene_light from lib/lights); use point lights only")
        out.update(light_uniforms(scene.lights))
    if scene.lit:
        coeffs = sh()
        out["u_sh"] = coeffs.tobytes()
    if spec.frame is not None:   # per-frame CPU work of the technique (e.g. a light matrix)
        out.update(spec.frame(FrameInputs(scene, values, coeffs if scene.lit else None)))
    return {k: v for k, v in out.items() if k in program}


class SceneEnvironment:
    """The importance-sampled environment textures (lib/environment), rebuilt only when the sky,
    its rotation or its map change."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.textures: EnvironmentTextures | None = None
        self.key = None

    def sync(self, scene, values: dict) -> EnvironmentTextures:
        try:
            env = scene_environment(scene, values)
        except ValueError as exc:
            raise SceneError(str(exc)) from None
        key = (env.get("sky"), float(env.get("rotation", 0.0)), env.get("map"))
        if self.textures is None or key != self.key:
            textures = EnvironmentTextures(self.ctx, EnvironmentSampler(environment_image(env)))
            if self.textures is not None:
                self.textures.release()
            self.textures, self.key = textures, key
        return self.textures

    def release(self) -> None:
        if self.textures is not None:
            self.textures.release()
            self.textures = None


def sync_shadows(spec, scene, bundles, values: dict, shadow_maps: ShadowMaps) -> int:
    """Redraws the shadow maps if the program's request changed; their version (a redraw key)."""
    if spec.shadows is not None:
        request = spec.shadows(scene, bundles, values)
        if request is None:
            shadow_maps.clear()
        else:
            shadow_maps.update(request)
    return shadow_maps.version


def bind_scene_resources(program, resources, scene_textures: dict, environment: Callable[[], EnvironmentTextures],
                         shadow_maps: ShadowMaps, gbuffer_names=(), gbuffer=None) -> None:
    """Bind what the scene program samples, one texture unit after the other: its networks'
    resources, the scene's textures, the environment (``environment()`` brings it up to date),
    the shadow maps and the G-buffer's textures (``gbuffer``, named ``gbuffer_names``, or none)."""
    unit = 0
    for block, res in enumerate(resources):
        unit = res.bind(program, first_unit=unit, first_block=block * 16)
    for name, tex in scene_textures.items():   # scene.json "textures"
        if name in program:
            tex.use(location=unit)
            program[name].value = unit
            unit += 1
    if "u_env_radiance" in program:   # lib/environment: the importance-sampled environment
        unit = environment().bind(program, unit)
    if "u_shadow_map" in program or "u_shadow_layers" in program:   # lib/shadow_map
        unit = shadow_maps.bind(program, unit)
    if gbuffer is not None:   # deferred mesh pass: texelFetch'ed by the scene program
        for name, tex in zip([f"u_gbuffer_{n}" for n in gbuffer_names], gbuffer):
            if name in program:
                tex.use(location=unit)
                program[name].value = unit
                unit += 1
