"""Reading a tiny-cuda-nn JSON config the way tiny-cuda-nn's json.value(key, default) does: each
value checked, each message naming the file and the field; the keys tiny-cuda-nn ignores noted."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .lanes import ConvertError


def next_multiple(n: int, m: int) -> int:
    return -(-n // m) * m


@dataclass
class Context:
    """Where the config came from (for messages) and what it held that tiny-cuda-nn ignores."""
    source: str
    ignored: list = field(default_factory=list)

    def error(self, where: str, message: str) -> ConvertError:
        return ConvertError(f"{self.source}: {where}: {message}")


class Reader:
    """One JSON object of the config; ``take`` marks keys as read, ``done`` records the rest."""

    def __init__(self, ctx: Context, obj, where: str):
        if not isinstance(obj, dict):
            raise ctx.error(where, f"expected a JSON object, got {type(obj).__name__}")
        self.ctx, self.obj, self.where, self.read = ctx, obj, where, {"otype"}

    def _path(self, key: str) -> str:
        return f"{self.where}.{key}" if self.where else key

    def has(self, key: str) -> bool:
        return key in self.obj

    def uint(self, key: str, default: int | None) -> int:
        self.read.add(key)
        v = self.obj.get(key, default)
        if v is None:
            raise self.ctx.error(self._path(key), "missing (no default in tiny-cuda-nn)")
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise self.ctx.error(self._path(key), f"expected a non-negative integer, got {v!r}")
        return int(v)

    def number(self, key: str, default) -> float:
        self.read.add(key)
        v = self.obj.get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise self.ctx.error(self._path(key), f"expected a number, got {v!r}")
        return float(np.float32(v))   # tiny-cuda-nn reads these fields as float

    def boolean(self, key: str, default: bool) -> bool:
        self.read.add(key)
        v = self.obj.get(key, default)
        if not isinstance(v, bool):
            raise self.ctx.error(self._path(key), f"expected true or false, got {v!r}")
        return v

    def word(self, key: str, default: str, choices) -> str:
        """A case-insensitive name (tiny-cuda-nn's equals_case_insensitive), lower-cased."""
        self.read.add(key)
        v = self.obj.get(key, default)
        if not isinstance(v, str) or v.lower() not in choices:
            raise self.ctx.error(self._path(key), f"{v!r} is not one of {', '.join(choices)}")
        return v.lower()

    def done(self) -> None:
        self.ctx.ignored += [self._path(k) for k in self.obj if k not in self.read]
