"""The tables of lowerings, one per source format, filled by decorators where each lowering is
defined (onnx2torch's converter registry is the model):

    @torch_op("relu")                    # an ATen op, by the name torch.export records
    @onnx_op("Relu")                     # an ONNX op type
    @tcnn_encoding("OneBlob")            # a tiny-cuda-nn encoding otype (any case)

A name registered twice is refused with both places named, so a plug-in cannot replace a
built-in lowering by accident. Standard library only: any package may import this to register
its own lowerings without loading torch or onnx.
"""
from __future__ import annotations

import sys
from collections.abc import Mapping
from dataclasses import dataclass, field


class DuplicateLowering(ValueError):
    """A name registered twice in one table; the message names the name and both places."""


@dataclass(frozen=True)
class Entry:
    """One registered lowering: ``where`` is the file:line that registered it; ``options`` what its
    table says about it (e.g. ``takes_ints``)."""
    name: str
    lower: object
    where: str
    options: dict = field(default_factory=dict)

    def option(self, key: str, default=False):
        return self.options.get(key, default)


class Registry(Mapping):
    """Name -> lowering, for one source format. ``fold`` maps a name to its key (tiny-cuda-nn
    reads otypes in any case); the names keep the spelling they were registered with."""

    def __init__(self, source: str, fold=None):
        self.source, self._fold = source, fold or (lambda name: name)
        self._entries: dict[str, Entry] = {}

    def add(self, name: str, lower, *, where: str | None = None, **options) -> None:
        key = self._fold(name)
        where = where or _caller(2)
        old = self._entries.get(key)
        if old is not None:
            raise DuplicateLowering(f"{self.source} {name!r} is registered twice: at {old.where} and at {where}")
        self._entries[key] = Entry(name, lower, where, dict(options))

    def register(self, *names: str, where: str | None = None, **options):
        """A decorator registering what it decorates under each of ``names``."""
        where = where or _caller(2)

        def decorate(lower):
            for name in names:
                self.add(name, lower, where=where, **options)
            return lower
        return decorate

    def entry(self, name: str) -> Entry | None:
        return self._entries.get(self._fold(name))

    def names(self) -> list[str]:
        """The names as registered (their own spelling), sorted."""
        return sorted(e.name for e in self._entries.values())

    def __getitem__(self, name: str):
        return self._entries[self._fold(name)].lower

    def __iter__(self):
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)


def _caller(depth: int) -> str:
    frame = sys._getframe(depth)
    return f"{frame.f_code.co_filename}:{frame.f_lineno}"


TORCH_OPS = Registry("torch op")
ONNX_OPS = Registry("ONNX op")
TCNN_ENCODINGS = Registry("tiny-cuda-nn encoding", fold=str.lower)


def torch_op(*names: str, takes_ints: bool = False):
    """Registers a lowering ``lower(walk, node, *args, **kwargs)`` of the ATen ops ``names``
    (torch.export's names: aten.relu.default is "relu"). ``takes_ints``: integer tensors reach it
    as they are (else as the floats they were cast from)."""
    return TORCH_OPS.register(*names, where=_caller(2), takes_ints=takes_ints)


def onnx_op(*names: str, takes_ints: bool = False, whole_shape: bool = False):
    """Registers a lowering ``lower(walk, node, *inputs, **attributes)`` of the ONNX op types
    ``names``. ``takes_ints``: as for torch_op; ``whole_shape``: it names axes of the whole tensor
    (or needs its full shape), so it is not lowered while several leading axes are the batch."""
    return ONNX_OPS.register(*names, where=_caller(2), takes_ints=takes_ints, whole_shape=whole_shape)


def tcnn_encoding(*otypes: str):
    """Registers ``make(where, n_dims, reader)`` -> an encoding, for the tiny-cuda-nn otypes."""
    return TCNN_ENCODINGS.register(*otypes, where=_caller(2))
