"""The radiance field's procedural scene ("still life") and its ground-truth images (numpy, float64,
deterministic; no downloads).

Inside the unit box [0, 1]^3 (the network's box, y up):
  - a base slab with a fine soft checker (period 1/20 of the box), a faint sheen;
  - a glossy red sphere with a tight white highlight (shininess 60);
  - a flat torus with fine stripes (14 around the ring) and a broad highlight;
  - three thin rods (radius 0.009: about 3.5 march steps across) carrying a thin gold wire ring
    (minor radius 0.008) whose highlight is gold.
Every primitive is an exact SDF, the scene is their hard union (so the scene SDF is 1-Lipschitz:
the ground-truth march skips empty space exactly, see ``render``).

Density (compact support, so empty space is exactly empty): sigma = DENSITY * smoothstep(-1, 1,
-sdf / SHELL), extinction per box unit. Colour at a point x seen along the unit direction d (view
dependent, defined everywhere so a march may meet it anywhere in the shell):
    n = the SDF's unit gradient, h = normalize(LIGHT - d),
    lit = albedo (AMBIENT + (1 - AMBIENT) max(n.LIGHT, 0)) + ks spec_colour max(n.h, 0)^shininess
          * smoothstep(0, 0.15, n.LIGHT),
    rgb = clip(lit, 0, 1),
with each material's albedo, ks, colour and shininess blended across primitives by weights
exp(-(d_k - d_min) / BLEND) (smooth where two primitives meet).

The ground truth is the march the shader runs (radiance_field_march.py: the sample positions
t0 + (i + 0.5) dt in box units, alpha = 1 - exp(-sigma dt), front to back, stopped once the
transmittance falls under STOP, then the background) applied to this analytic field: the
reference a radiance field of the same march settings can reach.
"""
from __future__ import annotations

import math

import numpy as np

LIGHT = np.array([0.45, 0.85, 0.3]) / np.linalg.norm([0.45, 0.85, 0.3])
AMBIENT = 0.3
DENSITY = 600.0     # extinction per box unit inside an object
SHELL = 0.004       # half-width of the density ramp around the surface (box units)
BLEND = 0.006       # material blending distance between primitives (box units)
TARGET = (0.5, 0.33, 0.5)   # what the views orbit
SCENES = ("still_life",)


class SceneError(ValueError):
    """A scene name or view request the scene cannot make (the message names the option)."""


# --- exact SDFs ------------------------------------------------------------------------------------

def _sphere(p, centre, r):
    return np.linalg.norm(p - np.asarray(centre), axis=-1) - r


def _round_box(p, centre, half, r):
    q = np.abs(p - np.asarray(centre)) - (np.asarray(half) - r)
    return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(-1), 0.0) - r


def _torus_y(p, centre, major, minor):
    """A torus around the y axis; also its angle around that axis."""
    q = p - np.asarray(centre)
    ring = np.hypot(q[..., 0], q[..., 2]) - major
    return np.hypot(ring, q[..., 1]) - minor, np.arctan2(q[..., 2], q[..., 0])


def _capsule(p, a, b, r):
    a, b = np.asarray(a), np.asarray(b)
    pa, ba = p - a, b - a
    h = np.clip((pa @ ba) / (ba @ ba), 0.0, 1.0)
    return np.linalg.norm(pa - h[..., None] * ba, axis=-1) - r


SLAB = dict(centre=(0.5, 0.14, 0.5), half=(0.38, 0.04, 0.38), r=0.015)
SPHERE = dict(centre=(0.34, 0.33, 0.6), r=0.15)
TORUS = dict(centre=(0.68, 0.22, 0.36), major=0.11, minor=0.04)
RING = dict(centre=(0.67, 0.58, 0.7), major=0.085, minor=0.008)
RODS = tuple((0.67 + 0.085 * math.cos(a), 0.18, 0.7 + 0.085 * math.sin(a)) for a in (0.3, 2.4, 4.5))
ROD_RADIUS = 0.009

# per primitive: albedo (None: a texture, see _albedo), ks, specular colour, shininess
MATERIALS = {
    "slab": (None, 0.12, (1.0, 1.0, 1.0), 8.0),
    "sphere": ((0.72, 0.1, 0.06), 0.45, (1.0, 1.0, 1.0), 60.0),
    "torus": (None, 0.25, (1.0, 0.95, 0.9), 16.0),
    "rods": ((0.2, 0.22, 0.26), 0.3, (0.9, 0.9, 1.0), 24.0),
    "ring": ((0.55, 0.4, 0.12), 0.4, (1.0, 0.8, 0.35), 32.0),
}
PRIMITIVES = tuple(MATERIALS)


def primitives(p: np.ndarray):
    """(distances [5, ...] in PRIMITIVES order, the torus angle [...]) at points p [..., 3]."""
    torus, phi = _torus_y(p, TORUS["centre"], TORUS["major"], TORUS["minor"])
    ring, _ = _torus_y(p, RING["centre"], RING["major"], RING["minor"])
    top = RING["centre"][1]
    rods = np.min([_capsule(p, foot, (foot[0], top, foot[2]), ROD_RADIUS) for foot in RODS], axis=0)
    return np.stack([_round_box(p, SLAB["centre"], SLAB["half"], SLAB["r"]),
                     _sphere(p, SPHERE["centre"], SPHERE["r"]), torus, rods, ring]), phi


def sdf(p: np.ndarray) -> np.ndarray:
    return primitives(p)[0].min(0)


def normal(p: np.ndarray, h: float = 2e-4) -> np.ndarray:
    """The scene SDF's unit gradient (central differences)."""
    g = np.stack([sdf(p + e) - sdf(p - e) for e in np.eye(3) * h], -1)
    return g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-12)


def density(p: np.ndarray) -> np.ndarray:
    """sigma (extinction per box unit) at p [..., 3]: zero beyond SHELL outside every surface."""
    s = np.clip(0.5 - 0.5 * sdf(p) / SHELL, 0.0, 1.0)
    return DENSITY * s * s * (3.0 - 2.0 * s)


def _albedo(p: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """[5, ..., 3] albedo of each primitive at p (textures where MATERIALS says None)."""
    out = np.empty((len(PRIMITIVES), *p.shape[:-1], 3))
    for k, name in enumerate(PRIMITIVES):
        if MATERIALS[name][0] is not None:
            out[k] = MATERIALS[name][0]
    check = 0.5 + 0.5 * np.tanh(4.0 * np.sin(20.0 * math.pi * p[..., 0]) * np.sin(20.0 * math.pi * p[..., 2]))
    out[0] = np.array([0.62, 0.6, 0.55]) * check[..., None] + np.array([0.16, 0.2, 0.3]) * (1 - check[..., None])
    stripe = 0.5 + 0.5 * np.tanh(3.0 * np.sin(14.0 * phi))
    out[2] = np.array([0.75, 0.62, 0.12]) * stripe[..., None] + np.array([0.1, 0.22, 0.55]) * (1 - stripe[..., None])
    return out


def colour(p: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Linear RGB in [0, 1] at points p [..., 3] seen along unit directions d [..., 3] (docstring)."""
    dist, phi = primitives(p)
    w = np.exp(-(dist - dist.min(0)) / BLEND)
    w = w / w.sum(0)
    albedo = np.einsum("k...,k...c->...c", w, _albedo(p, phi))
    ks = np.einsum("k...,k->...", w, np.array([m[1] for m in MATERIALS.values()]))
    spec_colour = np.einsum("k...,kc->...c", w, np.array([m[2] for m in MATERIALS.values()]))
    shininess = np.einsum("k...,k->...", w, np.array([m[3] for m in MATERIALS.values()]))
    n = normal(p)
    n_l = n @ LIGHT
    h = LIGHT - d
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-12)
    s = np.clip(n_l / 0.15, 0.0, 1.0)
    spec = ks * np.maximum(np.sum(n * h, -1), 0.0) ** shininess * s * s * (3.0 - 2.0 * s)
    lit = albedo * (AMBIENT + (1.0 - AMBIENT) * np.maximum(n_l, 0.0))[..., None] + spec[..., None] * spec_colour
    return np.clip(lit, 0.0, 1.0)


# --- views -----------------------------------------------------------------------------------------

def orbit_camera(yaw: float, pitch: float, distance: float = 1.75, fov_y: float = 40.0) -> dict:
    return {"type": "orbit", "fov_y": fov_y, "target": list(TARGET), "distance": distance, "yaw": float(yaw),
            "pitch": float(pitch)}


def views(count: int, offset: float) -> list[dict]:
    """``count`` orbit cameras spread over the upper hemisphere (a Fibonacci spiral in the sine of
    the pitch, from 8 to 65 degrees down); ``offset`` in [0, 1) shifts the spiral, so sets with
    different offsets interleave (the held-out views lie between the training views)."""
    golden = math.pi * (3.0 - math.sqrt(5.0))
    lo, hi = math.sin(math.radians(8.0)), math.sin(math.radians(65.0))
    out = []
    for k in range(count):
        u = (k + offset) / count
        pitch = -math.degrees(math.asin(lo + (hi - lo) * u))
        yaw = math.degrees((k + offset) * golden) % 360.0
        out.append(orbit_camera(yaw, pitch))
    return out


# --- ground truth ----------------------------------------------------------------------------------

def render(camera: dict, width: int, height: int, march) -> np.ndarray:
    """[H, W, 3] float32 linear RGB (row 0 = top) of the scene at a camera (scene.json form) under the
    march settings ``march`` (radiance_field_render.MarchSettings): the march of
    radiance_field_march.py with the analytic field. Samples farther than SHELL outside every
    surface have zero density, and since the SDF is 1-Lipschitz every sample within sdf - SHELL of
    one is empty too: those are stepped over, which is the same sum."""
    import torch

    from inshade.models.sdf import camera_rays
    from inshade.scene.camera import camera_from_dict

    with torch.no_grad():
        ro, rd = camera_rays(camera_from_dict(camera).uniforms(width, height), width, height)
    ro, rd = ro.numpy().astype(np.float64), rd.numpy().astype(np.float64)
    ro = (ro - np.asarray(march.aabb_min)) / march.side
    t0, t1, hit = _unit_box(ro, rd)
    dt = march.step
    out = np.zeros((len(ro), 3))
    trans = np.ones(len(ro))
    index = np.zeros(len(ro), np.int64)
    live = np.flatnonzero(hit)
    while len(live):
        t = t0[live] + (index[live] + 0.5) * dt
        keep = (t < t1[live]) & (index[live] < march.max_steps)
        live, t = live[keep], t[keep]
        if not len(live):
            break
        x = ro[live] + rd[live] * t[:, None]
        s = sdf(x)
        far = s > SHELL
        index[live[far]] += np.maximum(1, np.floor((s[far] - SHELL) / dt).astype(np.int64))
        near = live[~far]
        if len(near):
            xn = x[~far]
            alpha = 1.0 - np.exp(-density(xn) * dt)
            out[near] += (trans[near] * alpha)[:, None] * colour(xn, rd[near])
            trans[near] *= 1.0 - alpha
            index[near] += 1
        live = live[trans[live] >= march.stop]
    rgb = out + trans[:, None] * np.asarray(march.background)
    return rgb.reshape(height, width, 3).astype(np.float32)


def _unit_box(ro, rd):
    d = np.where(np.abs(rd) < 1e-12, 1e-12, rd)
    a, c = (0.0 - ro) / d, (1.0 - ro) / d
    lo, hi = np.minimum(a, c), np.maximum(a, c)
    t0 = np.maximum(lo.max(-1), 0.0)
    t1 = hi.min(-1)
    return t0, t1, t1 >= t0
