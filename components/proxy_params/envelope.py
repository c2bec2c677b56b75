"""The importance-sampling proxy's output activation: the parity envelope's rule."""
from __future__ import annotations

import numpy as np

from inshade.envelope_base import Site, rule


@rule("proxy_params")
def _proxy_params(s: Site):
    """Output bounds of proxy_params (models/proxy_lobe.py): w in [0, 1], alpha in [alpha_min, 1],
    rho in [-0.99, 0.99], slopes mu = x (1 + |x| / 4) (monotone) of raw lanes 2, 3, 7, 8."""
    p, lo, hi = s.params, s.lo, s.hi
    olo = np.array([0.0, 0.0, 0.0, 0.0, p["alpha_min"], p["alpha_min"], -0.99, 0.0, 0.0])
    ohi = np.array([1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.99, 0.0, 0.0])
    if p["isotropic"]:
        ohi[6] = olo[6] = 0.0
    else:
        mu = lambda x: x * (1 + np.abs(x) / 4)  # noqa: E731
        for i in (2, 3, 7, 8):
            olo[i], ohi[i] = mu(lo[i]), mu(hi[i])
    return olo, ohi
