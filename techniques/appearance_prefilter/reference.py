"""The ground truth the appearance-prefiltering bench compares against: full-geometry ray
tracing with embree, direct lighting only.

Per camera sample (subpixel-jittered, stratified; spp = 1 is the pixel centre, the aliasing
baseline a rasteriser gives): the first hit's colour is

    L = f(v, sun) max(0, n.sun) E_sun V(sun)                         (sun, shadow ray to the whole scene)
      + 1/S sum_s pi f(v, l_s) L_env(l_s) V(l_s)                     (environment, S cosine-weighted l_s)

with f = brdf_np.brdf and the face's real base colour, roughness and metallic; n the geometric
normal, turned toward the viewer on two-sided faces; L_env(d) = max(0, SH(d)) (real orthonormal
SH, inshade/sh.py). A miss shows the environment as the GL passes draw it (lib/spherical_harmonics
sh_background: the series with inshade.sh background_bands' window, clamped at 0). V = 1 when
``shadows`` is False.

Camera: ``scene/camera.py``'s model -- a camera dict (``orbit`` / ``fly``) or (origin, target,
fov_y degrees) as an orbit camera looking from origin at target -- and lib/camera.glsl's ray: the
pixel's far-plane point (ndc z = 1) unprojected by u_inv_view_proj, minus the eye, normalised;
ndc = (pixel + offset) * 2 / size - 1 with offset 0.5 at the pixel centre. Row 0 of the image
is the top.

numpy + embreex; no torch.
"""
from __future__ import annotations

import hashlib
import math

import numpy as np

from inshade.sh import background_bands, band_of, sh_evaluate
from inshade.techniques.appearance_prefilter.brdf_np import brdf

RAY_OFFSET = 1e-5     # shadow/env rays leave the surface along n (unit-box scene, float32 embree)


class ReferenceError(ValueError):
    """Bad reference-render input; the message names the field."""


def _camera(camera):
    from inshade.scene.camera import OrbitCamera, camera_from_dict

    if isinstance(camera, dict):
        cam = camera_from_dict(camera)
        if cam.kind == "plane2d":
            raise ReferenceError("camera.type: a 3D camera (orbit or fly) is needed, got plane2d")
        return cam
    try:
        origin, target, fov_y = camera
        origin = np.asarray(origin, np.float64).reshape(3)
        target = np.asarray(target, np.float64).reshape(3)
        fov_y = float(fov_y)
    except (TypeError, ValueError):
        raise ReferenceError("camera: expected a camera dict or (origin, target, fov_y)") from None
    offset = target - origin
    distance = float(np.linalg.norm(offset))
    if not (np.all(np.isfinite(offset)) and distance > 0.0 and 0.0 < fov_y < 180.0):
        raise ReferenceError("camera: origin and target must differ (finite) and 0 < fov_y < 180")
    f = offset / distance
    # OrbitCamera's forward is (-sin(yaw) cos(pitch), sin(pitch), -cos(yaw) cos(pitch))
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, f[1]))))
    yaw = math.degrees(math.atan2(-f[0], -f[2]))
    return OrbitCamera(fov_y=fov_y, target=tuple(target), distance=distance, yaw=yaw, pitch=pitch)


def camera_rays(camera, width: int, height: int, offset=None):
    """(eye [3], unit directions [H, W, 3] float64), row 0 = top; ``offset`` [H, W, 2] in [0, 1)
    is the sample position inside each pixel (None: the centre, 0.5)."""
    cam = _camera(camera)
    u = cam.uniforms(width, height)
    inv = np.frombuffer(u["u_inv_view_proj"], np.float32).reshape(4, 4).astype(np.float64)
    eye = np.asarray(u["u_eye"], np.float64)
    if offset is None:
        offset = np.full((height, width, 2), 0.5)
    fx = np.arange(width)[None, :] + offset[..., 0]
    fy = np.arange(height - 1, -1, -1)[:, None] + offset[..., 1]       # gl_FragCoord.y, top row first
    clip = np.stack([fx * (2.0 / width) - 1.0, fy * (2.0 / height) - 1.0,
                     np.ones_like(fx), np.ones_like(fx)], -1)
    w = clip @ inv           # GLSL inv * v with pyrr's row-vector layout = v @ inv
    d = w[..., :3] / w[..., 3:4] - eye
    return eye, d / np.linalg.norm(d, axis=-1, keepdims=True)


def _env(env_sh, dirs):
    return np.maximum(sh_evaluate(env_sh, dirs), 0.0)


def _background(env_sh, dirs):
    """What a ray that leaves the scene shows (lib/spherical_harmonics sh_background)."""
    degree = round(math.sqrt(env_sh.shape[0]))
    window = background_bands(degree)[band_of(degree)]
    return np.maximum(sh_evaluate(env_sh * window[:, None], dirs), 0.0)


def _check(size, spp, sun_dir, sun_radiance, env_sh, env_samples):
    if isinstance(size, (int, np.integer)):
        size = (int(size), int(size))
    if (not isinstance(size, (tuple, list)) or len(size) != 2 or
            not all(isinstance(v, (int, np.integer)) and v >= 1 for v in size)):
        raise ReferenceError(f"size: expected an int or (width, height) >= 1, got {size!r}")
    for name, v in (("spp", spp), ("env_samples", env_samples)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ReferenceError(f"{name}: must be an int >= 1, got {v!r}")
    sun = np.asarray(sun_dir, np.float64).reshape(-1)
    if sun.shape != (3,) or not np.all(np.isfinite(sun)) or np.linalg.norm(sun) == 0.0:
        raise ReferenceError(f"sun_dir: expected a finite non-zero 3-vector, got {sun_dir!r}")
    e = np.broadcast_to(np.asarray(sun_radiance, np.float64), (3,))
    if not np.all(np.isfinite(e)) or e.min() < 0.0:
        raise ReferenceError("sun_radiance: must be finite and >= 0 (one value or RGB)")
    sh = np.asarray(env_sh, np.float64)
    if sh.ndim == 1:
        sh = np.repeat(sh[:, None], 3, 1)
    k = sh.shape[0]
    if sh.ndim != 2 or sh.shape[1] != 3 or round(math.sqrt(k)) ** 2 != k or k > 25 or not np.all(np.isfinite(sh)):
        raise ReferenceError(f"env_sh: expected [K, 3] finite SH coefficients (K = 1, 4, 9, 16 or 25), got {sh.shape}")
    return tuple(size), sun / np.linalg.norm(sun), e, sh


def render_reference(scene, camera, size, spp: int = 64, sun_dir=(0.3, 0.8, 0.5), sun_radiance=3.0,
                     env_sh=None, shadows: bool = True, seed: int = 0, env_samples: int = 4) -> np.ndarray:
    """float32 [H, W, 3] linear radiance of ``scene`` (a PrefilterScene) seen by ``camera``."""
    from inshade.techniques.appearance_prefilter.data import _embree

    if env_sh is None:
        env_sh = np.zeros((1, 3))
    (width, height), sun, e_sun, sh = _check(size, spp, sun_dir, sun_radiance, env_sh, env_samples)
    mesh = scene.mesh
    vertices, faces = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    key = hashlib.sha256(vertices.tobytes() + faces.tobytes()).hexdigest()
    common = {"key": f"reference-{key}", "vertices": vertices, "faces": faces}
    rt = _embree(common)
    normals = np.asarray(mesh.face_normals, np.float64)
    rng = np.random.default_rng(seed)
    strata = int(math.ceil(math.sqrt(spp)))
    image = np.zeros((height, width, 3))
    for s in range(spp):
        if spp == 1:
            offset = np.full((height, width, 2), 0.5)
        else:   # stratified over a strata x strata grid, then jittered
            cell = np.array([s % strata, (s // strata) % strata], np.float64)
            offset = (cell + rng.random((height, width, 2))) / strata
        eye, dirs = camera_rays(camera, width, height, offset)
        image += _shade(scene, rt, normals, np.broadcast_to(eye, dirs.shape).reshape(-1, 3), dirs.reshape(-1, 3),
                        sun, e_sun, sh, shadows, env_samples, rng).reshape(height, width, 3)
    return (image / spp).astype(np.float32)


def _shade(scene, rt, normals, origin, dirs, sun, e_sun, sh, shadows, env_samples, rng):
    from inshade.techniques.appearance_prefilter.data import _cast, _occluded

    face, t = _cast(rt, origin, dirs, np.full(len(origin), 1e30))
    out = _background(sh, dirs)
    hit = face >= 0
    if not hit.any():
        return out
    f = face[hit]
    v = -dirs[hit]
    n = normals[f]
    flip = scene.two_sided[f] & ((n * v).sum(-1) < 0.0)
    n = np.where(flip[:, None], -n, n)
    x = origin[hit] + t[hit, None] * dirs[hit] + RAY_OFFSET * n
    base, rough, metal = scene.base_colour[f], scene.roughness[f], scene.metallic[f]
    sun_l = np.broadcast_to(sun, n.shape)
    cos = np.clip((n * sun_l).sum(-1), 0.0, None)
    vis = np.ones(len(f))
    if shadows:
        vis = ~_occluded(rt, x, sun_l, np.full(len(f), 1e30))
    colour = brdf(n, v, sun_l, base, rough, metal) * (cos * vis)[:, None] * e_sun
    # all env samples of all hits in one batch: [hits * S]
    rep = lambda a: np.repeat(a, env_samples, axis=0)    # noqa: E731
    n_s = rep(n)
    l = _cosine_sample(n_s, rng.random((len(n_s), 2)))
    env = _env(sh, l)
    if shadows:
        env = env * ~_occluded(rt, rep(x), l, np.full(len(l), 1e30))[:, None]
    radiance = math.pi * brdf(n_s, rep(v), l, rep(base), rep(rough), rep(metal)) * env
    colour += radiance.reshape(len(f), env_samples, 3).mean(1)
    out[hit] = colour
    return out


def _cosine_sample(n, u):
    """Cosine-weighted directions about unit normals n [R, 3] (pdf cos / pi)."""
    r, phi = np.sqrt(u[:, 0]), 2.0 * math.pi * u[:, 1]
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.clip(1.0 - u[:, 0], 0.0, None))], -1)
    a = np.where(np.abs(n[:, :1]) > 0.9, np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]))
    t = np.cross(a, n)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(n, t)
    return local[:, :1] * t + local[:, 1:2] * b + local[:, 2:3] * n
