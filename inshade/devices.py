"""The torch device every trainer takes: ``--device auto|cpu|cuda[:N]``.

``auto`` is CUDA when torch sees a CUDA device, else the CPU. Asking for CUDA where there is none,
or for a CUDA index past the count, is a ``DeviceError`` (a ValueError) with one line saying why,
which the trainers' command wrappers turn into ``inshade: error: ...`` and exit status 2. torch is
imported only when a device is resolved, so ``add_device_argument`` costs nothing at import time.
"""
from __future__ import annotations

import argparse
import re

CHOICES_HELP = "torch device: auto (CUDA when torch sees one, else CPU), cpu, cuda, cuda:N"
_SPEC = re.compile(r"^(auto|cpu|cuda(:\d+)?)$")


class DeviceError(ValueError):
    """A --device the user can fix."""


def check_spec(spec: str) -> str:
    """The spelling alone (no torch): auto, cpu, cuda or cuda:N."""
    if not isinstance(spec, str) or not _SPEC.match(spec):
        raise DeviceError(f"--device: {spec!r} is not one of auto, cpu, cuda, cuda:N")
    return spec


def resolve_device(spec: str = "auto"):
    """``torch.device`` for ``spec``; DeviceError when it names a CUDA device torch does not see."""
    import torch

    check_spec(spec)
    if spec == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if spec == "cpu":
        return torch.device("cpu")
    if not torch.cuda.is_available():
        raise DeviceError(f"--device {spec}: this torch build sees no CUDA device (torch {torch.__version__}, "
                          f"torch.cuda.is_available() is False); use --device cpu or auto")
    index = int(spec.split(":")[1]) if ":" in spec else 0
    count = torch.cuda.device_count()
    if index >= count:
        raise DeviceError(f"--device {spec}: torch sees {count} CUDA device(s) (cuda:0..cuda:{count - 1})")
    return torch.device("cuda", index)


def add_device_argument(parser: argparse.ArgumentParser, default: str = "auto") -> None:
    parser.add_argument("--device", default=default, type=_argparse_spec, help=f"{CHOICES_HELP} (default: %(default)s)")


def _argparse_spec(text: str) -> str:
    try:
        return check_spec(text)
    except DeviceError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
