"""The importance-sampling proxy's output activation (Real-Time Neural Appearance Models): the bundle-level spec."""
from __future__ import annotations

import numpy as np

from inshade.components.spec import ComponentSpec, Param, register


PROXY_PARAMS = ("w_d", "w_s", "mu_d.x", "mu_d.y", "alpha_x", "alpha_y", "rho", "mu_s.x", "mu_s.y")
register(ComponentSpec(
    "proxy_params",
    "importance-sampling proxy output activation: raw 9 lanes (3 when isotropic: 2 logits, alpha) "
    "-> [w_d, w_s, mu_d.x, mu_d.y, alpha_x, alpha_y, rho, mu_s.x, mu_s.y] (models/proxy_lobe.py)",
    {"isotropic": Param(bool, False),
     "alpha_min": Param(float, 0.01, lambda v: np.isfinite(v) and 0.0 < v <= 1.0)},
    out_dim=lambda p, d: len(PROXY_PARAMS),
    in_dim=lambda p, d: d == (3 if p["isotropic"] else 9),
))
