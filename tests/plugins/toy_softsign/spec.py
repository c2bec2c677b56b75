"""toy_softsign: the bundle-level spec."""
from __future__ import annotations

from inshade.components.spec import ComponentSpec, Param, finite, register, same_width

register(ComponentSpec(
    "toy_softsign", "y = x / (scale + |x|), per lane",
    {"scale": Param(float, 1.0, lambda v: finite(v) and v > 0, "finite and > 0")},
    out_dim=same_width))
