"""tiny-cuda-nn's OneBlob encoding: the parity envelope's rule."""
from __future__ import annotations

import numpy as np

from inshade.envelope_base import LOOKUP_GAIN, Site, rule


@rule("one_blob")
def _one_blob(s: Site):   # bin masses of a unit blob
    p = s.params
    gain = 15.0 / 16.0 * p["n_bins"]
    if not s.src_exact and gain > LOOKUP_GAIN:
        s.warn(f"one_blob gain 15/16 n_bins (n_bins {p['n_bins']}, input computed)", gain, LOOKUP_GAIN,
               "an upstream discrepancy is multiplied by the blob's slope: measured ~2.9e-7 * gain "
               "(1.6e-5 at n_bins 64 after a 64-input dense)")
    return np.zeros(s.node.out_dim), np.ones(s.node.out_dim)
