"""The layered reference material of the neural appearance technique: one JSON description per
material (materials/*.json, format in materials/README.md) drives procedural parameter textures,
the GLSL reference (shaders/lib/na_reference.glsl, uniforms ``u_na_*``) and its torch twin
(reference.py). numpy only: the runtime and the technique record import this.

Parameter channels (``CHANNELS``, the single source of truth), three RGBA8 textures of four:

    param0 = (base_r, base_g, base_b, roughness)
    param1 = (anisotropy, direction, slope_x, slope_y)
    param2 = (metallic, coat_weight, coat_roughness, mask)

Texture values t in [0, 1] decode to physical parameters with the description's constants (no
per-material code): perceptual roughness r = lo + (hi - lo) t, alpha = max(r^2, ALPHA_MIN);
aspect = sqrt(1 - anisotropy_max t), (alpha_x, alpha_y) = (alpha / aspect, alpha aspect), both
>= ALPHA_MIN; direction phi = pi t (an axis, so [0, pi) covers every one); slope
s = (2 t - 1) slope_scale, normal = normalize(-s_x, -s_y, 1); coat roughness
r_c = min(lo + (hi - lo) t + smudge_coat_roughness mask, 1), alpha_c = max(r_c^2, ALPHA_MIN);
dust weight = dust_weight mask.

Filtering caveat: the direction channel is an angle, so box mips and bilinear filtering (GL's and
reference.sample_parameters alike) average it as a number; where neighbours straddle t = 0 / 1
(the same axis) the filtered axis is wrong. parameter_pyramid filters (cos 2phi, sin 2phi) instead.

Orientation: arrays are [v, u, channel] with row 0 = v = 0 (GL texture orientation, uv (0, 0) at
the bottom left); PNG files are stored top row first (row 0 = v = 1), as image viewers show them.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from inshade.files import atomic_files

CHANNELS = ("base_r", "base_g", "base_b", "roughness",
            "anisotropy", "direction", "slope_x", "slope_y",
            "metallic", "coat_weight", "coat_roughness", "mask")
TEXTURES = 3
TEXTURE_NAMES = tuple(f"param{i}" for i in range(TEXTURES))
ALPHA_MIN = 0.03           # smallest GGX alpha: keeps every lobe smooth enough to learn (GLSL NA_ALPHA_MIN)
MATERIALS_DIR = Path(__file__).resolve().parent / "materials"

# description constants: name -> (number of floats, lower bound, upper bound)
CONSTANTS = {
    "roughness_range": (2, 0.0, 1.0),
    "anisotropy_max": (1, 0.0, 0.95),      # aspect = sqrt(1 - anisotropy_max t) stays > 0.2
    "slope_scale": (1, 0.0, 2.0),          # |slope| <= 2 keeps the normal > 35 degrees off the tangent plane
    "coat_ior": (1, 1.0, 3.0),
    "coat_roughness_range": (2, 0.0, 1.0),
    "smudge_coat_roughness": (1, 0.0, 1.0),
    "dust_weight": (1, 0.0, 1.0),
    "dust_colour": (3, 0.0, 1.0),
}

# encoder inputs k(x) per texel (parameter_pyramid): the decoded physical parameters
ENCODER_LAYOUT = ("base_r", "base_g", "base_b", "alpha_x", "alpha_y", "cos_2phi", "sin_2phi",
                  "normal_x", "normal_y", "normal_z", "metallic", "coat_weight", "coat_alpha", "mask")
ENCODER_INPUTS = len(ENCODER_LAYOUT)


@dataclass
class Material:
    name: str
    constants: dict
    generators: dict          # channel name -> {"value", "wrap", "layers"}
    seed: int
    path: Path | None = field(default=None, compare=False)


# --- loading ---------------------------------------------------------------------------------

def _fail(where, field_name: str, message: str):
    raise ValueError(f"{where}: {field_name}: {message}")


def _number(where, field_name, value, lo=-math.inf, hi=math.inf, integer=False):
    ok = isinstance(value, int) if integer else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok or not (lo <= value <= hi) or value != value:
        kind = "an integer" if integer else "a number"
        _fail(where, field_name, f"expected {kind} in [{lo}, {hi}], got {value!r}")
    return value


# pattern name -> {parameter: (default or None if required, lo, hi, integer)}
PATTERNS = {
    "noise": {"scale": (None, 1, 256, True), "octaves": (1, 1, 8, True), "gain": (0.5, 0.0, 1.0, False)},
    "fingerprints": {"count": (None, 1, 64, True), "radius": (None, 0.01, 0.5, False),
                     "ridges": (None, 1, 100, False), "aspect": (0.7, 0.2, 1.0, False),
                     "softness": (0.3, 0.01, 1.0, False)},
    "scratches": {"count": (None, 1, 2000, True), "length": (None, 0.001, 1.0, False),
                  "width": (None, 0.0005, 0.1, False), "angle": (None, -10.0, 10.0, False),
                  "angle_spread": (math.pi, 0.0, math.pi, False)},
    "crackle": {"cells": (None, 1, 128, True), "width": (None, 0.001, 0.5, False),
                "jitter": (0.8, 0.0, 1.0, False)},
    "swirl": {"center": ([0.5, 0.5], None, None, False), "offset": (0.0, -10.0, 10.0, False),
              "twist": (0.0, -100.0, 100.0, False)},
}
LAYER_KEYS = {"pattern", "amplitude", "seed", "derivative"}


def _table(where, desc, key: str, expected: str, known, unknown: str) -> dict:
    """The object ``desc[key]``, whose keys must lie in ``known``: ``expected`` says what it must be,
    ``unknown`` what a key outside ``known`` is (``{known}``: their list)."""
    table = desc.get(key)
    if not isinstance(table, dict):
        _fail(where, key, f"expected {expected}, got {table!r}")
    extra = sorted(set(table) - set(known))
    if extra:
        _fail(where, f"{key}.{extra[0]}", unknown.format(known=", ".join(known)))
    return table


def _check_layer(where, fname, layer):
    if not isinstance(layer, dict):
        _fail(where, fname, f"expected an object, got {layer!r}")
    pattern = layer.get("pattern")
    if pattern not in PATTERNS:
        _fail(where, f"{fname}.pattern", f"unknown pattern {pattern!r} (known: {', '.join(PATTERNS)})")
    spec = PATTERNS[pattern]
    unknown = sorted(set(layer) - LAYER_KEYS - set(spec))
    if unknown:
        _fail(where, f"{fname}.{unknown[0]}", f"unknown field for pattern {pattern!r}")
    out = {"pattern": pattern,
           "amplitude": float(_number(where, f"{fname}.amplitude", layer.get("amplitude"), -100.0, 100.0)),
           "seed": _number(where, f"{fname}.seed", layer.get("seed", 0), 0, 2**31 - 1, integer=True),
           "derivative": layer.get("derivative")}
    if out["derivative"] not in (None, "x", "y"):
        _fail(where, f"{fname}.derivative", f"expected 'x' or 'y', got {out['derivative']!r}")
    for key, (default, lo, hi, integer) in spec.items():
        if key not in layer:
            if default is None:
                _fail(where, f"{fname}.{key}", f"missing (pattern {pattern!r} needs it)")
            out[key] = default
        elif key == "center":
            c = layer[key]
            if not (isinstance(c, list) and len(c) == 2):
                _fail(where, f"{fname}.{key}", f"expected [u, v], got {c!r}")
            out[key] = [float(_number(where, f"{fname}.{key}", x, 0.0, 1.0)) for x in c]
        else:
            out[key] = _number(where, f"{fname}.{key}", layer[key], lo, hi, integer)
    return out


def _parse(where, desc) -> Material:
    if not isinstance(desc, dict):
        _fail(where, "(top level)", "expected a JSON object")
    unknown = sorted(set(desc) - {"name", "seed", "constants", "generators", "description"})
    if unknown:
        _fail(where, unknown[0], "unknown field")
    name = desc.get("name")
    if not isinstance(name, str) or not name:
        _fail(where, "name", f"expected a non-empty string, got {name!r}")
    seed = _number(where, "seed", desc.get("seed"), 0, 2**31 - 1, integer=True)
    consts = _table(where, desc, "constants", "an object", CONSTANTS, "unknown constant (known: {known})")
    constants = {}
    for key, (n, lo, hi) in CONSTANTS.items():
        if key not in consts:
            _fail(where, f"constants.{key}", "missing")
        value = consts[key]
        if n == 1:
            constants[key] = float(_number(where, f"constants.{key}", value, lo, hi))
        else:
            if not isinstance(value, list) or len(value) != n:
                _fail(where, f"constants.{key}", f"expected a list of {n} numbers, got {value!r}")
            constants[key] = tuple(float(_number(where, f"constants.{key}", x, lo, hi)) for x in value)
    for key in ("roughness_range", "coat_roughness_range"):
        if constants[key][0] > constants[key][1]:
            _fail(where, f"constants.{key}", f"lower end above upper end: {list(constants[key])}")
    gens = _table(where, desc, "generators", "an object with one entry per channel", CHANNELS,
                  "unknown channel (channels: {known})")
    generators = {}
    for ch in CHANNELS:
        g = gens.get(ch)
        if not isinstance(g, dict):
            _fail(where, f"generators.{ch}", f"missing or not an object: {g!r}")
        bad = sorted(set(g) - {"value", "wrap", "layers"})
        if bad:
            _fail(where, f"generators.{ch}.{bad[0]}", "unknown field")
        layers = g.get("layers", [])
        if not isinstance(layers, list):
            _fail(where, f"generators.{ch}.layers", f"expected a list, got {layers!r}")
        wrap = g.get("wrap", False)
        if not isinstance(wrap, bool):
            _fail(where, f"generators.{ch}.wrap", f"expected true or false, got {wrap!r}")
        generators[ch] = {"value": float(_number(where, f"generators.{ch}.value", g.get("value"), 0.0, 1.0)),
                          "wrap": wrap,
                          "layers": [_check_layer(where, f"generators.{ch}.layers[{i}]", layer)
                                     for i, layer in enumerate(layers)]}
    return Material(name=name, constants=constants, generators=generators, seed=seed)


def load_material(name_or_path) -> Material:
    """A material by name (materials/<name>.json) or by the path of a description file."""
    text = str(name_or_path)
    path = Path(text) if (text.endswith(".json") or "/" in text or "\\" in text) else MATERIALS_DIR / f"{text}.json"
    if not path.is_file():
        known = ", ".join(sorted(p.stem for p in MATERIALS_DIR.glob("*.json")))
        raise ValueError(f"material {text!r}: no description at {path} (known materials: {known})")
    try:
        desc = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: not valid JSON: {e}") from None
    material = _parse(path, desc)
    material.path = path
    return material


def uniforms(material: Material) -> dict:
    """The description constants as the reference shader's uniforms (floats and tuples)."""
    return {f"u_na_{key}": value for key, value in material.constants.items()}


# --- procedural patterns (deterministic, tileable, defined in uv so any size shows the same material)

def _grid(size: int):
    c = (np.arange(size, dtype=np.float64) + 0.5) / size
    return np.meshgrid(c, c)           # u along columns, v along rows (row 0 = v = 0)


def _wrap(d):
    return d - np.round(d)


def _noise(rng, size, p):
    u, v = _grid(size)
    out, amp, norm = np.zeros((size, size)), 1.0, 0.0
    for o in range(p["octaves"]):
        n = p["scale"] * 2 ** o
        lattice = rng.uniform(-1.0, 1.0, (n, n))
        x, y = u * n, v * n
        i, j = np.floor(x).astype(int), np.floor(y).astype(int)
        fx, fy = x - i, y - j
        fx, fy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)
        i0, j0, i1, j1 = i % n, j % n, (i + 1) % n, (j + 1) % n
        top = lattice[j0, i0] * (1 - fx) + lattice[j0, i1] * fx
        bot = lattice[j1, i0] * (1 - fx) + lattice[j1, i1] * fx
        out += amp * (top * (1 - fy) + bot * fy)
        norm += amp
        amp *= p["gain"]
    return out / norm                                   # in [-1, 1]


def _fingerprints(rng, size, p):
    """Ridged concentric ellipses fading out at the print's edge, the max over prints: [0, 1]."""
    u, v = _grid(size)
    out = np.zeros((size, size))
    for _ in range(p["count"]):
        cx, cy, rot = rng.uniform(0, 1), rng.uniform(0, 1), rng.uniform(0, math.pi)
        radius = p["radius"] * rng.uniform(0.7, 1.3)
        du, dv = _wrap(u - cx), _wrap(v - cy)
        a = (du * math.cos(rot) + dv * math.sin(rot)) / radius
        b = (-du * math.sin(rot) + dv * math.cos(rot)) / (radius * p["aspect"])
        d = np.sqrt(a * a + b * b)
        ridges = 0.5 + 0.5 * np.cos(2 * math.pi * p["ridges"] * d + rng.uniform(0, 2 * math.pi))
        envelope = np.clip((1.0 - d) / p["softness"], 0.0, 1.0)
        envelope = envelope * envelope * (3 - 2 * envelope)
        out = np.maximum(out, ridges * envelope * rng.uniform(0.6, 1.0))
    return out


def _scratches(rng, size, p):
    """Thin straight grooves (a smooth profile across, 1 on the line): [0, 1]."""
    u, v = _grid(size)
    out = np.zeros((size, size))
    for _ in range(p["count"]):
        cx, cy = rng.uniform(0, 1), rng.uniform(0, 1)
        ang = p["angle"] + rng.uniform(-0.5, 0.5) * p["angle_spread"]
        half = 0.5 * p["length"] * rng.uniform(0.5, 1.0)
        dx, dy = math.cos(ang), math.sin(ang)
        du, dv = _wrap(u - cx), _wrap(v - cy)
        along = du * dx + dv * dy
        across = -du * dy + dv * dx
        w = p["width"] * rng.uniform(0.5, 1.0)
        prof = np.exp(-(across / w) ** 2) * np.clip((half - np.abs(along)) / (0.2 * half), 0.0, 1.0)
        out = np.maximum(out, prof * rng.uniform(0.5, 1.0))
    return out


def _crackle(rng, size, p):
    """Voronoi cell borders (F2 - F1 small): 1 on a crack, 0 inside a cell; tileable."""
    u, v = _grid(size)
    n = p["cells"]
    pts = (np.stack(np.meshgrid(np.arange(n), np.arange(n)), -1) + 0.5
           + p["jitter"] * rng.uniform(-0.5, 0.5, (n, n, 2)))
    x, y = u * n, v * n
    ci, cj = np.floor(x).astype(int), np.floor(y).astype(int)
    f1, f2 = np.full(x.shape, np.inf), np.full(x.shape, np.inf)
    for oj in (-1, 0, 1):
        for oi in (-1, 0, 1):
            i, j = ci + oi, cj + oj
            pt = pts[j % n, i % n]
            px = pt[..., 0] + (i - i % n)
            py = pt[..., 1] + (j - j % n)
            d = np.sqrt((px - x) ** 2 + (py - y) ** 2)
            f2 = np.where(d < f1, f1, np.minimum(f2, d))
            f1 = np.minimum(f1, d)
    edge = (f2 - f1) / n / p["width"]
    return np.exp(-edge * edge)


def _swirl(rng, size, p):
    """An axial direction angle / pi in [0, 1): tangential around a centre (offset pi/2 = circular
    brushing, 0 = radial), turning by `twist` radians per unit of radius (a spiral)."""
    u, v = _grid(size)
    du, dv = _wrap(u - p["center"][0]), _wrap(v - p["center"][1])
    ang = np.arctan2(dv, du) + p["offset"] + p["twist"] * np.sqrt(du * du + dv * dv)
    return np.mod(ang / math.pi, 1.0)


_GENERATORS = {"noise": _noise, "fingerprints": _fingerprints, "scratches": _scratches,
               "crackle": _crackle, "swirl": _swirl}


def _layer_field(material: Material, layer: dict, size: int) -> np.ndarray:
    rng = np.random.default_rng([material.seed, layer["seed"]])
    f = _GENERATORS[layer["pattern"]](rng, size, layer)
    if layer["derivative"] is not None:   # d/du or d/dv of the field (uv units), periodic
        axis = 1 if layer["derivative"] == "x" else 0
        f = (np.roll(f, -1, axis) - np.roll(f, 1, axis)) * (size / 2.0)
    return layer["amplitude"] * f


def quantize(values: np.ndarray) -> np.ndarray:
    """[0, 1] floats -> the k / 255 an RGBA8 texture stores (float32)."""
    k = np.round(np.clip(values, 0.0, 1.0) * 255.0).astype(np.float32)
    return k / np.float32(255.0)


def bake_parameters(material: Material, size: int = 512) -> np.ndarray:
    """[size, size, 12] float32 texture values (exactly k / 255), row 0 = v = 0."""
    if not (isinstance(size, int) and size >= 1 and size & (size - 1) == 0):
        raise ValueError(f"bake_parameters: size must be a power of two, got {size!r}")
    out = np.empty((size, size, len(CHANNELS)), np.float32)
    cache: dict = {}
    for c, ch in enumerate(CHANNELS):
        g = material.generators[ch]
        value = np.full((size, size), g["value"])
        for layer in g["layers"]:
            key = json.dumps(layer, sort_keys=True)
            if key not in cache:
                cache[key] = _layer_field(material, layer, size)
            value = value + cache[key]
        value = np.mod(value, 1.0) if g["wrap"] else value
        out[..., c] = quantize(value)
    return out


# --- files -----------------------------------------------------------------------------------

def write_textures(material: Material, size: int, folder) -> list[Path]:
    """param0.png .. param2.png (RGBA8, top row = v = 1), written together atomically."""
    from PIL import Image

    raw = bake_parameters(material, size)
    k = np.round(raw * 255.0).astype(np.uint8)[::-1]
    paths = [Path(folder) / f"{name}.png" for name in TEXTURE_NAMES]
    with atomic_files(*paths) as temps:
        temps = temps if isinstance(temps, list) else [temps]
        for i, tmp in enumerate(temps):
            Image.fromarray(np.ascontiguousarray(k[..., 4 * i:4 * i + 4]), "RGBA").save(tmp, format="PNG")
    return paths


def read_textures(folder) -> np.ndarray:
    """[size, size, 12] float32 (k / 255) from param0..2.png, row 0 = v = 0."""
    from PIL import Image

    planes = []
    for name in TEXTURE_NAMES:
        path = Path(folder) / f"{name}.png"
        if not path.is_file():
            raise ValueError(f"read_textures: {path} is missing")
        with Image.open(path) as im:
            if im.mode != "RGBA":
                raise ValueError(f"read_textures: {path} is {im.mode}, expected RGBA (8 bits per channel)")
            planes.append(np.asarray(im, np.uint8))
    shapes = {p.shape for p in planes}
    if len(shapes) != 1:
        raise ValueError(f"read_textures: {folder}: param textures differ in size {sorted(shapes)}")
    k = np.concatenate(planes, -1)[::-1]
    return np.ascontiguousarray(k.astype(np.float32) / np.float32(255.0))


# --- encoder inputs with LEAN prefiltering ---------------------------------------------------

def _moments(raw: np.ndarray, c: dict) -> np.ndarray:
    """Per-texel quantities that average linearly (LEAN, Olano & Baker 2010): base colour,
    alpha_x^2, alpha_y^2, (cos 2phi, sin 2phi), slopes s, second moments s s^T, metallic, coat
    weight, coat alpha^2, mask."""
    t = raw.astype(np.float64)
    lo, hi = c["roughness_range"]
    r = lo + (hi - lo) * t[..., 3]
    alpha = np.maximum(r * r, ALPHA_MIN)
    aspect = np.sqrt(1.0 - c["anisotropy_max"] * t[..., 4])
    ax, ay = np.maximum(alpha / aspect, ALPHA_MIN), np.maximum(alpha * aspect, ALPHA_MIN)
    phi = math.pi * t[..., 5]
    sx, sy = (2.0 * t[..., 6] - 1.0) * c["slope_scale"], (2.0 * t[..., 7] - 1.0) * c["slope_scale"]
    clo, chi = c["coat_roughness_range"]
    rc = np.minimum(clo + (chi - clo) * t[..., 10] + c["smudge_coat_roughness"] * t[..., 11], 1.0)
    ac = np.maximum(rc * rc, ALPHA_MIN)
    return np.stack([t[..., 0], t[..., 1], t[..., 2], ax * ax, ay * ay, np.cos(2 * phi), np.sin(2 * phi),
                     sx, sy, sx * sx, sx * sy, sy * sy, t[..., 8], t[..., 9], ac * ac, t[..., 11]], -1)


def _features(m: np.ndarray) -> np.ndarray:
    """Moments -> ENCODER_LAYOUT. The slope covariance (LEAN) widens the alphas along the
    anisotropy axes: alpha^2 += 2 var (GGX alpha^2 ~ 2 x Beckmann slope variance)."""
    mx, my = m[..., 7], m[..., 8]
    vxx, vxy, vyy = m[..., 9] - mx * mx, m[..., 10] - mx * my, m[..., 11] - my * my
    phi = 0.5 * np.arctan2(m[..., 6], m[..., 5])
    cp, sp = np.cos(phi), np.sin(phi)
    var_t = np.maximum(cp * cp * vxx + 2 * cp * sp * vxy + sp * sp * vyy, 0.0)
    var_b = np.maximum(sp * sp * vxx - 2 * cp * sp * vxy + cp * cp * vyy, 0.0)
    ax, ay = np.sqrt(m[..., 3] + 2.0 * var_t), np.sqrt(m[..., 4] + 2.0 * var_b)
    inv = 1.0 / np.sqrt(mx * mx + my * my + 1.0)
    return np.stack([m[..., 0], m[..., 1], m[..., 2], ax, ay, m[..., 5], m[..., 6],
                     -mx * inv, -my * inv, inv, m[..., 12], m[..., 13], np.sqrt(m[..., 14]), m[..., 15]],
                    -1).astype(np.float32)


def _box(a: np.ndarray) -> np.ndarray:
    h, w = a.shape[:2]
    return 0.25 * (a[0:h:2, 0:w:2] + a[1:h:2, 0:w:2] + a[0:h:2, 1:w:2] + a[1:h:2, 1:w:2])


def parameter_pyramid(raw: np.ndarray, levels: int, material: Material | dict) -> list[np.ndarray]:
    """Encoder inputs k(x) per level ([N / 2^l, N / 2^l, ENCODER_INPUTS] float32, ENCODER_LAYOUT):
    level 0 from the texels, coarser levels by 2x2 box filtering of LEAN moments (so a bumpy
    normal map becomes wider alphas). `material` (or its constants dict) gives the decoding."""
    consts = material.constants if isinstance(material, Material) else material
    raw = np.asarray(raw)
    if raw.ndim != 3 or raw.shape[2] != len(CHANNELS) or raw.shape[0] != raw.shape[1]:
        raise ValueError(f"parameter_pyramid: raw must be [N, N, {len(CHANNELS)}], got {raw.shape}")
    if not (1 <= levels and raw.shape[0] % (1 << (levels - 1)) == 0):
        raise ValueError(f"parameter_pyramid: levels={levels} does not fit size {raw.shape[0]}")
    m = _moments(raw, consts)
    out = [_features(m)]
    for _ in range(levels - 1):
        m = _box(m)
        out.append(_features(m))
    return out
