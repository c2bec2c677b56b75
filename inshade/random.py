"""numpy twin of ``shaders/lib/random.glsl``: the same per-pixel random numbers, bit for bit.

A stochastic (accumulating) program draws one sample per pixel per frame, seeded by the pixel,
the sample index since the last reset (``u_sample_index``) and a stream number; tests and CPU
references use this module to know exactly which numbers the shader drew.
"""
from __future__ import annotations

import numpy as np

_U32 = np.uint32


def pcg(v) -> np.ndarray:
    """PCG-RXS-M-XS hash of uint32 ``v`` (array or scalar), as GLSL ``uint pcg(uint)``."""
    with np.errstate(over="ignore"):   # uint32 arithmetic wraps modulo 2**32, as GLSL's uint
        state = np.asarray(v, _U32) * _U32(747796405) + _U32(2891336453)
        word = ((state >> ((state >> _U32(28)) + _U32(4))) ^ state) * _U32(277803737)
        return (word >> _U32(22)) ^ word


def _u32(x) -> np.ndarray:
    """GLSL ``uint(int)``: two's complement wrap, so negative ints hash as they do in the shader."""
    return np.asarray(np.asarray(x, np.int64) & 0xFFFFFFFF, _U32)


def random_seed(pixel_x, pixel_y, sample_index, stream) -> np.ndarray:
    """GLSL ``random_seed(uvec2(pixel_x, pixel_y), sample_index, stream)`` (broadcasting)."""
    with np.errstate(over="ignore"):
        inner = pcg(_u32(sample_index) + pcg(_u32(stream)))
        return pcg(_u32(pixel_x) + pcg(_u32(pixel_y) + inner))


def random_unit(h) -> np.ndarray:
    """The top 24 bits of ``h`` as float32 in [0, 1), exactly as GLSL ``random_unit``."""
    return (np.asarray(h, _U32) >> _U32(8)).astype(np.float32) * np.float32(1.0 / 16777216.0)


def random_uniform(pixel_x, pixel_y, sample_index, stream, n: int = 1) -> np.ndarray:
    """``n`` (1..4) uniform float32 numbers per pixel, last axis (absent for n = 1): GLSL
    ``random_uniform`` (n = 1) and ``random_uniform2/3/4``. Pixel coordinates are integers
    (``ivec2(gl_FragCoord.xy)``)."""
    if n not in (1, 2, 3, 4):
        raise ValueError(f"n: must be 1..4, got {n!r}")
    h = pcg(random_seed(pixel_x, pixel_y, sample_index, stream))
    out = []
    for _ in range(n):
        out.append(random_unit(h))
        h = pcg(h)
    return out[0] if n == 1 else np.stack(out, -1)
