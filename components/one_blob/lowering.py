"""tiny-cuda-nn's OneBlob encoding: what its otype becomes (inshade convert of a tiny-cuda-nn
config or instant-ngp snapshot)."""
from __future__ import annotations

from inshade.convert.registry import tcnn_encoding
from inshade.convert.tcnn_encodings.base import Encoding, lanes_of
from inshade.convert.tcnn_json import Reader


@tcnn_encoding("OneBlob")
class OneBlob(Encoding):
    """-> ``one_blob``."""
    otype = "OneBlob"
    fields = ("n_bins",)

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)
        self.n_bins = r.uint("n_bins", 16)
        if self.n_bins < 1 or self.n_bins & (self.n_bins - 1):
            raise r.ctx.error(f"{where}.n_bins", f"{self.n_bins}: tiny-cuda-nn needs a power of two")
        self.out = n_dims * self.n_bins

    def lower(self, b, src, params, dtype):
        node = b.node("one_blob", {"n_bins": self.n_bins}, [src], where=self.where)
        return self.with_padding(lanes_of(node, self.out))
