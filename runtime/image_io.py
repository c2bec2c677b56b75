"""Writing renders: PNG for eyes (tonemap + sRGB, 8-bit), EXR for numbers (linear float32).

Arrays are image-oriented ([H, W, C], row 0 = top), as returned by ``render.read_rgba``.
Each output can get a JSON sidecar saying how it was made. Every file is written atomically
(inshade/files.py): a temporary file in the same folder, renamed into place when complete.
"""

from __future__ import annotations

import datetime
import json
from importlib import metadata
from pathlib import Path

import numpy as np
import OpenEXR
from PIL import Image

from inshade.files import atomic_files

TONEMAPS = ("none", "reinhard")


def srgb_oetf(linear: np.ndarray) -> np.ndarray:
    """sRGB encoding of linear values in [0, 1] (same formula as ``lib/colour.glsl``)."""
    linear = np.clip(linear, 0.0, 1.0)
    return np.where(linear <= 0.0031308, linear * 12.92, 1.055 * np.power(linear, 1.0 / 2.4) - 0.055)


def write_png(path: str | Path, linear_rgb: np.ndarray, exposure: float = 1.0, tonemap: str = "none") -> Path:
    """Write linear ``[H, W, 3|4]`` as an 8-bit sRGB PNG: scale by exposure, tonemap, clip, encode.

    Alpha (if present) is written linearly, without exposure or tonemap.
    """
    if tonemap not in TONEMAPS:
        raise ValueError(f"unknown tonemap {tonemap!r}; expected one of {TONEMAPS}")
    image = _check_image(linear_rgb).astype(np.float64)
    rgb = np.maximum(image[..., :3] * exposure, 0.0)
    if tonemap == "reinhard":
        rgb = rgb / (1.0 + rgb)
    channels = [srgb_oetf(rgb)] + ([np.clip(image[..., 3:], 0.0, 1.0)] if image.shape[2] == 4 else [])
    pixels = np.rint(np.concatenate(channels, axis=2) * 255.0).astype(np.uint8)
    path = Path(path)
    with atomic_files(path) as tmp:
        Image.fromarray(pixels).save(tmp, format="PNG")
    return path


def write_exr(path: str | Path, linear: np.ndarray) -> Path:
    """Write linear ``[H, W, 3|4]`` float32 to an EXR (FLOAT channels, ZIP compression)."""
    image = np.ascontiguousarray(_check_image(linear), dtype=np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    channels = {"RGBA" if image.shape[2] == 4 else "RGB": image}
    path = Path(path)
    with atomic_files(path) as tmp, OpenEXR.File(header, channels) as exr:
        exr.write(str(tmp))
    return path


def read_exr(path: str | Path) -> np.ndarray:
    """Read an RGB or RGBA EXR back as float32 ``[H, W, 3|4]``."""
    with OpenEXR.File(str(path)) as exr:
        channels = exr.channels()
        name = "RGBA" if "RGBA" in channels else "RGB"
        return np.asarray(channels[name].pixels, dtype=np.float32)


def write_sidecar(image_path: str | Path, info: dict) -> Path:
    """Write ``<image>.json`` (e.g. ``render.png.json``) with ``info`` plus version and UTC time.

    ``info`` carries what the caller knows (camera, settings, bundle hash, GL renderer); numpy
    values are converted to plain JSON.
    """
    path = sidecar_path(image_path)
    with atomic_files(path) as tmp:
        tmp.write_text(sidecar_text(info))
    return path


def sidecar_path(image_path: str | Path) -> Path:
    return Path(f"{image_path}.json")


def sidecar_text(info: dict) -> str:
    """The sidecar JSON of ``info`` plus the inshade version and the UTC time."""
    record = dict(info)
    record["inshade_version"] = metadata.version("inshade")
    record["timestamp_utc"] = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    return json.dumps(record, sort_keys=True, indent=2, default=_to_json) + "\n"


def _to_json(value):
    if isinstance(value, (np.ndarray, np.generic)):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def _check_image(array: np.ndarray) -> np.ndarray:
    array = np.asarray(array)
    if array.ndim != 3 or array.shape[2] not in (3, 4):
        raise ValueError(f"expected an image [H, W, 3|4], got shape {array.shape}")
    return array
