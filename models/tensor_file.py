"""Reading a safetensors file whole: its metadata and every tensor, with one error for a file that
is not readable (truncated, corrupt, not safetensors at all), worded by the caller."""
from __future__ import annotations

from typing import Callable


def read_tensors(path, framework: str, unreadable: Callable[[Exception], Exception]) -> tuple[dict, dict]:
    """(metadata, tensors) of the file at ``path`` as ``framework`` ("np" or "pt") arrays; a file
    safetensors cannot read raises ``unreadable(exc)``."""
    from safetensors import safe_open

    try:
        with safe_open(str(path), framework=framework) as f:
            return f.metadata() or {}, {k: f.get_tensor(k) for k in f.keys()}
    except Exception as exc:  # safetensors raises several types for corrupt files
        raise unreadable(exc) from None
