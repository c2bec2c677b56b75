"""The scene's environment as a texture a shader can look up and importance-sample (lib/environment).

``environment_image`` turns the scene's environment (a sky preset or a loaded map, rotated about +y)
into an equirectangular radiance image; ``EnvironmentSampler`` builds a piecewise-constant 2D
distribution over its texels (weight = luminance x sin(theta): a marginal CDF over rows, one
conditional CDF per row) and is the numpy twin of the GLSL functions; ``EnvironmentTextures`` holds
the GL textures and binds them. Torch-free.

CONVENTIONS (shared with shaders/lib/environment.glsl):

- direction <-> equirect as inshade/sh.py: theta from +y, phi = atan2(x, -z), u = phi / 2pi + 0.5,
  v = theta / pi; image row 0 looks up (+y), the image centre looks down -z.
- nearest-texel lookup: theta = atan2(|d.xz|, d.y) (accurate near the poles, unlike acos),
  column j = clamp(floor(u W), 0, W-1), row i = clamp(floor(v H), 0, H-1).
- textures in data orientation: texel (j, i) holds image[i, j] (no flip).
- sampling (as PBRT's Distribution2D): u[1] picks the row by inverse CDF (the largest i with
  marginal[i] <= u[1]), u[0] the column in that row; the offset inside the texel is linear in u,
  so the density is uniform in (u, v) inside a texel and the solid-angle pdf is
  p_texel * W * H / (2 pi^2 sin(theta)). A direction with sin(theta) = 0 gets pdf 0.
- p_texel = (marginal[i+1] - marginal[i]) * (conditional[i, j+1] - conditional[i, j]), computed in
  float32 from the float32 CDFs the shader reads, i.e. exactly the measure of u that selects the
  texel; it is stored in the radiance texture's alpha so GLSL and numpy use the same number.
"""
from __future__ import annotations

import functools
import math

import moderngl
import numpy as np

from inshade.scene.image_io import load_environment
from inshade.sh import procedural_sky, rotation_matrix, sky_radiance, equirect_directions

PRESET_WIDTH = 512   # sky presets at 512x256: texels of 0.7 deg resolve the sharpest sun lobe
# ("noon", sharpness 3000: ~1 deg wide); 256x128 would spread it over ~2 texels.
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])   # Rec. 709 weights (linear RGB)
U_MAX = np.float32(np.nextafter(np.float32(1.0), np.float32(0.0)))   # largest float32 below 1
ENV_UNIFORMS = ("u_env_radiance", "u_env_marginal", "u_env_conditional")


# --- the image ----------------------------------------------------------------------------------

def scene_environment(scene, values) -> dict:
    """The scene's environment with its "environment" settings applied (``values`` by setting name)."""
    if scene.environment is None:
        raise ValueError(f"scene '{scene.name}': program {scene.program} samples the environment "
                         "(lib/environment) but the scene has no environment (only SDF and mesh scenes do)")
    env = dict(scene.environment)
    for name, s in scene.settings.items():
        if s.binding == "environment":
            env[s.target] = values[name]
    return env


@functools.lru_cache(maxsize=4)
def _map(path: str) -> np.ndarray:
    image = load_environment(path)
    image.setflags(write=False)
    return image


def environment_image(scene_environment: dict, values: dict | None = None) -> np.ndarray:
    """The environment as float32 [H, W, 3] linear radiance (the convention above).

    ``scene_environment`` is a scene's "environment" ({"sky", "rotation", ["map"], ["intensity"]});
    ``values`` overrides them (what "environment" settings target); "intensity" scales the radiance. Rotation by r degrees about
    +y is the SH path's (runtime/renderer.py ``environment_sh``): the rotated radiance at w is the
    original at R^T w, i.e. at azimuth phi + r. Presets are evaluated there exactly; a map's columns
    are shifted by r / 360 * W with periodic linear interpolation (exact for whole-texel shifts)."""
    env = {**scene_environment, **(values or {})}
    gain = float(env.get("intensity", 1.0))
    image = _unscaled_image(env)
    return image if gain == 1.0 else (image * np.float32(gain)).astype(np.float32)


def _unscaled_image(env: dict) -> np.ndarray:
    sky, rotation = env.get("sky"), env.get("rotation", 0.0)
    if isinstance(rotation, bool) or not isinstance(rotation, (int, float)) or not math.isfinite(rotation):
        raise ValueError(f"environment.rotation: must be a finite number of degrees, got {rotation!r}")
    if sky == "map":
        if not isinstance(env.get("map"), str):
            raise ValueError("environment.map: sky 'map' needs environment.map (an image path)")
        image = np.asarray(_map(env["map"]), np.float64)
        w = image.shape[1]
        shift = (float(rotation) / 360.0 * w) % w
        lo = int(math.floor(shift))
        frac = shift - lo
        cols = (np.arange(w) + lo) % w
        out = image[:, cols] * (1.0 - frac) + image[:, (cols + 1) % w] * frac if frac else image[:, cols]
        return np.ascontiguousarray(out, np.float32)
    if not isinstance(sky, str):
        raise ValueError(f"environment.sky: must be a sky name, got {sky!r}")
    if not rotation:
        return procedural_sky(sky, PRESET_WIDTH)
    r = rotation_matrix([0.0, 1.0, 0.0], math.radians(float(rotation)))
    dirs = equirect_directions(PRESET_WIDTH, PRESET_WIDTH // 2)
    return sky_radiance(sky, dirs @ r).astype(np.float32)   # row d -> R^T d


# --- the distribution (numpy twin) ----------------------------------------------------------------

def _cdf(weights: np.ndarray) -> np.ndarray:
    """float32 CDFs [..., N+1] of non-negative weights [..., N]: 0 first, exactly 1 last; a row
    without weight gets a uniform CDF (it is never selected, but stays searchable)."""
    total = weights.sum(-1, keepdims=True)
    n = weights.shape[-1]
    safe = np.where(total > 0, weights, 1.0)
    c = np.cumsum(safe, -1) / np.where(total > 0, total, n)
    out = np.concatenate([np.zeros(weights.shape[:-1] + (1,)), c], -1).astype(np.float32)
    out[..., -1] = 1.0
    return out


class EnvironmentSampler:
    """Importance sampling of an equirectangular image [H, W, 3] (W = 2H), numpy side."""

    def __init__(self, image):
        image = np.asarray(image)
        if image.ndim != 3 or image.shape[2] not in (3, 4) or image.shape[1] != 2 * image.shape[0] \
                or image.shape[0] < 1:
            raise ValueError(f"environment image: expected an equirectangular [H, W, 3] array with W = 2H, "
                             f"got shape {list(image.shape)}")
        rgb = image[..., :3].astype(np.float64)
        if not np.isfinite(rgb).all() or (rgb < 0).any():
            raise ValueError("environment image: radiance must be finite and >= 0")
        self.height, self.width = rgb.shape[:2]
        h, w = self.height, self.width
        sin_theta = np.sin((np.arange(h) + 0.5) * (math.pi / h))[:, None]
        weight = (rgb @ LUMINANCE) * sin_theta
        if not weight.sum() > 0:          # black environment: uniform over the sphere
            weight = np.broadcast_to(sin_theta, (h, w)).copy()
        self.marginal = _cdf(weight.sum(1))            # [H+1]
        self.conditional = _cdf(weight)                # [H, W+1]
        p = (self.marginal[1:] - self.marginal[:-1])[:, None] * (self.conditional[:, 1:] - self.conditional[:, :-1])
        self.texel_probability = p.astype(np.float32)  # [H, W], float32 ops as in GLSL
        self._row_keys = ((np.arange(h, dtype=np.int64)[:, None] << 31) + self.conditional.view(np.int32)).reshape(-1)
        self.image = np.ascontiguousarray(rgb, np.float32)
        self.pdf_scale = h * w / (2.0 * math.pi * math.pi)   # uv density -> solid angle (times 1/sin theta)

    def texels(self, dirs) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(row i, column j, sin(theta)) of unit directions [N, 3] (nearest texel, as GLSL)."""
        d = np.asarray(dirs, np.float64)
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        s = np.hypot(d[..., 0], d[..., 2])
        theta = np.arctan2(s, d[..., 1])
        phi = np.arctan2(d[..., 0], -d[..., 2])
        j = np.clip(np.floor((phi / (2.0 * math.pi) + 0.5) * self.width), 0, self.width - 1).astype(np.int64)
        i = np.clip(np.floor(theta / math.pi * self.height), 0, self.height - 1).astype(np.int64)
        return i, j, s

    def radiance(self, dirs) -> np.ndarray:
        """Radiance [N, 3] of the nearest texel."""
        i, j, _ = self.texels(dirs)
        return self.image[i, j]

    def pdf(self, dirs) -> np.ndarray:
        """Solid-angle density [N] of ``sample`` at unit directions [N, 3]."""
        i, j, s = self.texels(dirs)
        p = self.texel_probability[i, j] * self.pdf_scale
        return np.where(s > 0, p / np.where(s > 0, s, 1.0), 0.0)

    def sample(self, u) -> tuple[np.ndarray, np.ndarray]:
        """Directions [N, 3] and their solid-angle pdf [N] from uniforms u [N, 2] in [0, 1)
        (float32, as a shader gets them; u[:, 1] picks the row, u[:, 0] the column)."""
        u = np.clip(np.asarray(u, np.float32), np.float32(0.0), U_MAX) + np.float32(0.0)   # -0 -> +0
        if u.ndim != 2 or u.shape[1] != 2:
            raise ValueError(f"sample: u must be [N, 2], got shape {list(u.shape)}")
        h, w = self.height, self.width
        # largest index with cdf <= u: the same float32 comparisons as the GLSL binary search
        i = np.clip(np.searchsorted(self.marginal, u[:, 1], side="right") - 1, 0, h - 1)
        # the row's CDF searched as one sorted array of keys row * 2^31 + float32 bits (non-negative
        # float32 order = their bit patterns' order): exact, like the shader's comparisons
        key = (i.astype(np.int64) << 31) + u[:, 0].view(np.int32)
        j = np.clip(np.searchsorted(self._row_keys, key, side="right") - 1 - i * (w + 1), 0, w - 1)
        m0, m1 = self.marginal[i].astype(np.float64), self.marginal[i + 1].astype(np.float64)
        c0, c1 = self.conditional[i, j].astype(np.float64), self.conditional[i, j + 1].astype(np.float64)
        south = 2 * i >= h       # theta from the nearer pole, as the GLSL (its float32 precision)
        edge = np.where(south, (m1 - u[:, 1]) / (m1 - m0), (u[:, 1] - m0) / (m1 - m0))
        angle = math.pi * (np.where(south, h - 1 - i, i) + edge) / h
        st, ct = np.sin(angle), np.where(south, -np.cos(angle), np.cos(angle))
        phi = 2.0 * math.pi * ((j + (u[:, 0] - c0) / (c1 - c0)) / w - 0.5)
        dirs = np.stack([st * np.sin(phi), ct, -st * np.cos(phi)], -1)
        p = self.texel_probability[i, j] * self.pdf_scale
        return dirs, np.where(st > 0, p / np.where(st > 0, st, 1.0), 0.0)


# --- GL side --------------------------------------------------------------------------------------

class EnvironmentTextures:
    """The sampler's textures: ``u_env_radiance`` RGBA32F [H, W] (rgb radiance, a = texel
    probability), ``u_env_marginal`` R32F [H+1, 1], ``u_env_conditional`` R32F [W+1, H]; NEAREST,
    clamp-to-edge, read with texelFetch. ``bind`` also sets ``u_env_size`` = (W, H)."""

    def __init__(self, ctx: moderngl.Context, sampler: EnvironmentSampler):
        from .render import check_gl_error, clear_gl_error

        limit = min(int(ctx.info["GL_MAX_TEXTURE_SIZE"]), 2 ** 17)   # 2^17: lib/environment ENV_SEARCH_STEPS
        if sampler.width + 1 > limit:
            raise ValueError(f"environment map: {sampler.width} texels wide needs textures of "
                             f"{sampler.width + 1} texels; this context allows {limit} (GL_MAX_TEXTURE_SIZE)")
        self.ctx, self.sampler = ctx, sampler
        self.size = (sampler.width, sampler.height)
        rgba = np.concatenate([sampler.image, sampler.texel_probability[..., None]], -1)
        clear_gl_error(ctx, "the environment textures")
        self.textures = {"u_env_radiance": self._texture(rgba),
                         "u_env_marginal": self._texture(sampler.marginal[None, :, None]),
                         "u_env_conditional": self._texture(sampler.conditional[..., None])}
        check_gl_error(ctx, f"environment textures ({sampler.width}x{sampler.height})")

    def _texture(self, data: np.ndarray) -> moderngl.Texture:
        data = np.ascontiguousarray(data, np.float32)
        tex = self.ctx.texture((data.shape[1], data.shape[0]), data.shape[2], data.tobytes(), dtype="f4")
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        tex.repeat_x = tex.repeat_y = False
        return tex

    def bind(self, program: moderngl.Program, first_unit: int = 0) -> int:
        """Bind the textures the program uses from texture unit ``first_unit``; returns the next free unit."""
        unit = first_unit
        for name, tex in self.textures.items():
            if name in program:
                tex.use(location=unit)
                program[name].value = unit
                unit += 1
        if "u_env_size" in program:
            program["u_env_size"].value = self.size
        return unit

    def release(self) -> None:
        for tex in self.textures.values():
            tex.release()
        self.textures = {}


def mis_power(a, b) -> np.ndarray:
    """Power-heuristic (beta = 2) weight a^2 / (a^2 + b^2) of the strategy with density a; 0 where
    a = 0 (GLSL: mis_power in lib/environment)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    den = a * a + b * b
    return np.where(a > 0, a * a / np.where(den > 0, den, 1.0), 0.0)
