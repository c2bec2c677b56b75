"""toy_softsign: the parity envelope's rule (increasing, so the ends of the input interval bound it)."""
from __future__ import annotations

from inshade.envelope_base import Site, rule


@rule("toy_softsign")
def _toy_softsign(s: Site):
    scale = s.params["scale"]
    return s.lo / (scale + abs(s.lo)), s.hi / (scale + abs(s.hi))
