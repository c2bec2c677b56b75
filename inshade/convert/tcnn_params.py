"""tiny-cuda-nn's flat parameter vector, as its torch bindings hold it (``module.params``, saved as
``state_dict()["params"]``: one 1-D tensor, float16 by default or float32), read from a file
without running any code from it:

- ``.npy``: a 1-D float16 / float32 array (np.load, allow_pickle=False);
- ``.bin``: raw little-endian values; the file's length says which (2 bytes a value: float16,
  4: float32), against the count the config needs;
- ``.safetensors``: one tensor, or the one named ``params`` (or ``--params-key``);
- ``.pt`` / ``.pth``: torch.load(weights_only=True) of a tensor, or of a (nested) state dict holding
  ``params`` (or one key ending in ``params``, or ``--params-key``).
"""
from __future__ import annotations

import pickle
import zipfile
from pathlib import Path

import numpy as np

from .lowering import ConvertError

DTYPES = ("float16", "float32")
FORMATS = (".npy", ".bin", ".safetensors", ".pt", ".pth")


def read_params(path, expected: int, key: str | None = None) -> tuple[np.ndarray, str]:
    """(the values as float32 [N], the dtype they were stored in: "float16" | "float32").
    ``expected``: the count the config needs (it decides a .bin file's dtype)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ConvertError(f"{path}: unknown parameter file format {suffix or '(no suffix)'!r} "
                           f"(reads {', '.join(FORMATS)})")
    if path.is_dir():
        raise ConvertError(f"{path}: is a folder, expected a parameter file")
    reader = {".npy": _npy, ".bin": _bin, ".safetensors": _safetensors, ".pt": _torch, ".pth": _torch}[suffix]
    values, dtype = reader(path, expected, key)
    if values.ndim != 1:
        raise ConvertError(f"{path}: shape {list(values.shape)}; tiny-cuda-nn's parameters are one flat vector")
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise ConvertError(f"{path}: parameter {bad[0]} is {values[bad[0]]} (NaN or Inf: the model cannot be "
                           "converted)")
    return values.astype(np.float32), dtype


def _dtype_of(path: Path, dtype, where: str = "") -> str:
    name = np.dtype(dtype).name if not isinstance(dtype, str) else dtype
    if name not in DTYPES:
        raise ConvertError(f"{path}: {where}dtype {name}; tiny-cuda-nn's parameters are float16 or float32")
    return name


def _npy(path: Path, expected: int, key):
    try:
        a = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:   # not a .npy array (pickles refused)
        raise ConvertError(f"{path}: cannot read as a .npy array ({exc})") from None
    if not isinstance(a, np.ndarray):
        raise ConvertError(f"{path}: holds several arrays (an .npz); save the parameter vector alone")
    return a, _dtype_of(path, a.dtype)


def _bin(path: Path, expected: int, key):
    size = path.stat().st_size
    for dtype, width in (("float16", 2), ("float32", 4)):
        if size == expected * width:
            return np.fromfile(path, np.dtype(dtype).newbyteorder("<")), dtype
    raise ConvertError(f"{path}: {size} bytes; the config needs {expected} parameters: {2 * expected} bytes as "
                       f"raw float16 or {4 * expected} as float32")


def _pick(path: Path, tensors: dict, key: str | None):
    """The parameter tensor among ``tensors`` (name -> array)."""
    if key is not None:
        if key not in tensors:
            raise ConvertError(f"{path}: --params-key {key!r}: no such tensor (has {_names(tensors)})")
        return key
    if len(tensors) == 1:
        return next(iter(tensors))
    if "params" in tensors:
        return "params"
    ends = [k for k in tensors if k.endswith(".params")]
    if len(ends) == 1:
        return ends[0]
    if not tensors:
        raise ConvertError(f"{path}: holds no tensor")
    raise ConvertError(f"{path}: holds {len(tensors)} tensors and none named params ({_names(tensors)}); "
                       "choose one with --params-key")


def _names(tensors: dict) -> str:
    names = list(tensors)
    return ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")


def _safetensors(path: Path, expected: int, key):
    from inshade.bundle import _read_safetensors

    tensors, widened = _read_safetensors(path)   # checked whole before anything is allocated
    name = _pick(path, tensors, key)
    stored = widened.get(name, tensors[name].dtype.name)
    return tensors[name], _dtype_of(path, stored, f"{name}: ")


def _torch(path: Path, expected: int, key):
    import torch

    try:
        obj = torch.load(path, map_location="cpu", weights_only=True)
    except (pickle.UnpicklingError, RuntimeError, EOFError, ValueError, zipfile.BadZipFile) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ConvertError(f"{path}: cannot read as a file of tensors (torch.load with weights_only=True: "
                           f"{first[:160]})") from None
    tensors = {}
    _tensors(obj, "", tensors)
    name = _pick(path, tensors, key)
    t = tensors[name].detach()
    dtype = _dtype_of(path, str(t.dtype).removeprefix("torch."), f"{name}: " if name else "")
    return t.float().numpy(), dtype


def _tensors(obj, prefix: str, out: dict) -> None:
    """Every tensor in a (nested) dict / list, by its dotted name."""
    import torch

    if isinstance(obj, torch.Tensor):
        out[prefix] = obj
    elif isinstance(obj, dict):
        for k, v in obj.items():
            _tensors(v, f"{prefix}.{k}" if prefix else str(k), out)
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            _tensors(v, f"{prefix}.{i}" if prefix else str(i), out)
