"""tiny-cuda-nn's encodings without parameters (encodings/identity.h, frequency.h,
spherical_harmonics.h, oneblob.h, triangle_wave.h, empty.h), each with the components computing it."""
from __future__ import annotations

import numpy as np

from ..registry import tcnn_encoding
from ..tcnn_json import Reader
from .base import Encoding, lanes_of


@tcnn_encoding("Identity")
class Identity(Encoding):
    """-> ``affine`` (nothing at all for scale 1, offset 0)."""
    otype = "Identity"
    fields = ("scale", "offset")

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)
        self.scale, self.offset = r.number("scale", 1.0), r.number("offset", 0.0)
        self.out = n_dims

    def lower(self, b, src, params, dtype):
        if self.scale == 1.0 and self.offset == 0.0:
            return self.with_padding(lanes_of(src, self.n_dims))
        n = self.n_dims
        node = b.node("affine", {}, [src], {"scale": np.full(n, self.scale), "offset": np.full(n, self.offset)},
                      self.where)
        return self.with_padding(lanes_of(node, n))


@tcnn_encoding("Frequency")
class Frequency(Encoding):
    """-> ``frequency``: inshade's lanes are sin blocks, then cos blocks, each [frequency][input];
    tiny-cuda-nn's are [input][frequency][sin, cos] (its cos is sin(t + pi/2))."""
    otype = "Frequency"
    fields = ("n_frequencies",)

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)
        self.n_frequencies = r.uint("n_frequencies", 12)
        self.out = n_dims * self.n_frequencies * 2

    def lower(self, b, src, params, dtype):
        d, f = self.n_dims, self.n_frequencies
        if f == 0:
            return self.with_padding([])
        node = b.node("frequency", {"n_freqs": f, "include_input": False}, [src], where=f"{self.where}.n_frequencies")
        return self.with_padding([(node, s * f * d + k * d + i) for i in range(d) for k in range(f) for s in (0, 1)])


@tcnn_encoding("SphericalHarmonics")
class SphericalHarmonics(Encoding):
    """-> ``affine`` (x * 2 - 1: [0, 1]^3 to [-1, 1]^3) -> ``spherical_harmonics``."""
    otype = "SphericalHarmonics"
    pad_first = True   # kernel_sh writes the padding lanes first
    fields = ("degree",)

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)
        self.degree = r.uint("degree", 4)
        if n_dims != 3:
            raise r.ctx.error(where, f"SphericalHarmonics encodes 3 input lanes (a direction), got {n_dims}")
        if not 1 <= self.degree <= 8:
            raise r.ctx.error(f"{where}.degree", f"{self.degree}: tiny-cuda-nn takes degrees 1..8")
        self.out = self.degree ** 2

    def lower(self, b, src, params, dtype):
        direction = b.node("affine", {}, [src], {"scale": np.full(3, 2.0), "offset": np.full(3, -1.0)}, self.where)
        node = b.node("spherical_harmonics", {"degree": self.degree}, [direction], where=f"{self.where}.degree")
        return self.with_padding(lanes_of(node, self.out))


@tcnn_encoding("TriangleWave")
class TriangleWave(Encoding):
    """-> ``select`` (each input once per frequency) -> ``affine`` (2^f x + f/2) -> ``triangle_wave``
    -> ``affine`` (1 - 2 t): |frac(x 2^(f-1) + f/4) - 1/2| * 4 - 1 = 1 - 2 tri(x 2^f + f/2), for
    tri(t) = 1 - |mod(t, 2) - 1|."""
    otype = "TriangleWave"
    fields = ("n_frequencies",)

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)
        self.n_frequencies = r.uint("n_frequencies", 12)
        self.out = n_dims * self.n_frequencies

    def lower(self, b, src, params, dtype):
        d, f = self.n_dims, self.n_frequencies
        if f == 0:
            return self.with_padding([])
        spread = b.node("select", {"lanes": [i for i in range(d) for _ in range(f)]}, [src], where=self.where)
        k = np.tile(np.arange(f, dtype=np.float64), d)
        phase = b.node("affine", {}, [spread], {"scale": 2.0 ** k, "offset": k / 2}, self.where)
        tri = b.node("triangle_wave", {"n_freqs": 1}, [phase], where=self.where)
        node = b.node("affine", {}, [tri], {"scale": np.full(d * f, -2.0), "offset": np.ones(d * f)}, self.where)
        return self.with_padding(lanes_of(node, self.out))


@tcnn_encoding("Empty")
class Empty(Encoding):
    otype = "Empty"

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)

    def lower(self, b, src, params, dtype):
        return self.with_padding([])
