"""Real orthonormal spherical harmonics, bands l = 0..4, index l*l + l + m.

One table of monomial terms generates the numpy/torch evaluation and the GLSL code, so the
two cannot drift apart. Convention: Condon-Shortley phase included (as tiny-cuda-nn and
Sloan's "Stupid SH tricks"); the polynomials assume a unit direction.
"""
from __future__ import annotations

import numpy as np

# Each coefficient is a list of (constant, (power of x, power of y, power of z)).
_A = 0.59004358992664352
_B = 0.45704579946446572
_C = 1.7701307697799304
_D = 0.94617469575756008
_E = 0.66904654355728921
_F = 0.47308734787878004
SH_TERMS: list[list[tuple[float, tuple[int, int, int]]]] = [
    [(0.28209479177387814, (0, 0, 0))],
    [(-0.48860251190291987, (0, 1, 0))],
    [(0.48860251190291987, (0, 0, 1))],
    [(-0.48860251190291987, (1, 0, 0))],
    [(1.0925484305920792, (1, 1, 0))],
    [(-1.0925484305920792, (0, 1, 1))],
    [(0.94617469575755997, (0, 0, 2)), (-0.31539156525251999, (0, 0, 0))],
    [(-1.0925484305920792, (1, 0, 1))],
    [(0.54627421529603959, (2, 0, 0)), (-0.54627421529603959, (0, 2, 0))],
    [(-3 * _A, (2, 1, 0)), (_A, (0, 3, 0))],
    [(2.8906114426405538, (1, 1, 1))],
    [(_B, (0, 1, 0)), (-5 * _B, (0, 1, 2))],
    [(5 * 0.3731763325901154, (0, 0, 3)), (-3 * 0.3731763325901154, (0, 0, 1))],
    [(_B, (1, 0, 0)), (-5 * _B, (1, 0, 2))],
    [(1.4453057213202769, (2, 0, 1)), (-1.4453057213202769, (0, 2, 1))],
    [(-_A, (3, 0, 0)), (3 * _A, (1, 2, 0))],
    [(2.5033429417967046, (3, 1, 0)), (-2.5033429417967046, (1, 3, 0))],
    [(-3 * _C, (2, 1, 1)), (_C, (0, 3, 1))],
    [(7 * _D, (1, 1, 2)), (-_D, (1, 1, 0))],
    [(3 * _E, (0, 1, 1)), (-7 * _E, (0, 1, 3))],
    [(0.31735664074561293, (0, 0, 0)), (-3.1735664074561294, (0, 0, 2)), (3.7024941420321507, (0, 0, 4))],
    [(3 * _E, (1, 0, 1)), (-7 * _E, (1, 0, 3))],
    [(7 * _F, (2, 0, 2)), (-_F, (2, 0, 0)), (-7 * _F, (0, 2, 2)), (_F, (0, 2, 0))],
    [(-_C, (3, 0, 1)), (3 * _C, (1, 2, 1))],
    [(-3.7550144126950569, (2, 2, 0)), (0.62583573544917614, (4, 0, 0)), (0.62583573544917614, (0, 4, 0))],
]


def monomials(degree: int) -> list[tuple[int, int, int]]:
    """The distinct monomials the first degree**2 basis functions use, in a stable order."""
    return sorted({pw for terms in SH_TERMS[: degree * degree] for _, pw in terms})


def sh_basis(dirs, degree: int, xp=np):
    """Evaluates the basis at directions [..., 3] with numpy or torch (`xp`)."""
    x, y, z = dirs[..., 0], dirs[..., 1], dirs[..., 2]
    cols = []
    for terms in SH_TERMS[: degree * degree]:
        acc = 0.0
        for c, (a, b, e) in terms:
            acc = acc + c * (x ** a) * (y ** b) * (z ** e)
        cols.append(acc + 0.0 * x)
    return xp.stack(cols, -1)


# =============================================================================================
# Toolkit: quadrature, projection, environments, rotation, triple product, zonal convolution.
# Numpy throughout (the runtime is torch-free); functions that take `xp` also accept torch.
#
# "degree" follows `sh_basis`: the number of bands, i.e. degree**2 coefficients, bands
# l = 0 .. degree-1. Degree 4 (l <= 3, 16 coefficients) is the PRT default; degree 5 (l <= 4,
# 25 coefficients) is the largest SH_TERMS supports.
# =============================================================================================

import functools
import math

MAX_DEGREE = int(round(math.sqrt(len(SH_TERMS))))  # 5: bands l = 0..4


def _check_degree(degree: int) -> int:
    if not (isinstance(degree, (int, np.integer)) and 1 <= degree <= MAX_DEGREE):
        raise ValueError(f"SH degree must be an int in 1..{MAX_DEGREE} (bands l < degree), got {degree!r}")
    return int(degree)


def band_of(degree: int) -> np.ndarray:
    """The band l of every coefficient index (l*l + l + m) of a degree-`degree` vector."""
    return np.concatenate([np.full(2 * l + 1, l) for l in range(_check_degree(degree))])


# --- quadrature -------------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def _sphere_quadrature(n: int) -> tuple[np.ndarray, np.ndarray]:
    t, wt = np.polynomial.legendre.leggauss(n)            # cos(theta) nodes on [-1, 1]
    phi = (np.arange(2 * n) + 0.5) * (math.pi / n)         # 2n equispaced azimuths
    st = np.sqrt(1.0 - t * t)
    dirs = np.stack([st[:, None] * np.cos(phi)[None, :], np.broadcast_to(t[:, None], (n, 2 * n)),
                     st[:, None] * np.sin(phi)[None, :]], -1).reshape(-1, 3)
    w = np.broadcast_to(wt[:, None] * (math.pi / n), (n, 2 * n)).reshape(-1)
    dirs.setflags(write=False)
    w = np.ascontiguousarray(w)
    w.setflags(write=False)
    return dirs, w


def sphere_quadrature(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre in cos(theta) (n nodes, theta from +y) x 2n equispaced azimuths.

    Returns (dirs [2n*n, 3] unit vectors, weights [2n*n], summing to 4 pi). Exact for every
    polynomial in (x, y, z) of total degree <= 2n - 1, so products of SH bands are integrated
    to rounding error: two bands up to l = 4 need n >= 5, three (triple product) n >= 7.
    """
    if n < 1:
        raise ValueError(f"quadrature order must be >= 1, got {n}")
    return _sphere_quadrature(int(n))


def project_function(f, degree: int, n: int = 32) -> np.ndarray:
    """SH coefficients of f by quadrature: c_i = integral f(w) Y_i(w) dw.

    `f` maps unit directions [N, 3] to values [N] or [N, C]; the result is [degree**2] or
    [degree**2, C]. Exact (to rounding) for band-limited f of polynomial degree <= 2n-1-l.
    """
    degree = _check_degree(degree)
    dirs, w = sphere_quadrature(n)
    values = np.asarray(f(dirs), np.float64)
    if values.shape[0] != dirs.shape[0]:
        raise ValueError(f"f must return one value (row) per direction: got shape {values.shape}")
    y = sh_basis(dirs, degree) * w[:, None]                 # [N, K]
    return y.T @ values


def sh_evaluate(coeffs, dirs, xp=np):
    """Reconstruction sum_i c_i Y_i(d): coeffs [K] or [K, C], dirs [..., 3] -> [...] or [..., C]."""
    k = coeffs.shape[0]
    degree = int(round(math.sqrt(k)))
    if degree * degree != k:
        raise ValueError(f"{k} is not a square number of SH coefficients")
    y = sh_basis(dirs, degree, xp)
    return y @ coeffs


# --- equirectangular environments -------------------------------------------------------------
#
# DIRECTION CONVENTION (right-handed, y up, the camera's forward is -z; DESIGN.md):
# an equirectangular image [H, W, 3] has row 0 at the top. The texel centre (row i, column j)
# has  u = (j + 0.5) / W,  v = (i + 0.5) / H,  polar angle theta = pi * v from +y (row 0 looks
# up, the last row down) and azimuth phi = 2 pi (u - 0.5), with direction
#
#     d = (sin(theta) sin(phi),  cos(theta),  -sin(theta) cos(phi))
#
# so the image centre (u = 0.5) is -z (what the default camera sees), u = 0.75 is +x (to its
# right), u = 0.25 is -x and the left/right edges are +z (behind the camera).

def equirect_directions(width: int, height: int) -> np.ndarray:
    """Unit directions [H, W, 3] of the texel centres of an equirectangular image."""
    theta = (np.arange(height) + 0.5) * (math.pi / height)
    phi = ((np.arange(width) + 0.5) / width - 0.5) * (2.0 * math.pi)
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    return np.stack([st * np.sin(phi)[None, :], np.broadcast_to(ct, (height, width)),
                     -st * np.cos(phi)[None, :]], -1)


def direction_to_equirect(dirs: np.ndarray) -> np.ndarray:
    """Inverse of the convention above: unit directions [..., 3] -> (u, v) [..., 2] in [0, 1]."""
    dirs = np.asarray(dirs, np.float64)
    theta = np.arccos(np.clip(dirs[..., 1], -1.0, 1.0))
    phi = np.arctan2(dirs[..., 0], -dirs[..., 2])
    return np.stack([phi / (2.0 * math.pi) + 0.5, theta / math.pi], -1)


def equirect_solid_angles(width: int, height: int) -> np.ndarray:
    """Solid angle [H, W] of every texel: the exact band integral dphi * (cos t0 - cos t1),
    i.e. sin(theta) dtheta dphi integrated over the texel rather than sampled at its centre
    (the two differ by O(dtheta^2) relatively); the total is exactly 4 pi."""
    edges = np.cos(np.arange(height + 1) * (math.pi / height))
    band = (edges[:-1] - edges[1:]) * (2.0 * math.pi / width)
    return np.broadcast_to(band[:, None], (height, width))


def check_environment(env, what: str = "environment") -> np.ndarray:
    env = np.asarray(env)
    if env.ndim != 3 or env.shape[2] not in (3, 4):
        raise ValueError(f"{what}: expected an equirectangular [H, W, 3] RGB image, got shape {list(env.shape)}")
    h, w = env.shape[:2]
    if h < 2 or w != 2 * h:
        raise ValueError(f"{what}: an equirectangular map must be twice as wide as tall (W = 2H), "
                         f"got {w}x{h} (W x H)")
    env = env[..., :3].astype(np.float64)
    bad = ~np.isfinite(env)
    if bad.any():
        r, c, _ = np.argwhere(bad)[0]
        raise ValueError(f"{what}: {int(bad.sum())} non-finite values (NaN/inf), first at row {r}, column {c}")
    if (env < 0).any():
        raise ValueError(f"{what}: negative radiance ({float(env.min()):.3g}); expected linear HDR >= 0")
    return env


def project_environment(env, degree: int = 4) -> np.ndarray:
    """SH coefficients [degree**2, 3] of a linear HDR equirectangular map [H, W, 3] (the
    convention above), summing radiance * Y_i * texel solid angle. Alpha is ignored."""
    degree = _check_degree(degree)
    env = check_environment(env)
    h, w = env.shape[:2]
    y = sh_basis(equirect_directions(w, h), degree)                    # [H, W, K]
    y = y * equirect_solid_angles(w, h)[..., None]
    return np.einsum("hwk,hwc->kc", y, env)


def sh_to_equirect(coeffs, width: int, height: int) -> np.ndarray:
    """Renders SH coefficients [K, C] back to an equirectangular [H, W, C] image."""
    return sh_evaluate(np.asarray(coeffs, np.float64), equirect_directions(width, height))


# --- procedural skies (data, not code paths) --------------------------------------------------
#
# Every preset is the same analytic model: a vertical gradient (horizon -> zenith as
# max(y, 0)**gradient above the horizon, horizon -> ground over `ground_blend` below it) plus
# spherical-Gaussian lobes colour * exp(sharpness * (cos(angle to lobe) - 1)), the lobe
# directions given as (elevation, azimuth) in degrees, azimuth 0 = -z, 90 = +x. Linear radiance.

SKY_PRESETS: dict[str, dict] = {
    "sunset": dict(zenith=(0.10, 0.16, 0.42), horizon=(1.30, 0.62, 0.30), ground=(0.10, 0.07, 0.05),
                   gradient=0.45, ground_blend=0.25,
                   lobes=[((4.0, 60.0), (18.0, 8.0, 2.5), 900.0),      # low sun
                          ((8.0, 60.0), (1.2, 0.45, 0.15), 6.0)]),      # glow around it
    "overcast": dict(zenith=(0.95, 0.97, 1.00), horizon=(0.45, 0.46, 0.48), ground=(0.16, 0.15, 0.14),
                     gradient=1.0, ground_blend=0.6, lobes=[]),
    "noon": dict(zenith=(0.15, 0.32, 0.85), horizon=(0.65, 0.78, 0.95), ground=(0.22, 0.19, 0.15),
                 gradient=0.6, ground_blend=0.3,
                 lobes=[((65.0, -30.0), (60.0, 57.0, 50.0), 3000.0)]),
    # a grey room lit by soft panels above and around, no colour cast: the first look of a glTF file, as
    # viewers show one (a neutral studio environment); its level lights a diffuse surface as three.js's
    # RoomEnvironment does (tests/web/test_three_peer.py: the same mean brightness within a few percent)
    "neutral": dict(zenith=(1.5, 1.5, 1.5), horizon=(1.1, 1.1, 1.1), ground=(0.6, 0.6, 0.6),
                    gradient=1.0, ground_blend=0.5,
                    lobes=[((75.0, 0.0), (3.2, 3.2, 3.2), 6.0),        # ceiling panels
                           ((15.0, -60.0), (1.6, 1.6, 1.6), 8.0),      # wall panels
                           ((15.0, 120.0), (1.6, 1.6, 1.6), 8.0)]),
    "studio": dict(zenith=(0.05, 0.05, 0.05), horizon=(0.02, 0.02, 0.02), ground=(0.01, 0.01, 0.01),
                   gradient=1.0, ground_blend=0.5,
                   lobes=[((35.0, -45.0), (4.0, 3.9, 3.7), 40.0),      # key softbox
                          ((15.0, 60.0), (1.2, 1.3, 1.5), 25.0),       # fill
                          ((25.0, 170.0), (2.5, 2.5, 2.5), 60.0)]),    # rim
}


def _lobe_direction(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(e) * math.sin(a), math.sin(e), -math.cos(e) * math.cos(a)])


def sky_radiance(name: str, dirs) -> np.ndarray:
    """Linear RGB radiance [..., 3] of preset `name` at unit directions [..., 3]."""
    if name not in SKY_PRESETS:
        raise ValueError(f"unknown sky preset {name!r}; known: {', '.join(SKY_PRESETS)}")
    p = SKY_PRESETS[name]
    dirs = np.asarray(dirs, np.float64)
    y = dirs[..., 1:2]
    zen, hor, gnd = (np.asarray(p[k], np.float64) for k in ("zenith", "horizon", "ground"))
    up = np.maximum(y, 0.0) ** p["gradient"]
    down = np.clip(-y / p["ground_blend"], 0.0, 1.0)
    down = down * down * (3.0 - 2.0 * down)                          # smoothstep
    out = np.where(y >= 0, hor + (zen - hor) * up, hor + (gnd - hor) * down)
    for (elev, azim), colour, sharpness in p["lobes"]:
        c = dirs @ _lobe_direction(elev, azim)
        out = out + np.asarray(colour) * np.exp(sharpness * (c - 1.0))[..., None]
    return out


def procedural_sky(name: str, width: int = 256, height: int | None = None) -> np.ndarray:
    """An equirectangular float32 [H, W, 3] linear HDR environment from `SKY_PRESETS`
    (height defaults to width // 2; the map follows the direction convention above)."""
    height = width // 2 if height is None else height
    return sky_radiance(name, equirect_directions(width, height)).astype(np.float32)


# --- rotation ---------------------------------------------------------------------------------

def sh_rotation(rotation, degree: int = 4) -> np.ndarray:
    """The [K, K] block-diagonal matrix D with  coeffs(f o R^T) = D @ coeffs(f), i.e. the
    coefficients of f rotated by the 3x3 rotation R (g(w) = f(R^T w)). D(A) D(B) = D(AB) and
    each band block is orthogonal.

    Computed as D_ij = integral Y_i(w) Y_j(R^T w) dw by Gauss quadrature, which is exact for
    these degree <= 8 polynomials (error ~1e-15), per band (a block for every l)."""
    degree = _check_degree(degree)
    r = np.asarray(rotation, np.float64)
    if r.shape != (3, 3) or not np.allclose(r @ r.T, np.eye(3), atol=1e-6) or np.linalg.det(r) < 0:
        raise ValueError(f"expected a 3x3 proper rotation matrix, got {r.tolist()}")
    dirs, w = sphere_quadrature(degree + 1)
    y = sh_basis(dirs, degree)                                        # Y_i(w)
    yr = sh_basis(dirs @ r, degree)                                   # Y_j(R^T w): row w -> R^T w
    d = (y * w[:, None]).T @ yr
    mask = band_of(degree)[:, None] == band_of(degree)[None, :]
    return np.where(mask, d, 0.0)


def rotate_sh(coeffs, rotation) -> np.ndarray:
    """Coefficients [K] or [K, C] of the function rotated by R (see `sh_rotation`)."""
    coeffs = np.asarray(coeffs, np.float64)
    degree = int(round(math.sqrt(coeffs.shape[0])))
    return sh_rotation(rotation, degree) @ coeffs


def rotation_matrix(axis, angle: float) -> np.ndarray:
    """Right-handed rotation by `angle` radians about `axis` (Rodrigues)."""
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


# --- triple product ---------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def _triple_product(degree: int) -> np.ndarray:
    dirs, w = sphere_quadrature(3 * degree)      # exact for degree 3(degree-1) <= 2n-1
    y = sh_basis(dirs, degree)
    t = np.einsum("n,ni,nj,nk->ijk", w, y, y, y)
    idx = np.sort(np.indices(t.shape).reshape(3, -1), axis=0)  # exactly symmetric: every
    t = t[idx[0], idx[1], idx[2]].reshape(t.shape)             # permutation reads t[i<=j<=k]
    t[np.abs(t) < 1e-12] = 0.0                   # exact zeros (selection rules), not rounding
    t.setflags(write=False)
    return t


def triple_product_tensor(degree: int = 4) -> np.ndarray:
    """Gaunt tensor T[i, j, k] = integral Y_i Y_j Y_k dw, [K, K, K], fully symmetric and sparse;
    T[0, i, j] = delta_ij / sqrt(4 pi). Computed once per degree by exact Gauss quadrature and
    cached (read-only)."""
    return _triple_product(_check_degree(degree))


def sh_product_matrix(a, degree: int | None = None) -> np.ndarray:
    """M[k, j] = sum_i a_i T[i, j, k]: the projection of (f_a * g) is M @ coeffs(g) — the
    "light matrix" of a lighting a. `a` is [K]; a [K, C] input gives [C, K, K]."""
    a = np.asarray(a, np.float64)
    degree = int(round(math.sqrt(a.shape[0]))) if degree is None else degree
    t = triple_product_tensor(degree)
    if a.ndim == 1:
        return np.einsum("i,ijk->kj", a, t)
    return np.einsum("ic,ijk->ckj", a, t)


def sh_product(a, b) -> np.ndarray:
    """Projection of the product of two SH functions (same degree): c_k = sum a_i b_j T_ijk."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    degree = int(round(math.sqrt(a.shape[0])))
    return np.einsum("i,j,ijk->k", a, b, triple_product_tensor(degree)) if a.ndim == 1 else \
        np.einsum("ic,jc,ijk->kc", a, b, triple_product_tensor(degree))


# --- zonal convolution ------------------------------------------------------------------------
#
# Convolving a function with a rotationally symmetric kernel h(cos angle) multiplies band l by
#     Lambda_l = 2 pi * integral_{-1}^{1} h(t) P_l(t) dt  ( = sqrt(4 pi / (2l+1)) h_l0 ),
# (Funk-Hecke). For h(t) = t^s on the upper hemisphere the moments M_l = int_0^1 t^s P_l(t) dt
# satisfy M_0 = 1/(s+1), M_1 = 1/(s+2), M_l = (s - l + 2) / (s + l + 1) M_{l-2}.

def _hemisphere_moments(s: float, degree: int) -> np.ndarray:
    m = np.zeros(degree)
    for l in range(degree):
        m[l] = 1.0 / (s + 1.0 + l) if l < 2 else (s - l + 2.0) / (s + l + 1.0) * m[l - 2]
    return m


def lambert_bands(degree: int = 4) -> np.ndarray:
    """Per-band factors A_l [degree] that turn radiance SH into irradiance SH (clamped cosine,
    not divided by pi): A_0 = pi, A_1 = 2pi/3, A_2 = pi/4, A_3 = 0, A_4 = -pi/24. Closed form
    (Ramamoorthi & Hanrahan 2001): A_1 = 2pi/3, odd l > 1: 0, even l:
    2pi (-1)^(l/2-1) / ((l+2)(l-1)) * l! / (2^l ((l/2)!)^2)."""
    degree = _check_degree(degree)
    out = np.zeros(degree)
    for l in range(degree):
        if l == 1:
            out[l] = 2.0 * math.pi / 3.0
        elif l % 2 == 0:
            out[l] = (2.0 * math.pi * (-1.0) ** (l // 2 - 1) / ((l + 2) * (l - 1))
                      * math.factorial(l) / (2.0 ** l * math.factorial(l // 2) ** 2))
    return out


def background_bands(degree: int = 4) -> np.ndarray:
    """Per-band factors [degree] of the environment as a background is shown: a Hann window
    w_l = (1 + cos(pi l / degree)) / 2. The truncated series rings (the studio preset at degree 4
    goes negative over ~30% of the sphere, shown black where clamped); the window keeps it smooth and
    almost non-negative. Lighting uses the coefficients as they are."""
    degree = _check_degree(degree)
    return 0.5 * (1.0 + np.cos(np.pi * np.arange(degree) / degree))


def phong_bands(exponent: float, degree: int = 4) -> np.ndarray:
    """Per-band factors [degree] of the normalised Phong lobe (s+1)/(2pi) max(cos a, 0)^s
    (integrates to 1, so band 0 is 1): Lambda_l = (s + 1) M_l(s). s = 1 gives lambert_bands/pi.
    For large s, Lambda_l ~ exp(-l^2 / (2s))."""
    degree = _check_degree(degree)
    if not exponent >= 0:
        raise ValueError(f"Phong exponent must be >= 0, got {exponent}")
    return (exponent + 1.0) * _hemisphere_moments(float(exponent), degree)


def zonal_bands(h, degree: int = 4, n: int = 256) -> np.ndarray:
    """Per-band factors of any zonal kernel h(cos angle) (vectorised), by Gauss-Legendre
    quadrature of Funk-Hecke; for kernels without a closed form (e.g. a fitted GGX lobe)."""
    degree = _check_degree(degree)
    t, w = np.polynomial.legendre.leggauss(n)
    ht = np.asarray(h(t), np.float64)
    return np.array([2.0 * math.pi * np.sum(w * ht * np.polynomial.legendre.Legendre.basis(l)(t))
                     for l in range(degree)])


def convolve_zonal(coeffs, bands) -> np.ndarray:
    """Applies per-band factors [degree] to coefficients [K] or [K, C]."""
    coeffs = np.asarray(coeffs, np.float64)
    bands = np.asarray(bands, np.float64)
    scale = bands[band_of(len(bands))]
    return coeffs * (scale if coeffs.ndim == 1 else scale[:, None])


def sh_irradiance(coeffs, normals, xp=np):
    """Irradiance E(n) = sum_lm A_l L_lm Y_lm(n) (not divided by pi) from radiance coefficients
    [K, C] at normals [..., 3] -> [..., C]; the GLSL twin is `sh_irradiance` in
    shaders/lib/spherical_harmonics.glsl."""
    k = coeffs.shape[0]
    degree = int(round(math.sqrt(k)))
    scale = lambert_bands(degree)[band_of(degree)]
    if xp is not np:
        scale = xp.as_tensor(scale, dtype=coeffs.dtype)
        return sh_basis(normals, degree, xp) @ (coeffs * scale[:, None])
    return sh_basis(normals, degree) @ (np.asarray(coeffs) * scale[:, None])
