"""tiny-cuda-nn's OneBlob encoding: the bundle-level spec."""
from __future__ import annotations

from inshade.components.spec import MAX_WIDTH, ComponentError, ComponentSpec, Param, pos_int, register


ONE_BLOB_MAX_BINS = 1024


def _one_blob_width(p, d):
    if d * p["n_bins"] > MAX_WIDTH:
        raise ComponentError(f"n_bins: {d} inputs x {p['n_bins']} bins = {d * p['n_bins']} lanes, more than {MAX_WIDTH}")


register(ComponentSpec(
    "one_blob", "tiny-cuda-nn's OneBlob (encodings/oneblob.h, kernel_one_blob_soa): per input x and bin "
                "k < n_bins, the mass of a quartic kernel of radius 1/n_bins centred at x (wrapped with "
                "period 1) that falls in [k, k+1) / n_bins; lanes input-major (x_i's bins at i*n_bins..); "
                "components/one_blob/torch_twin.py has the exact rule",
    {"n_bins": Param(int, 16, lambda v: pos_int(ONE_BLOB_MAX_BINS)(v) and v & (v - 1) == 0,
                     doc=f"a power of two, 1..{ONE_BLOB_MAX_BINS}")},
    out_dim=lambda p, d: d * p["n_bins"],
    extra_checks=_one_blob_width,
    category="encoding",
))
