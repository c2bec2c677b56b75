"""tiny-cuda-nn's Encoding<T> as inshade reads it: output width, padding and parameter count from
the config, and ``lower`` onto bundle components in tiny-cuda-nn's lane order. Each encoding
registers its otypes with ``@tcnn_encoding``; ``parse_encoding`` finds it there."""
from __future__ import annotations

import math

from ..registry import TCNN_ENCODINGS
from ..tcnn_json import Context, Reader, next_multiple


def lanes_of(value: str, count: int) -> list:
    """The first ``count`` lanes of ``value``, as (value, lane) references."""
    return [(value, i) for i in range(count)]


class Encoding:
    """tiny-cuda-nn's Encoding<T>: ``out`` lanes computed, then ``pad`` lanes of ``pad_value``
    (before the computed ones where ``pad_first``). ``fields``: what ``resolved`` records besides
    the otype."""

    otype = ""
    alignment = 1          # required_output_alignment()
    pad_value = 1.0
    pad_first = False
    fields: tuple = ()

    def __init__(self, where: str, n_dims: int):
        self.where, self.n_dims, self.out, self.pad = where, n_dims, 0, 0

    @property
    def padded(self) -> int:
        return self.out + self.pad

    def n_params(self) -> int:
        return 0

    def set_padded(self, width: int) -> None:   # set_padded_output_width
        if width < self.out:
            raise ValueError(f"{self.where}: padded width {width} < {self.out}")
        self.pad = width - self.out

    def set_alignment(self, alignment: int) -> None:   # Encoding<T>::set_alignment
        self.set_padded(next_multiple(self.padded, math.lcm(alignment, self.alignment)))

    def params_text(self) -> str:
        return ""

    def resolved(self) -> dict:
        return {"otype": self.otype, **{f: getattr(self, f) for f in self.fields}}

    def with_padding(self, computed: list) -> list:
        """The encoding's output lanes: ``computed`` (value, lane) references and the padding
        constants, where tiny-cuda-nn puts them."""
        pads = [self.pad_value] * self.pad
        return pads + computed if self.pad_first else computed + pads

    def lower(self, b, src: str, params, dtype: str) -> list:
        """The components computing this encoding of value ``src`` (added to the Builder ``b``,
        reading parameters from the Cursor ``params``, stored as ``dtype``): its padded output
        lanes, each a (value, lane) reference or a constant."""
        raise NotImplementedError


def parse_encoding(ctx: Context, cfg, n_dims: int, where: str, alignment: int, known=()) -> Encoding:
    """create_encoding(n_dims_to_encode, encoding, alignment): otype "OneBlob" when absent; the
    result padded to ``alignment`` when it is not 0."""
    r = Reader(ctx, cfg, where)
    r.read.update(known)
    otype = cfg.get("otype", "OneBlob")
    if not isinstance(otype, str) or otype.lower() not in TCNN_ENCODINGS:
        raise ctx.error(f"{where}.otype", f"{otype!r} is not a tiny-cuda-nn encoding "
                                          f"({', '.join(sorted(TCNN_ENCODINGS))}; any case)")
    enc = TCNN_ENCODINGS[otype](where, n_dims, r)
    r.done()
    if alignment > 0:
        enc.set_alignment(alignment)
    return enc


def lower_encoding(b, enc: Encoding, src: str, params, dtype: str) -> list:
    """``enc.lower``, checked to give as many lanes as tiny-cuda-nn's padded output."""
    out = enc.lower(b, src, params, dtype)
    assert len(out) == enc.padded, (enc.where, len(out), enc.padded)
    return out
