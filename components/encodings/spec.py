"""Input encodings: NeRF's frequencies, triangle waves, spherical harmonics: the bundle-level spec."""
from __future__ import annotations

from inshade.components.spec import ComponentSpec, Param, pos_int, register


MAX_FREQS = 16
SH_MAX_DEGREE = 5         # bands l = 0..4, i.e. "up to order 4"

register(ComponentSpec(
    "frequency", "NeRF positional encoding: [x] + [sin(2^k pi x), cos(2^k pi x)] for k < n_freqs",
    {"n_freqs": Param(int, check=pos_int(MAX_FREQS)), "include_input": Param(bool, True)},
    out_dim=lambda p, d: d * (2 * p["n_freqs"] + (1 if p["include_input"] else 0)),
    category="encoding",
))
register(ComponentSpec(
    "triangle_wave", "tri(2^k x) for k < n_freqs, tri(t) = 1 - |mod(t, 2) - 1|",
    {"n_freqs": Param(int, check=pos_int(MAX_FREQS))},
    out_dim=lambda p, d: d * p["n_freqs"],
    category="encoding",
))
register(ComponentSpec(
    "spherical_harmonics", "real orthonormal SH basis of a unit direction, bands l < degree",
    {"degree": Param(int, check=pos_int(SH_MAX_DEGREE))},
    out_dim=lambda p, d: p["degree"] ** 2,
    in_dim=lambda p, d: d == 3,
    category="encoding",
))
