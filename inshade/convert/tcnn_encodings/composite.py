"""tiny-cuda-nn's Composite encoding (encodings/composite.h, Concatenation) and the composites
encoding.cu builds by name (OneBlobFrequency / NRC): a ``select`` of each nested encoding's input
lanes, the nested outputs side by side."""
from __future__ import annotations

import math

from ..registry import tcnn_encoding
from ..tcnn_json import Context, Reader, next_multiple
from .base import Encoding, lower_encoding, parse_encoding


@tcnn_encoding("Composite")
class Composite(Encoding):
    """CompositeEncoding (encodings/composite.h): ``nested`` encodings over input lanes
    ``begins[i]`` .. ``begins[i] + nested[i].n_dims``, their outputs concatenated."""

    otype = "Composite"

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)
        err = r.ctx.error
        reduction = r.word("reduction", "Concatenation", ("concatenation", "sum", "product"))
        if reduction != "concatenation":
            raise err(f"{where}.reduction", f"{r.obj['reduction']}: inshade lowers Concatenation only")
        r.read.add("nested")
        nested = r.obj.get("nested")
        if not isinstance(nested, list) or not nested:
            raise err(f"{where}.nested", "must be a non-empty list of encodings")
        for i, n in enumerate(nested):
            if not isinstance(n, dict):
                raise err(f"{where}.nested[{i}]", "expected a JSON object")
        explicit = any("dims_to_encode_begin" in n for n in nested)
        total = sum(_dims(r.ctx, n, f"{where}.nested[{i}]") for i, n in enumerate(nested))
        if not explicit and total > n_dims:
            raise err(f"{where}.nested", f"the nested encodings encode {total} lanes, more than the {n_dims} "
                                         f"the composite takes")
        unspecified = None if explicit else n_dims - total
        self.nested, self.begins, offset = [], [], 0
        for i, cfg in enumerate(nested):
            w = f"{where}.nested[{i}]"
            if "n_dims_to_encode" in cfg:
                if "dims_to_encode_begin" in cfg:
                    offset = _dims(r.ctx, cfg, w, "dims_to_encode_begin")
                count = _dims(r.ctx, cfg, w)
            else:
                if unspecified is None:
                    raise err(f"{w}.n_dims_to_encode", "may be left out for one nested encoding only")
                count, unspecified = unspecified, None
            if offset + count > n_dims:
                raise err(w, f"encodes input lanes {offset}..{offset + count - 1}; the composite has {n_dims}")
            if count > 0:
                self.nested.append(parse_encoding(r.ctx, cfg, count, w, alignment=1, known=("n_dims_to_encode",
                                                                                         "dims_to_encode_begin")))
                self.begins.append(offset)
            offset += count
        if not self.nested:
            raise err(f"{where}.nested", "no nested encoding encodes any lane")
        # each nested output padded so that the next one starts at its required alignment
        so_far = 0
        for a, b in zip(self.nested, self.nested[1:]):
            a.set_padded(next_multiple(so_far + a.padded, b.alignment) - so_far)
            so_far += a.padded
        self.alignment = math.lcm(*(n.alignment for n in self.nested))

    @property
    def out(self) -> int:
        return sum(n.padded for n in self.nested) if hasattr(self, "nested") else 0

    @out.setter
    def out(self, value) -> None:   # the base class sets it before the nested exist
        pass

    @property
    def padded(self) -> int:
        return self.out

    def set_padded(self, width: int) -> None:   # the padding goes to the last nested encoding
        last = self.nested[-1]
        last.set_padded(width - (self.out - last.padded))

    def n_params(self) -> int:
        return sum(n.n_params() for n in self.nested)

    def params_text(self) -> str:
        return "; ".join(t for t in (n.params_text() for n in self.nested) if t)

    def resolved(self):
        return {"otype": self.otype, "nested": [{"n_dims_to_encode": n.n_dims, "dims_to_encode_begin": b,
                                                 **n.resolved()} for n, b in zip(self.nested, self.begins)]}

    def lower(self, b, src, params, dtype):
        out = []
        for nested, begin in zip(self.nested, self.begins):
            part = src
            if (begin, nested.n_dims) != (0, b.width(src)):
                part = b.node("select", {"lanes": list(range(begin, begin + nested.n_dims))}, [src],
                              where=nested.where)
            out += lower_encoding(b, nested, part, params, dtype)
        return out   # the composite's own padding is its last nested encoding's


def _dims(ctx: Context, cfg: dict, where: str, key: str = "n_dims_to_encode") -> int:
    v = cfg.get(key, 0)
    if isinstance(v, bool) or not isinstance(v, int) or v < 0:
        raise ctx.error(f"{where}.{key}", f"expected a non-negative integer, got {v!r}")
    return v


def _nrc(where, n_dims, r: Reader) -> Composite:
    """encoding.cu's "OneBlobFrequency" / "NRC": TriangleWave on 3 lanes, OneBlob on 5, Identity on the rest."""
    cfg = {"otype": "Composite", "nested": [
        {"n_dims_to_encode": 3, "otype": "TriangleWave", "n_frequencies": r.uint("n_frequencies", 12)},
        {"n_dims_to_encode": 5, "otype": "OneBlob", "n_bins": r.uint("n_bins", 4)},
        {"otype": "Identity"}]}
    return Composite(where, n_dims, Reader(r.ctx, cfg, where))


tcnn_encoding("OneBlobFrequency", "NRC")(_nrc)
