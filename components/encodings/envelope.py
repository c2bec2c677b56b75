"""Input encodings: NeRF's frequencies, triangle waves, spherical harmonics: the parity envelope's rules."""
from __future__ import annotations

import math

import numpy as np

from inshade.envelope_base import Site, mag, rule, sin_range


@rule("frequency")
def _frequency(s: Site):
    n, p, lo, hi = s.node, s.params, s.lo, s.hi
    nf, d = p["n_freqs"], n.in_dim
    parts_lo, parts_hi = ([lo], [hi]) if p["include_input"] else ([], [])
    for fn in ("sin", "cos"):
        for k in range(nf):
            a = (2.0 ** k) * math.pi
            alo, ahi = a * lo, a * hi
            if fn == "cos":   # cos(t) = sin(t + pi/2)
                alo, ahi = alo + math.pi / 2, ahi + math.pi / 2
            slo, shi = sin_range(alo, ahi)
            parts_lo.append(slo)
            parts_hi.append(shi)
    bound = (2.0 ** (nf - 1)) * math.pi * float(np.max(mag(lo, hi)))
    s.walk.periodic_args[n.id] = [(2.0 ** k) * math.pi * float(np.max(mag(lo, hi))) for k in range(nf)]
    s.periodic(f"frequency argument 2^{nf - 1} pi |x| (n_freqs {nf})", bound)
    olo, ohi = np.concatenate(parts_lo), np.concatenate(parts_hi)
    assert olo.size == n.out_dim == d * (2 * nf + int(p["include_input"]))
    return olo, ohi


@rule("triangle_wave")
def _triangle_wave(s: Site):   # of an input: exact (power-of-two scale, mod 2), so only computed ones
    nf = s.params["n_freqs"]
    bound = (2.0 ** (nf - 1)) * float(np.max(mag(s.lo, s.hi)))
    s.periodic(f"triangle_wave argument 2^{nf - 1} |x| (n_freqs {nf})", bound, check_input=False)
    return np.zeros(s.node.out_dim), np.ones(s.node.out_dim)


@rule("spherical_harmonics")
def _spherical_harmonics(s: Site):
    deg = s.params["degree"]
    # real orthonormal SH: sum_m Y_lm^2 = (2l+1)/4pi on the unit sphere, so |Y_lm| <= that root
    m = np.concatenate([np.full(2 * l + 1, math.sqrt((2 * l + 1) / (4 * math.pi))) for l in range(deg)])
    return -m, m
